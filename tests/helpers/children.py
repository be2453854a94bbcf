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


_held = []  # kept to the child's exit: a semaphore collected earlier would be unlinked at once


def hold_a_semaphore_and_exit_slowly(marker: str) -> None:
    """Takes a named semaphore (registered with the resource tracker of the process that started this one), then
    returns; at exit, before multiprocessing's clean-up unlinks the semaphore, writes ``marker`` (this process's id)
    and waits, so that a test can signal it there."""
    import multiprocessing
    import multiprocessing.util
    import time

    def exit_slowly() -> None:
        with open(marker + ".part", "w") as out:
            out.write(str(os.getpid()))
        os.replace(marker + ".part", marker)
        time.sleep(3)

    _held.append(multiprocessing.get_context("spawn").Lock())
    multiprocessing.util.Finalize(None, exit_slowly, exitpriority=10)  # before the semaphore's (priority 0)
