"""Console programs and scripts of this checkout run as a user runs them: a subprocess, never on a prompt."""

from __future__ import annotations

import functools
import importlib
import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

BIN = Path(sys.executable).parent
ROOT = Path(__file__).parents[2]
ENTRY_POINTS = dict(re.findall(r'"(veragmil-[\w-]+)=([\w.]+:\w+)"', (ROOT / "setup.py").read_text()))
# the benchmark scripts, run as python benchmarks/NAME.py: programs a researcher runs too, with the same command line
BENCHMARKS = {f"benchmarks/{p.name}": p for p in sorted((ROOT / "benchmarks").glob("bench_*.py"))}
# the package's programs run as python -m MODULE: the module whose main() they run
MODULE_PROGRAMS = {
    "python -m veragmil_suite.calibration": "veragmil_suite.calibration.benchmark",
    "python -m veragmil_suite.calibration.stability": "veragmil_suite.calibration.stability",
    "python -m veragmil_suite.scripts.measure_expert": "veragmil_suite.scripts.measure_expert",
    "python -m veragmil_suite.devices.vr.client": "veragmil_suite.devices.vr.client",
}
PROGRAMS = [*sorted(ENTRY_POINTS), *BENCHMARKS, *MODULE_PROGRAMS]


@functools.cache
def main_of(program: str):
    """The ``main(argv) -> exit status`` of a console program, a benchmark script or a ``python -m`` program."""
    if program in BENCHMARKS:
        spec = importlib.util.spec_from_file_location(BENCHMARKS[program].stem, BENCHMARKS[program])
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module.main
    if program in MODULE_PROGRAMS:
        return importlib.import_module(MODULE_PROGRAMS[program]).main
    module, function = ENTRY_POINTS[program].split(":")
    return getattr(importlib.import_module(module), function)


def command_of(program: str) -> list[str]:
    """The program as a user starts it."""
    if program in BENCHMARKS:
        return [sys.executable, str(BENCHMARKS[program])]
    if program in MODULE_PROGRAMS:
        return [sys.executable, *program.split()[1:]]
    return [str(BIN / program)]


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
