"""A write cut short leaves a file every tool reads, and a file has one writer at a time: a kill before every call
that changes the disk, a full disk and an I/O error at every write, a real full disk under veragmil-collect and
veragmil-render-obs, and a second writer refused before it records."""

import errno
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers.recording import synthetic_episode, synthetic_writer

from veragmil_suite.data import safe_hdf5
from veragmil_suite.data.datasets import clean_dataset, dataset_summary
from veragmil_suite.data.schema import DatasetError, demo_names, open_dataset
from veragmil_suite.scripts import dataset_tools

BIN = Path(sys.executable).parent
# every os call by which the writer changes what is on disk: a kill before any of them is a kill at that instant
DISK_CALLS = ("open", "pwrite", "sendfile", "ftruncate", "fsync", "replace", "rename", "unlink")


def _recorded(path: Path, demos: int = 2) -> bytes:
    with synthetic_writer(path) as writer:
        for seed in range(demos):
            writer.write(synthetic_episode(seed=seed))
    return path.read_bytes()


def _read_whole(path: Path) -> list[str]:
    """The demos of ``path`` as our tools read them (schema checked, every dataset read whole), and as robomimic
    does: the demos of data/ by their index, with their num_samples."""
    with open_dataset(path) as f:
        names = demo_names(f)
        for name in names:
            f["data"][name].visititems(lambda _, d: d[()] if isinstance(d, h5py.Dataset) else None)
    with h5py.File(path, "r") as f:
        demos = sorted(f["data"].keys(), key=lambda n: int(n[5:]))
        assert [int(f[f"data/{n}"].attrs["num_samples"]) for n in demos] == [20] * len(demos)
    return names


def _leftovers(path: Path) -> list[str]:
    return sorted(p.name for p in path.parent.iterdir() if p.name.startswith("."))


def _counting(calls: list, kill_at: int | None = None):
    """Wraps DISK_CALLS to list them in ``calls`` as they come, and SIGKILLs this process before call ``kill_at``."""
    for name in DISK_CALLS:
        real = getattr(os, name)

        def call(*args, _real=real, _name=name, **kwargs):
            calls.append(_name)
            if len(calls) == kill_at:
                os.kill(os.getpid(), signal.SIGKILL)
            return _real(*args, **kwargs)

        setattr(os, name, call)


def _killed_writing(path: Path, kill_at: int) -> int:
    """A forked child appends one demo to ``path`` and is SIGKILLed before its disk call ``kill_at``; returns its
    exit status (-SIGKILL; 0 when the write made fewer calls)."""

    def write():
        _counting([], kill_at)
        with synthetic_writer(path) as writer:
            writer.write(synthetic_episode(seed=7))

    return _in_child(write)


def _in_child(action) -> int:
    """Runs ``action`` in a forked child; returns its exit status (-9 when killed)."""
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            action()
            code = 0
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    return -os.WTERMSIG(status) if os.WIFSIGNALED(status) else os.WEXITSTATUS(status)


def _disk_calls(path: Path) -> list[str]:
    """The disk calls one append to ``path`` makes, in order (learnt in a child, on a copy)."""
    probe = path.with_name("probe.hdf5")
    shutil.copy(path, probe)
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:
        calls: list[str] = []
        _counting(calls)
        with synthetic_writer(probe) as writer:
            writer.write(synthetic_episode(seed=7))
        os.write(write, ",".join(calls).encode())
        os._exit(0)
    os.close(write)
    with os.fdopen(read) as f:
        calls = f.read().split(",")
    os.waitpid(pid, 0)
    probe.unlink()
    return calls


def test_a_write_replaces_the_file_and_never_changes_it_in_place(tmp_path):
    """The root of crash safety: a reader holding the file sees it unchanged while a demo is appended, and the
    new state arrives by one rename (another inode), never by writing into the file."""
    path = tmp_path / "demos.hdf5"
    before = _recorded(path)
    with open(path, "rb") as reader:
        inode = os.fstat(reader.fileno()).st_ino
        with synthetic_writer(path) as writer:
            writer.write(synthetic_episode(seed=5))
        assert os.stat(path).st_ino != inode
        reader.seek(0)
        assert reader.read() == before
    assert _read_whole(path) == ["demo_0", "demo_1", "demo_2"]
    assert _leftovers(path) == []  # no working copy, no lock file


