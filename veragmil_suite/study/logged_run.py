"""Our console programs run in a child process, their output kept in a log file and shown as a progress bar."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm

from veragmil_suite.study.settings import StageError
from veragmil_suite.utils.rendering import use_headless_rendering


@dataclass(frozen=True)
class LogProgress:
    """A progress bar a child's log drives: ``pattern``'s first group, in the last line that matches, is the count
    done out of ``total``; with ``echo``, the log's lines are shown above the bar as they come."""

    total: int
    pattern: str
    desc: str
    unit: str
    echo: bool = False


# veragmil-collect's line per episode kept ("  saved as demo_3 (2/5)"); robomimic's train.py's line per epoch
RECORDING_PROGRESS = r"saved as demo_\d+ \((\d+)/\d+\)"
TRAINING_PROGRESS = r"^Train Epoch (\d+)$"
LOG_POLL_S = 0.5


def run_logged(
    command: list[str],
    log_path: Path,
    what: str,
    environ: dict[str, str] | None = None,
    progress: LogProgress | None = None,
) -> float:
    """Runs a command (with ``environ`` added to this environment) with its output in ``log_path``, advancing a
    progress bar from the log when ``progress`` is given; returns its wall time, raises StageError on failure."""
    env = dict(os.environ, **(environ or {}))
    use_headless_rendering(environ=env)
    env.setdefault("PYNPUT_BACKEND", "dummy")
    start = time.perf_counter()
    with (
        open(log_path, "w") as log,
        subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env) as child,
    ):
        try:
            code = child.wait() if progress is None else _follow(child, log_path, progress)
        except BaseException:  # interrupted: the child goes too, as subprocess.call would see to
            child.kill()
            raise
    if code != 0:
        tail = log_path.read_text(errors="replace")[-3000:]
        raise StageError(f"{what} failed (exit {code}); log {log_path}:\n{tail}")
    return time.perf_counter() - start


def _follow(child: subprocess.Popen, log_path: Path, progress: LogProgress) -> int:
    """Waits for ``child``, its progress read from the lines it writes to ``log_path``; returns its exit code."""
    pattern = re.compile(progress.pattern, re.MULTILINE)
    bar = tqdm(total=progress.total, desc=progress.desc, unit=progress.unit)
    with open(log_path, errors="replace") as log, bar:
        pending = ""
        while True:
            code = child.poll()
            pending += log.read()
            complete, _, pending = pending.rpartition("\n")
            found = pattern.findall(complete)
            if progress.echo and complete:
                bar.write(complete)
            if found:
                bar.update(min(int(found[-1]), progress.total) - bar.n)
            if code is not None:
                return code
            time.sleep(LOG_POLL_S)


def console(name: str) -> list[str]:
    """A console program of this package, run with this interpreter (works without the venv on PATH)."""
    modules = {
        "veragmil-collect": "veragmil_suite.scripts.collect_human_demonstrations",
        "veragmil-train": "veragmil_suite.scripts.robomimic_entry",
    }
    command = [sys.executable, "-m", modules[name]]
    return [*command, "train"] if name == "veragmil-train" else command
