"""SIGTERM as an exception, and a stop that takes a process's whole tree.

A console program or a study's stage stopped by SIGTERM (kill, a scheduler's stop) unwinds as on Ctrl-C: its
``finally`` blocks close worker pools and finish writes, instead of dying with children that go on with its work.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

import psutil


class Terminated(BaseException):
    """SIGTERM, raised where the process is (sigterm_raises)."""


def _raise_terminated(signum, frame) -> None:
    # once: a second SIGTERM would break off the unwinding the first one started (a pool half closed)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise Terminated


@contextlib.contextmanager
def sigterm_raises() -> Iterator[None]:
    """SIGTERM raises Terminated in the block, once (later ones are ignored while the block unwinds), in the main
    thread, where Python delivers signals (elsewhere as it was); the handler before is put back after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, before)


def stop_tree(pid: int, timeout_s: float = 10.0) -> None:
    """
    Stops process ``pid`` and every process under it: those under it are killed (a stage's worker pools and their
    forkserver, which outlive a stage killed alone), then ``pid`` is sent SIGTERM, so that a process under
    sigterm_raises unwinds and lets go of what it holds, and is killed if it has not ended after ``timeout_s``.
    """
    try:
        root = psutil.Process(pid)
        under = root.children(recursive=True)  # listed before any goes: an orphan is no one's child
    except psutil.NoSuchProcess:
        return
    # a multiprocessing resource tracker is left to end on its own once those it serves are gone: it then unlinks
    # the semaphores they leave (killed, it would leave them on /dev/shm)
    under = [process for process in under if not _is_resource_tracker(process)]
    for process in under:
        with contextlib.suppress(psutil.NoSuchProcess):
            process.kill()
    psutil.wait_procs(under, timeout=timeout_s)
    with contextlib.suppress(psutil.NoSuchProcess):
        root.terminate()
        _, alive = psutil.wait_procs([root], timeout=timeout_s)
        for process in alive:
            process.kill()


def _is_resource_tracker(process: psutil.Process) -> bool:
    try:
        return any("multiprocessing.resource_tracker" in part for part in process.cmdline())
    except psutil.Error:
        return False