def test_a_kill_before_any_disk_call_of_a_write_leaves_every_demo_before_it(tmp_path):
    path = tmp_path / "demos.hdf5"
    before = _recorded(path)
    calls = _disk_calls(path)
    assert calls.count("pwrite") > 20 and calls.count("replace") == 1
    for k in range(1, len(calls) + 1):  # every instant at which a kill changes what is on disk
        path.write_bytes(before)
        for name in _leftovers(path):  # the same start each time (the next writer would remove them)
            (tmp_path / name).unlink()
        assert _killed_writing(path, k) == -signal.SIGKILL
        names = _read_whole(path)  # readable, by our tools and robomimic's way
        renamed = k > calls.index("replace") + 1
        assert names == (["demo_0", "demo_1", "demo_2"] if renamed else ["demo_0", "demo_1"]), k
        if not renamed:
            assert path.read_bytes() == before, k  # the old file, to the byte
    assert _killed_writing(path, len(calls) + 1) == 0
    # killed with its demo complete but not renamed: the tools say what was lost; --clean, or the next writer,
    # removes what it left
    path.write_bytes(before)
    _killed_writing(path, calls.index("replace") + 1)
    left = dataset_summary(path)["interrupted_writes"]
    assert len(left) == 1 and left[0].endswith(".writing") and not dataset_summary(path)["being_written"]
    assert clean_dataset(path) == left and _leftovers(path) == []
    _killed_writing(path, calls.index("replace") + 1)
    with synthetic_writer(path) as writer:
        writer.write(synthetic_episode(seed=8))
    assert _read_whole(path) == ["demo_0", "demo_1", "demo_2"] and _leftovers(path) == []


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EIO])
def test_a_refused_write_at_any_point_leaves_the_file_as_it_was(tmp_path, monkeypatch, code):
    path = tmp_path / "demos.hdf5"
    before = _recorded(path)
    calls = _disk_calls(path)
    for name in ("pwrite", "sendfile", "ftruncate", "fsync", "replace"):
        for k in range(1, calls.count(name) + 1):
            path.write_bytes(before)
            seen = [0]
            real = getattr(os, name)

            def refuse(*args, _real=real, _k=k, seen=seen, **kwargs):
                seen[0] += 1
                if seen[0] >= _k:
                    raise OSError(code, os.strerror(code))
                return _real(*args, **kwargs)

            monkeypatch.setattr(os, name, refuse)
            with synthetic_writer(path) as writer:
                try:
                    writer.write(synthetic_episode(seed=7))
                except DatasetError as error:
                    assert os.strerror(code) in str(error) and "unchanged" in str(error), (name, k, error)
                    assert path.read_bytes() == before, (name, k)
                else:
                    # only the folder's fsync may fail unsaid: the rename is done, its durability is best effort
                    assert name == "fsync" and k > 1
                    assert _read_whole(path) == ["demo_0", "demo_1", "demo_2"]
            monkeypatch.setattr(os, name, real)
            assert _read_whole(path)[:2] == ["demo_0", "demo_1"] and _leftovers(path) == [], (name, k)


def test_a_full_disk_mid_merge_fails_in_one_line_with_the_input_intact(tmp_path, monkeypatch, capsys):
    source = tmp_path / "in.hdf5"
    before = _recorded(source)
    out = tmp_path / "out.hdf5"
    real, seen = os.pwrite, [0]

    def full(*args):
        seen[0] += 1
        if seen[0] > 40:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(*args)

    monkeypatch.setattr(os, "pwrite", full)
    assert dataset_tools.merge_main([str(source), "--output", str(out)]) == 2
    err = capsys.readouterr().err
    assert "No space left on device" in err and len(err.strip().splitlines()) == 1
    assert source.read_bytes() == before and not out.exists() and _leftovers(out) == []


