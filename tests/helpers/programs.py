"""Console programs and scripts of this checkout run as a user runs them: a subprocess, never on a prompt."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

BIN = Path(sys.executable).parent
ROOT = Path(__file__).parents[2]


def _run(argv: list, cwd, check: bool, timeout: float) -> subprocess.CompletedProcess:
    result = subprocess.run(
        [str(a) for a in argv],
        cwd=cwd,
        env=dict(os.environ, MUJOCO_GL="osmesa"),
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    if check:
        assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]
    return result


def run_program(command: str, *args, cwd=None, check: bool = True, timeout: float = 600) -> subprocess.CompletedProcess:
    """Runs ``command`` (a console script of this venv) with ``args``; with ``check``, asserts it succeeded."""
    return _run([BIN / command, *args], cwd, check, timeout)


def run_script(path: str, *args, cwd=None, check: bool = True, timeout: float = 600) -> subprocess.CompletedProcess:
    """Runs the script at ``path`` (relative to the checkout) with this venv's Python, as ``python path args``."""
    return _run([sys.executable, ROOT / path, *args], cwd, check, timeout)
