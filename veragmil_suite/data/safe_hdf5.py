"""HDF5 files that a cut-short write never damages, written by one process at a time.

A file is never changed in place. Its new state is written to a working copy beside it (a copy of the file, or a
new file), flushed to disk and renamed over it in one atomic step, so a kill, a full disk or an I/O error at any
instant leaves the old file or the new one, each complete. A kill leaves its working copy behind
(``.<name>.<8 hex>.writing``): working_copies finds it, remove_working_copies removes it.

HDF5 never sees an I/O error: it writes through a file object that, once the disk refuses a write, keeps the rest
of the write in memory so HDF5 finishes and closes cleanly; the error is raised after that (HDF5 2.0's own error
paths after a failed write can crash the process). Code that writes much at once calls WorkingCopy.check between
parts to stop at the first failure.

One writer per file: a lock on a hidden file beside it (``.<name>.lock``, flock), taken before anything is done and
held for as long as the writer needs (a recording session), so a second writer is refused at once.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import os
import re
import secrets
import shutil
from collections.abc import Iterator
from pathlib import Path

import h5py

WORKING_SUFFIX = ".writing"
LOCK_SUFFIX = ".lock"
_MAX_STEM = 200  # hidden names keep this much of the file's name: with a suffix they stay under NAME_MAX (255)


class WriteFailed(OSError):
    """The disk refused a write (full, an I/O error, read-only): the file is as it was before."""


class FileInUse(OSError):
    """Another process holds the file's write lock."""


def _stem(path: Path) -> str:
    name = path.name
    if len(name.encode()) <= _MAX_STEM:
        return name
    digest = hashlib.sha1(name.encode()).hexdigest()[:12]
    return name.encode()[: _MAX_STEM - 13].decode(errors="ignore") + "-" + digest


def _on_disk(path: str | Path) -> Path:
    """The file a path names, through symbolic links: a change replaces it, not the link."""
    return Path(os.path.realpath(path))


def lock_path(path: str | Path) -> Path:
    path = _on_disk(path)
    return path.with_name(f".{_stem(path)}{LOCK_SUFFIX}")


def working_copies(path: str | Path) -> list[Path]:
    """Working copies of ``path`` left beside it: each the state of a write that was cut short (or is under way,
    while the lock is held)."""
    path = _on_disk(path)
    pattern = re.compile(re.escape(f".{_stem(path)}.") + r"[0-9a-f]{8}" + re.escape(WORKING_SUFFIX))
    try:
        return sorted(p for p in path.parent.iterdir() if pattern.fullmatch(p.name))
    except OSError:
        return []


def working_copy_path(path: str | Path) -> Path:
    """A new working copy's name beside ``path`` (the file on disk), which working_copies finds once a kill left it."""
    target = _on_disk(path)
    return target.with_name(f".{_stem(target)}.{secrets.token_hex(4)}{WORKING_SUFFIX}")


def remove_working_copies(path: str | Path) -> list[Path]:
    """Delete the working copies left beside ``path`` (call with its lock held); returns them."""
    removed = working_copies(path)
    for p in removed:
        with contextlib.suppress(FileNotFoundError):
            p.unlink()
    return removed