def _mount_tmpfs(folder: Path, size: str) -> bool:
    folder.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    return subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)]).returncode == 0


def _fill(folder: Path, leave: int) -> None:
    free = shutil.disk_usage(folder).free - leave
    with open(folder / "filler", "wb") as f:
        while free > 0:
            free -= f.write(b"\0" * min(free, 1 << 16))


def _run(*command, timeout=300):
    return subprocess.run(
        [str(BIN / command[0]), *map(str, command[1:])],
        capture_output=True,
        text=True,
        stdin=subprocess.DEVNULL,
        env=dict(os.environ, MUJOCO_GL="osmesa"),
        timeout=timeout,
    )


def test_on_a_real_full_disk_collect_and_render_obs_fail_in_one_line_and_keep_the_file(tmp_path, capsys):
    """veragmil-collect appending on a full 3 MB tmpfs, and veragmil-render-obs writing there (which crashed, and
    left a file every tool failed on): one line, exit 2, every demo before kept (needs root to mount a tmpfs)."""
    from veragmil_suite.scripts import collect_human_demonstrations as collect

    disk = tmp_path / "disk"
    if not _mount_tmpfs(disk, "3m"):
        pytest.skip("needs root and mount to make a small tmpfs")
    try:
        path = disk / "c.hdf5"
        args = ["--device", "scripted", "--food", "pasta", "--n-grains", "8", "--horizon", "10", "--keep", "all"]
        args += ["--camera-size", "32", "--quiet", "--output", str(path)]
        assert collect.main([*args, "--episodes", "2"]) == 0
        before = path.read_bytes()
        _fill(disk, 40_000)
        full = _run("veragmil-collect", *args, "--episodes", "2")
        assert full.returncode == 2, full.stderr[-2000:]
        lines = [line for line in full.stderr.splitlines() if line.startswith("veragmil-collect:")]
        assert len(lines) == 1 and "No space left on device" in lines[0] and "Traceback" not in full.stderr
        assert path.read_bytes() == before and _leftovers(path) == []
        render = _run("veragmil-render-obs", path, "--output", disk / "r.hdf5", "--cameras", "agentview")
        assert render.returncode == 2 and "No space left on device" in render.stderr, render.stderr[-2000:]
        assert "Traceback" not in render.stderr and path.read_bytes() == before and not (disk / "r.hdf5").exists()
        capsys.readouterr()
        assert dataset_tools.info_main([str(path), "--clean"]) == 0
        assert "c.hdf5: 2 demos" in capsys.readouterr().out
    finally:
        subprocess.run(["umount", str(disk)])


HOLDER = textwrap.dedent(
    """
    import sys, time, h5py
    f = h5py.File(sys.argv[1], "a")  # another program holding the file open for writing (HDF5 locks it)
    print("HOLDING", flush=True)
    time.sleep(60)
    """
)


def test_a_second_writer_is_refused_at_once_and_before_it_records(tmp_path, capsys):
    path = tmp_path / "demos.hdf5"
    _recorded(path)
    with synthetic_writer(path) as first:
        with pytest.raises(DatasetError, match="in use by another process"):
            synthetic_writer(path)
        # veragmil-collect on the same file: refused before it builds an env or records an episode
        started = time.monotonic()
        other = _run("veragmil-collect", "--device", "scripted", "--food", "pasta", "--episodes", "1", "--output", path)
        assert other.returncode == 2 and "in use by another process" in other.stderr, other.stderr[-2000:]
        assert "episode" not in other.stdout and time.monotonic() - started < 60
        # readers read on, and say so; a cleaner is refused
        capsys.readouterr()
        assert dataset_tools.info_main([str(path)]) == 0
        assert "BEING WRITTEN by another process" in capsys.readouterr().out
        assert dataset_tools.info_main([str(path), "--clean"]) == 2
        assert "in use by another process" in capsys.readouterr().err
        first.write(synthetic_episode(seed=9))  # the holder writes on
    with synthetic_writer(path) as second:  # released: the next writer goes ahead
        second.write(synthetic_episode(seed=10))
    assert _read_whole(path) == ["demo_0", "demo_1", "demo_2", "demo_3"] and _leftovers(path) == []


