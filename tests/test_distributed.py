"""Local worker pools (veragmil_suite.utils.distributed without Ray): where the workers come from, what a dead one
does. The Ray backend: test_ray.py."""

import os
from pathlib import Path

import pytest

from veragmil_suite.utils.distributed import WorkerLost, run_pieces


def parents_libraries(_, n: int) -> tuple[int, str]:
    """The piece's worker's parent process and the files mapped into that parent's memory."""
    return os.getppid(), Path(f"/proc/{os.getppid()}/maps").read_text()


def dies(_, n: int) -> int:
    os._exit(1)


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="reads a process's mapped files from /proc")
def test_local_workers_fork_from_a_server_that_imported_the_package_once():
    results = dict(run_pieces(parents_libraries, range(4), processes=2))
    (server,) = {parent for parent, _ in results.values()}
    assert server != os.getpid()  # a forkserver, not this process
    assert all("mujoco" in maps for _, maps in results.values())  # it holds MuJoCo: the workers inherit the import


def test_a_local_worker_that_dies_stops_the_run_with_worker_lost():
    with pytest.raises(WorkerLost, match="a worker process died"):
        list(run_pieces(dies, range(2), processes=2))