class FileLock:
    """
    The write lock of one file: flock on ``.<name>.lock`` beside it, not blocking. The lock file is removed on
    release; a lock file a killed process left is taken over (flock dies with its holder).
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.lock_file = lock_path(self.path)
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def acquire(self) -> None:
        """Take the lock; FileInUse when another process (or another writer here) holds it."""
        if self._fd is not None:
            return
        while True:
            try:
                fd = os.open(self.lock_file, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            except OSError as e:
                raise WriteFailed(f"{self.path}: cannot write in its folder ({e.strerror or e})") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                raise FileInUse(f"{self.path} is in use by another process, which is writing it") from None
            # the holder before us may have removed the lock file after we opened it: lock the one at the path
            try:
                same = os.stat(self.lock_file).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                self._fd = fd
                return
            os.close(fd)

    def release(self) -> None:
        if self._fd is None:
            return
        with contextlib.suppress(OSError):
            self.lock_file.unlink()
        os.close(self._fd)
        self._fd = None

    def in_use_elsewhere(self) -> bool:
        """Whether another process holds the lock now (for readers that want to say so)."""
        if self._fd is not None:
            return False
        try:
            fd = os.open(self.lock_file, os.O_RDONLY | os.O_CLOEXEC)
        except OSError:
            return False
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        finally:
            os.close(fd)
        return False

    def __del__(self):
        with contextlib.suppress(Exception):  # at interpreter exit what it uses may be gone already
            self.release()


class _GuardedFile:
    """
    The working copy as HDF5 sees it (h5py's file-object driver): positioned reads and writes on one descriptor.
    After the first refused write (or truncate) it records the error and keeps every later write in memory, and
    reads see them, so HDF5 goes on and closes without an error path.
    """

    def __init__(self, fd: int):
        self.fd = fd
        self.pos = 0
        self.error: OSError | None = None
        self._overlay: list[tuple[int, bytes]] = []
        self._overlay_end = 0

    def seek(self, pos: int, whence: int = os.SEEK_SET) -> int:
        if whence == os.SEEK_SET:
            self.pos = pos
        elif whence == os.SEEK_CUR:
            self.pos += pos
        else:
            self.pos = max(os.fstat(self.fd).st_size, self._overlay_end) + pos
        return self.pos

    def tell(self) -> int:
        return self.pos

    def readinto(self, buffer: bytearray | memoryview) -> int:
        view = memoryview(buffer).cast("B")
        n = os.preadv(self.fd, [view], self.pos)
        view[n:] = bytes(len(view) - n)
        for offset, data in self._overlay:
            lo, hi = max(offset, self.pos), min(offset + len(data), self.pos + len(view))
            if lo < hi:
                view[lo - self.pos : hi - self.pos] = data[lo - offset : hi - offset]
        self.pos += len(view)
        return len(view)

    def read(self, size: int) -> bytes:
        buffer = bytearray(size)
        return bytes(buffer[: self.readinto(buffer)])

    def write(self, buffer: bytes | bytearray | memoryview) -> int:
        data = memoryview(buffer).cast("B")
        if self.error is None:
            try:
                done = 0
                while done < len(data):
                    done += os.pwrite(self.fd, data[done:], self.pos + done)
            except OSError as e:
                self.error = e
        if self.error is not None:
            self._overlay.append((self.pos, bytes(data)))
            self._overlay_end = max(self._overlay_end, self.pos + len(data))
        self.pos += len(data)
        return len(data)

    def truncate(self, size: int | None = None) -> int:
        size = self.pos if size is None else size
        if self.error is None:
            try:
                os.ftruncate(self.fd, size)
            except OSError as e:
                self.error = e
        return size

    def flush(self) -> None:
        pass


class WorkingCopy:
    """An h5py File (``file``) on the working copy of a write under way (see replaced)."""

    def __init__(self, path: Path, file: h5py.File, guard: _GuardedFile):
        self.path = path
        self.file = file
        self._guard = guard

    def check(self) -> None:
        """WriteFailed now if the disk refused a write so far (the rest would only go to memory)."""
        if self._guard.error is not None:
            raise _failed(self.path, self._guard.error)


def _failed(path: Path, error: OSError) -> WriteFailed:
    state = "it is unchanged" if path.exists() else "nothing was written"
    return WriteFailed(f"{path} could not be written ({error.strerror or error}); {state}")


@contextlib.contextmanager
def replaced(path: str | Path, new: bool = False, lock: FileLock | None = None) -> Iterator[WorkingCopy]:
    """
    Change ``path`` (or, with ``new``, write it anew) as one atomic step: yields a WorkingCopy whose ``file`` is
    open for writing; at a clean exit it is flushed to disk and renamed over ``path``; at an exception, a full
    disk or an I/O error it is removed and ``path`` is as it was. The file's write lock is taken for the while
    unless ``lock`` (held by the caller) is given; the working copies killed writes left are removed first.

    Raises:
        FileInUse: [another process writes ``path``]
        WriteFailed: [the disk refused a write (full, an I/O error, read-only folder)]
    """
    path = Path(path)
    own_lock = lock is None
    if own_lock:
        lock = FileLock(path)
        lock.acquire()
    elif not lock.held:
        raise RuntimeError(f"the write lock of {path} is not held")
    target = _on_disk(path)
    remove_working_copies(target)  # what writes killed before left: with the lock held, none is under way
    copy = working_copy_path(target)
    try:
        try:
            fd = os.open(copy, os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o644)
        except OSError as e:
            raise _failed(path, e) from None
        try:
            try:
                if not new and target.exists():
                    with open(target, "rb") as source:
                        _copy(source.fileno(), fd)
                    shutil.copymode(target, copy)
                    mode = "r+"
                else:
                    mode = "w"
            except OSError as e:
                raise _failed(path, e) from None
            guard = _GuardedFile(fd)
            with h5py.File(guard, mode) as f:
                working = WorkingCopy(path, f, guard)
                yield working
            working.check()
            try:
                os.fsync(fd)
            except OSError as e:
                raise _failed(path, e) from None
        finally:
            os.close(fd)
        try:
            os.replace(copy, target)
            _fsync_folder(target.parent)
        except OSError as e:
            raise _failed(path, e) from None
    finally:
        with contextlib.suppress(FileNotFoundError):
            copy.unlink()  # gone already once renamed over path
        if own_lock:
            lock.release()


def _copy(source: int, target: int) -> None:
    """The whole of file descriptor ``source`` into ``target``, in the kernel where it can."""
    size = os.fstat(source).st_size
    offset = 0
    try:
        while offset < size:
            sent = os.sendfile(target, source, offset, size - offset)
            if sent == 0:
                break
            offset += sent
    except OSError as e:
        if e.errno not in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP):
            raise
        while chunk := memoryview(os.pread(source, 1 << 20, offset)):
            while chunk:
                written = os.pwrite(target, chunk, offset)
                chunk, offset = chunk[written:], offset + written


def _fsync_folder(folder: Path) -> None:
    """Make a rename in ``folder`` durable (where the filesystem allows opening a folder)."""
    try:
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    except OSError:
        return
    try:
        with contextlib.suppress(OSError):
            os.fsync(fd)
    finally:
        os.close(fd)