def test_a_file_another_program_holds_open_for_writing_is_said_in_use_not_corrupt(tmp_path):
    path = tmp_path / "demos.hdf5"
    _recorded(path)
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(path)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "HOLDING"
        with pytest.raises(DatasetError, match="in use by another process") as refused:
            open_dataset(path)
        assert "corrupt" not in str(refused.value)
        with pytest.raises(DatasetError, match="in use by another process"):
            synthetic_writer(path)
    finally:
        holder.kill()
        holder.wait()
    assert _leftovers(path) == []


def test_hidden_names_of_a_long_file_name_stay_within_the_filesystems_limit(tmp_path):
    path = tmp_path / ("d" * 250 + ".h5")
    _recorded(path, demos=1)
    assert _read_whole(path) == ["demo_0"] and _leftovers(path) == []
    assert len(safe_hdf5.lock_path(path).name) <= 255


def test_a_refused_demo_leaves_the_file_as_it_was(tmp_path):
    path = tmp_path / "demos.hdf5"
    before = _recorded(path)
    with synthetic_writer(path) as writer:
        other = synthetic_episode(seed=3)
        other.obs["overhead_image"] = np.zeros((20, 8, 8, 3), dtype=np.uint8)  # another camera size than the file's
        with pytest.raises(DatasetError, match="observations differ"):
            writer.write(other)
    assert path.read_bytes() == before and _leftovers(path) == []


def test_writing_through_a_symbolic_link_changes_its_target_and_keeps_the_link(tmp_path):
    target = tmp_path / "store" / "demos.hdf5"
    target.parent.mkdir()
    _recorded(target, demos=1)
    link = tmp_path / "link.hdf5"
    link.symlink_to(target)
    with synthetic_writer(link) as writer:
        writer.write(synthetic_episode(seed=4))
    assert link.is_symlink() and _read_whole(target) == ["demo_0", "demo_1"]
    assert _leftovers(target) == [] and _leftovers(link) == []


def _scribble_over(path: Path, *objects: str) -> None:
    """Overwrite the object headers of ``objects`` with garbage: what a write cut short in place left (the
    writers before safe_hdf5, or another program)."""
    with h5py.File(path, "r") as f:
        addresses = [h5py.h5o.get_info(f[name].id).addr for name in objects]
    data = bytearray(path.read_bytes())
    for address in addresses:
        data[address : address + 24] = b"\xff" * 24
    path.write_bytes(bytes(data))


def test_a_file_damaged_in_place_is_named_and_clean_keeps_the_demos_that_read(tmp_path, capsys):
    path = tmp_path / "demos.hdf5"
    _recorded(path, demos=3)
    _scribble_over(path, "data/demo_1/actions", "mask/valid")
    with pytest.raises(DatasetError, match="demo_1 is incomplete.*--clean keeps the demos that still read"):
        open_dataset(path)
    capsys.readouterr()
    assert dataset_tools.info_main([str(path)]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    assert dataset_tools.info_main([str(path), "--clean"]) == 0
    said = capsys.readouterr().out
    assert "data/demo_1 (is incomplete: no 'actions' dataset)" in said and "mask/valid (damaged)" in said
    assert _read_whole(path) == ["demo_0", "demo_2"] and _leftovers(path) == []
    with h5py.File(path, "r") as f:
        members = sorted(m.decode() for key in ("train", "valid") for m in f["mask"][key][()])
    assert members == ["demo_0", "demo_2"]
    with synthetic_writer(path) as writer:  # appended to again
        assert writer.write(synthetic_episode(seed=5)) == "demo_3"
