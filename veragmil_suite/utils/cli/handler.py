"""The handler every console program runs under: an expected error is one line on stderr and exit status 2, Ctrl-C one
line and 130 (the shell's status for an interrupted program), SIGTERM one line and 143 after the same clean-up.
"""

from __future__ import annotations

import argparse
import errno
import functools
import os
import select
import signal
import sys
from collections.abc import Callable
from typing import Any

from veragmil_suite.utils.cli.files import one_line
from veragmil_suite.utils.cli.kinds import Kind, count, non_negative
from veragmil_suite.utils.termination import Terminated, sigterm_raises


class UsageError(Exception):
    """Bad input found after parsing: the handler prints it as one line and exits 2."""


# errors the handler reports in one line, by class name (importing their modules here would import h5py or Ray)
EXPECTED_ERRORS = (
    "veragmil_suite.data.schema.DatasetError",
    "veragmil_suite.utils.distributed.RayMissing",
    "veragmil_suite.data.lerobot_export.ExtraNotInstalled",
)
# OSErrors about the user's files, folders, disk or addresses, not about our code
USER_ERRNOS = {
    errno.ENOENT,
    errno.EACCES,
    errno.EPERM,
    errno.EISDIR,
    errno.ENOTDIR,
    errno.ENAMETOOLONG,
    errno.EROFS,
    errno.ENOSPC,
    errno.EDQUOT,
    errno.EEXIST,
    errno.EADDRINUSE,
    errno.EADDRNOTAVAIL,
    errno.EAGAIN,
}


def check_option(option: str, value: str, kind: Kind) -> Any:
    """``kind(value)`` for a value a program derives from its options; UsageError names ``option`` when refused."""
    try:
        return kind(value)
    except argparse.ArgumentTypeError as error:
        raise UsageError(f"{option}: {error}") from None


def refuse_existing(path: str | None, force: bool, option: str = "--force") -> None:
    """Refuses to write over a file or folder that is there unless ``option`` (--force) was given: what was
    recorded or written before is lost only when asked."""
    if path is not None and os.path.lexists(path) and not force:
        raise UsageError(f"{path} exists (use {option} to overwrite it)")


# the numbers programs read from the environment, with the kind of value each takes
ENVIRONMENT_SETTINGS = {
    "VERAGMIL_TORCH_THREADS": count,  # torch threads of a training run or a policy
    "VERAGMIL_RESUME_EVERY_S": non_negative,  # seconds between saves of a training's resume state
}


def check_environment() -> None:
    """Refuses a malformed ENVIRONMENT_SETTINGS value before a program runs (a set but empty one is unset)."""
    for name, kind in ENVIRONMENT_SETTINGS.items():
        value = os.environ.get(name)
        if value:
            check_option(f"${name}", value, kind)


def _expected(error: BaseException) -> bool:
    if isinstance(error, UsageError):
        return True
    if isinstance(error, OSError):
        return error.filename is not None or error.errno in USER_ERRNOS
    return any(f"{c.__module__}.{c.__qualname__}" in EXPECTED_ERRORS for c in type(error).__mro__)


def _stdout_reader_gone() -> bool:
    """Whether standard output is a pipe whose reader has closed it (a broken socket elsewhere is not)."""
    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
        return any(events & select.POLLERR for _, events in poller.poll(0))
    except (OSError, ValueError, AttributeError):  # no file descriptor (captured output), or no poll()
        return False


def error_line(error: BaseException) -> str:
    """An expected error as one line: an OSError as 'PATH: reason', anything else as its message."""
    if isinstance(error, OSError) and error.filename is not None and error.strerror:
        return f"{error.filename}: {error.strerror}"
    return one_line(error)


def command(
    build_parser: Callable[[], argparse.ArgumentParser], interrupted: str = "interrupted"
) -> Callable[[Callable[[argparse.Namespace], int | None]], Callable[[list[str] | None], int]]:
    """
    Makes ``run(args) -> int`` a console program's ``main(argv=None) -> int`` (the exit status, also for --help and
    a value argparse refused): parses ``argv`` with ``build_parser()`` (kept as ``main.build_parser`` for
    tests/test_cli.py), runs, and turns an expected error
    (UsageError, our dataset and Ray errors, an OSError about the user's files, disk or addresses, a malformed
    ENVIRONMENT_SETTINGS value) into one line on stderr and exit status 2, Ctrl-C into one line (``interrupted``)
    and 130, and SIGTERM, raised as Terminated so that what the program started and holds is let go as on Ctrl-C,
    into one line and 143; output whose reader has gone (``| head``) ends quietly with 141.
    """

    def decorate(run: Callable[[argparse.Namespace], int | None]) -> Callable[[list[str] | None], int]:
        @functools.wraps(run)
        def main(argv: list[str] | None = None) -> int:
            parser = build_parser()
            try:
                args = parser.parse_args(argv)
            except SystemExit as stop:  # argparse printed --help, or the bad value in one line
                return stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 2)
            try:
                check_environment()
                with sigterm_raises():
                    return int(run(args) or 0)
            except KeyboardInterrupt:
                print(f"\n{parser.prog}: {interrupted}", file=sys.stderr)
                return 130
            except Terminated:
                print(f"\n{parser.prog}: terminated", file=sys.stderr)
                return 128 + signal.SIGTERM
            except Exception as error:
                if isinstance(error, BrokenPipeError) and _stdout_reader_gone():
                    # the reader of the output went away (``| head``): quiet, as a shell tool, with the status
                    # SIGPIPE gives one; what is left unflushed goes nowhere instead of failing again at exit
                    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
                    return 128 + signal.SIGPIPE
                if not _expected(error):
                    raise
                print(f"{parser.prog}: {error_line(error)}", file=sys.stderr)
                return 2

        main.build_parser = build_parser
        return main

    return decorate
