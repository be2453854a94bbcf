"""Files written whole or not at all, and never over one of their own inputs.

A program's outputs (tables, records, settings a study resumes from, videos) are written under a temporary name
beside their place and renamed onto it once complete: a kill, a full disk or an error part-way leaves the file that
was there, never half of the new one. HDF5 datasets have their own writer (veragmil_suite.data.safe_hdf5). Records
that grow a line at a time (an evaluation's journal) are appended whole lines: a line a kill cut short is left out
when read and cut off before the next line is appended.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path


def same_file(a: str | Path, b: str | Path) -> bool:
    """True when ``a`` and ``b`` name one file or folder: the same path once resolved (symbolic links, ``..``), or
    two names of one file (a hard link), which a write to either would change."""
    if Path(a).resolve() == Path(b).resolve():
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:  # either is not there: then they are not one file
        return False


@contextlib.contextmanager
def written_whole(path: str | Path, keep_suffix: bool = False) -> Iterator[Path]:
    """
    Yields a temporary path beside ``path`` to write the file to, renamed onto ``path`` when the block ends (a block
    that wrote nothing leaves ``path`` as it was) and removed when it raises. It ends in ``.partial`` (no search for
    ``*.pth`` or ``*.json`` finds one a kill left), or with ``keep_suffix`` in ``path``'s own suffix, for writers that
    read the format from the name (matplotlib, imageio).
    """
    path = Path(path)
    # the name cut so that one at the file system's length limit still has room for the temporary one's
    tail = f".{os.getpid()}.partial"
    partial = path.with_name(f".{path.stem[:180]}{tail}{path.suffix}" if keep_suffix else f".{path.name[:180]}{tail}")
    try:
        yield partial
        if partial.exists():
            os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)


def write_whole(path: str | Path, write: Callable[[Path], object]) -> None:
    """``write(partial)`` writes the file under a temporary name, then it is renamed onto ``path``."""
    with written_whole(path) as partial:
        write(partial)


def write_text_whole(path: str | Path, text: str) -> None:
    """``path`` holds ``text``, written whole (written_whole)."""
    with written_whole(path) as partial:
        partial.write_text(text)


def _aside(folder: Path) -> Path:
    return folder.with_name(f".{folder.name}.replaced")


def put_folder_in_place(partial: str | Path, folder: str | Path) -> None:
    """Moves the complete folder ``partial`` to ``folder``. The folder it replaces is set aside whole first and
    deleted after: a kill at any instant leaves one of the two complete, which recover_folder puts in place."""
    partial, folder = Path(partial), Path(folder)
    if folder.exists():
        folder.rename(_aside(folder))
    partial.rename(folder)
    shutil.rmtree(_aside(folder), ignore_errors=True)


def recover_folder(folder: str | Path) -> None:
    """What a kill in put_folder_in_place left: the replaced folder back in place when nothing took its place,
    otherwise deleted."""
    folder = Path(folder)
    aside = _aside(folder)
    if aside.exists():
        if folder.exists():
            shutil.rmtree(aside)
        else:
            aside.rename(folder)


def json_lines(path: str | Path) -> list:
    """The records of a file appended a JSON line at a time (append_line): a last line a kill cut short (no newline
    at its end) is left out, and so is a line that does not parse."""
    text = Path(path).read_text()
    records = []
    for line in text[: text.rfind("\n") + 1].splitlines():
        try:
            records.append(json.loads(line))
        except ValueError:
            continue
    return records


def append_line(path: str | Path, line: str) -> None:
    """Appends ``line`` and its newline to ``path``. A last line a kill cut short is cut off first, so the new one
    starts on a line of its own instead of joining it."""
    with open(path, "a+b") as f:
        end = f.seek(0, os.SEEK_END)
        if end:
            f.seek(end - 1)
            if f.read(1) != b"\n":
                f.seek(0)
                f.truncate(f.read().rfind(b"\n") + 1)
        f.write(line.encode() + b"\n")
