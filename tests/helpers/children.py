"""Functions a stage runs in a child process (veragmil_suite.study.logged_run.run_logged_call): importable by name."""

import os
import sys


def say_then(
    lines: list[str], error: str | None = None, c_line: str | None = None, variables: tuple[str, ...] = ()
) -> None:
    """Prints ``lines`` and the environment's ``variables`` (and ``c_line`` straight to file descriptor 1, as C code
    would), then raises ``error``."""
    for line in lines:
        print(line)
    for name in variables:
        print(f"{name}={os.environ.get(name)}")
    if c_line is not None:
        sys.stdout.flush()
        os.write(1, (c_line + "\n").encode())
    if error is not None:
        raise RuntimeError(error)
