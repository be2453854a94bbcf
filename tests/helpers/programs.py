"""Console programs of this package run as a user runs them: a subprocess in a given folder, never on a prompt."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

BIN = Path(sys.executable).parent


def run_program(command: str, *args, cwd, check: bool = True) -> subprocess.CompletedProcess:
    """Runs ``command`` (a console script of this venv) with ``args``; with ``check``, asserts it succeeded."""
    result = subprocess.run(
        [str(BIN / command), *map(str, args)],
        cwd=cwd,
        env=dict(os.environ, MUJOCO_GL="osmesa"),
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=600,
    )
    if check:
        assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]
    return result
