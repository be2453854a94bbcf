"""A stage run in a child process (a console program, or a function in a fresh interpreter), its output kept in a
log file and shown as a progress bar."""

from __future__ import annotations

import importlib
import os
import pickle
import re
import signal
import subprocess
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm

from veragmil_suite.study.settings import StageError
from veragmil_suite.utils.rendering import use_headless_rendering
from veragmil_suite.utils.termination import sigterm_raises, stop_tree


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
    start = time.perf_counter()
    with (
        open(log_path, "w") as log,
        subprocess.Popen(
            command, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=child_environ(environ)
        ) as child,
    ):
        try:
            code = child.wait() if progress is None else _follow(child.poll, log_path, progress)
        except BaseException:  # interrupted (Ctrl-C, SIGTERM): the stage goes too
            stop_tree(child.pid)
            raise
    _check_exit(code, log_path, what)
    return time.perf_counter() - start


def run_logged_call(
    function: Callable[..., object],
    kwargs: dict,
    log_path: Path,
    what: str,
    progress: LogProgress | None = None,
) -> float:
    """Calls ``function(**kwargs)`` in a fresh interpreter (MuJoCo, rendering, worker pools and a multiprocessing
    resource tracker of its own, whose warnings land in the log too), its output in ``log_path`` as ``run_logged``'s;
    returns its wall time, raises StageError when it raises. ``function`` must be importable by name (a module-level
    function); the call travels pickled in a hidden file beside the log."""
    log_path = Path(log_path)
    call = log_path.with_name(f".{log_path.name}.call")
    module, name = function.__module__, function.__qualname__
    call.write_bytes(pickle.dumps(dict(path=sys.path, module=module, name=name, kwargs=pickle.dumps(kwargs))))
    try:
        return run_logged([sys.executable, "-m", __name__, str(call)], log_path, what, progress=progress)
    finally:
        call.unlink(missing_ok=True)


def child_environ(extra: dict[str, str] | None = None) -> dict[str, str]:
    """A stage's environment: this one with ``extra``, headless rendering without a display, and pynput's dummy
    backend (robosuite's devices import it, and it wants an X server)."""
    env = dict(os.environ, **(extra or {}))
    use_headless_rendering(environ=env)
    env.setdefault("PYNPUT_BACKEND", "dummy")
    return env


def _call(call_path: str) -> None:
    """The interpreter run_logged_call starts: the pickled call of ``call_path``, its standard output and error (the
    log) line-buffered; an exception is logged and exits 1."""
    call = pickle.loads(Path(call_path).read_bytes())
    sys.path[:0] = [entry for entry in call["path"] if entry not in sys.path]  # the caller's, for its function
    sys.stdout.reconfigure(line_buffering=True)
    sys.stderr.reconfigure(line_buffering=True)
    # stopped by the study (stop_tree) or Ctrl-C (the terminal's, to the whole process group): the function unwinds,
    # its pools and writes closed. Either signal after it is ignored: it would break off multiprocessing's exit
    # clean-up, which unlinks the pools' semaphores (the study stops this process itself)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    try:
        try:
            with sigterm_raises():
                function = getattr(importlib.import_module(call["module"]), call["name"])
                function(**pickle.loads(call["kwargs"]))
        finally:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
    except BaseException:
        traceback.print_exc()
        sys.stdout.flush()
        sys.exit(1)


def _check_exit(code: int | None, log_path: Path, what: str) -> None:
    if code != 0:
        tail = Path(log_path).read_text(errors="replace")[-3000:]
        raise StageError(f"{what} failed (exit {code}); log {log_path}:\n{tail}")


def _follow(poll: Callable[[], int | None], log_path: Path, progress: LogProgress) -> int:
    """Waits for a child (``poll``: its exit code, None while it runs), its progress read from the lines it writes
    to ``log_path``; returns its exit code."""
    pattern = re.compile(progress.pattern, re.MULTILINE)
    bar = tqdm(total=progress.total, desc=progress.desc, unit=progress.unit)
    with open(log_path, errors="replace") as log, bar:
        pending = ""
        while True:
            code = poll()
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


if __name__ == "__main__":
    _call(sys.argv[1])
