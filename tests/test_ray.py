"""
--ray: a tiny study on a local Ray instance (2 CPUs, loopback only) gives the tables, episodes and recordings of the
same study in local processes; veragmil-evaluate --ray scores the same episode; Ray workers take the driver's
settled piles (their own pile cache is empty) and settle none; a worker that dies has its piece run again; a
piece's own error stops the run; without the flag nothing imports Ray, and with it but no Ray one line names the
install command.
"""

import contextlib
import csv
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import h5py
import pytest
from helpers.programs import BIN, run_program
from test_pipeline import CHEAP_STUDY

from veragmil_suite.environments.settling import PileNotShipped, cache_dir
from veragmil_suite.utils import distributed
from veragmil_suite.utils.distributed import THIS_MACHINE, WorkerLost, ray_session, run_pieces

# one worker runs this file's tests, so its module fixtures are built once (make test: --dist loadgroup), and the
# killed-study test (the group's other member) never runs beside their studies: both start many processes
pytestmark = pytest.mark.xdist_group("studies")

# the smallest grid: one demo of pasta, 2 x 5 gradient steps, one episode of each agent on pasta
GRID = [*CHEAP_STUDY, "--eval-foods", "pasta", "--demos-per-food", "1", "--episodes", "1", "--processes", "2"]
# what an episode's outcome is: every column of episodes.csv but its wall time
NOT_OUTCOME = ("wall_s",)
SENTINEL_SPEED = 123.0
# the two studies took 72 s beside the other worker's tests
STUDY_TIMEOUT_S = 400


@pytest.fixture(scope="module")
def ray_address(tmp_path_factory):
    """A Ray instance of 2 CPUs on 127.0.0.1, owned by this process (stopped at the end); its workers see an empty
    pile cache of their own, so every pile they use is one the driver handed them."""
    worker_cache = tmp_path_factory.mktemp("worker_pile_cache")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("VERAGMIL_CACHE_DIR", str(worker_cache))  # read by the raylet and its workers as they start
        session = ray_session(THIS_MACHINE, num_cpus=2)
        address = session.__enter__()
    try:
        yield address
    finally:
        session.__exit__(None, None, None)


@pytest.fixture(scope="module")
def grids(ray_address, tmp_path_factory):
    """The same tiny study in local processes and on Ray, both at once (each is mostly one process at a time):
    (local output, Ray output, Ray run's stdout)."""
    out = tmp_path_factory.mktemp("grids")
    runs = {
        where: subprocess.Popen(
            [str(BIN / "veragmil-study"), *map(str, [*GRID, *flags, "--output-dir", out / where])],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            stdin=subprocess.DEVNULL,
            text=True,
            start_new_session=True,  # a study that hangs is killed with its workers
        )
        for where, flags in (("local", ["--processes", "2"]), ("ray", ["--ray", ray_address]))
    }
    said = {}
    deadline = time.monotonic() + STUDY_TIMEOUT_S  # one deadline for both: they run at once
    try:
        for where, run in runs.items():
            said[where] = run.communicate(timeout=max(0.0, deadline - time.monotonic()))
    except subprocess.TimeoutExpired:
        for run in runs.values():
            with contextlib.suppress(ProcessLookupError):
                os.killpg(run.pid, signal.SIGKILL)
        tails = {where: run.communicate()[1][-3000:] for where, run in runs.items() if where not in said}
        pytest.fail(f"the studies ran past {STUDY_TIMEOUT_S} s; stderr of those unfinished: {tails}")
    for where, run in runs.items():
        assert run.returncode == 0, f"{where}: " + said[where][0][-3000:] + said[where][1][-3000:]
    return out / "local", out / "ray", said["ray"][0]


def _outcomes(episodes_csv: Path) -> list[list[str]]:
    with open(episodes_csv) as f:
        rows = list(csv.reader(f))
    keep = [i for i, name in enumerate(rows[0]) if name not in NOT_OUTCOME]
    assert len(keep) == len(rows[0]) - len(NOT_OUTCOME)
    return [[row[i] for i in keep] for row in rows]


def test_a_study_on_ray_gives_the_tables_and_data_of_local_processes(grids):
    local, on_ray, said = grids
    assert "[veragmil] running the pieces on Ray at 127.0.0.1:" in said and "(2 CPUs, 0 GPUs)" in said
    for name in ("table.md", "table.csv", "stages.md", "stages.csv"):
        assert (on_ray / "eval" / name).read_text() == (local / "eval" / name).read_text(), name
    assert _outcomes(on_ray / "eval" / "episodes.csv") == _outcomes(local / "eval" / "episodes.csv")
    # the driver journaled each episode as its result came back from Ray (what a resumed study reads)
    journal = (on_ray / "eval" / "episodes.jsonl").read_text().splitlines()
    assert sorted(json.loads(line)["record"]["agent"] for line in journal) == [
        "expert BC no-load-size obs",
        "expert operator",
    ]
    results = [json.loads((d / "eval" / "results.json").read_text()) for d in (local, on_ray)]
    assert [r["config"]["ray"] for r in results] == [False, True]
    assert results[0]["summary"] == results[1]["summary"]
    # the demo recorded by Ray tasks is the one recorded by local workers
    with h5py.File(local / "data" / "expert.hdf5") as a, h5py.File(on_ray / "data" / "expert.hdf5") as b:
        assert list(a["data"]) == list(b["data"]) == ["demo_0"]
        assert (a["data/demo_0/states"][:] == b["data/demo_0/states"][:]).all()
        assert (a["data/demo_0/actions"][:] == b["data/demo_0/actions"][:]).all()


def test_veragmil_evaluate_on_ray_scores_the_studys_episode(grids, ray_address, tmp_path):
    local, _, _ = grids
    args = ["--agent", "expert operator=expert", "--foods", "pasta", "--episodes", 1, "--seed", 100000]
    args += ["--horizon", 250, "--env-kwargs", json.dumps({"n_grains": 12}), "--quiet", "--output-dir", tmp_path]
    result = run_program("veragmil-evaluate", *args, "--ray", ray_address, check=False)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    study = [row for row in _outcomes(local / "eval" / "episodes.csv") if row[0] == "expert operator"]
    assert _outcomes(tmp_path / "episodes.csv")[1:] == study


def test_ray_workers_take_the_drivers_settled_piles_and_settle_none(ray_address):
    import robosuite

    def settled_speed(piles: dict, kwargs: dict) -> tuple[float, str]:
        """In a Ray worker: the settled speed of the pile an env built on the shipped ``piles`` was reset on, and
        the worker's own pile cache."""
        import robosuite

        import veragmil_suite  # noqa: F401
        from veragmil_suite.environments import settling

        settling.use_shipped_piles(piles)
        try:
            env = robosuite.make("ScoopGranular", **kwargs)
            env.close()
            return env.settled_max_speed, str(settling.cache_dir())
        finally:
            settling.use_shipped_piles(None)

    kwargs = dict(robots="XArm7", food="pasta", n_grains=12, pile_variants=1, has_renderer=False)
    kwargs.update(has_offscreen_renderer=False, use_camera_obs=False)
    env = robosuite.make("ScoopGranular", **kwargs)
    piles = env.settled_piles()
    env.close()
    assert len(piles) == 1
    marked = {key: replace(pile, max_speed_m_s=SENTINEL_SPEED) for key, pile in piles.items()}
    ((_, (speed, worker_cache)),) = run_pieces(settled_speed, [kwargs], context=marked, on_ray=True)
    assert speed == SENTINEL_SPEED  # the driver's pile, not one of the worker's
    assert Path(worker_cache) != cache_dir() and list(Path(worker_cache).iterdir()) == []  # nothing settled there
    with pytest.raises(PileNotShipped, match="was not handed over by the driver"):
        list(run_pieces(settled_speed, [kwargs], context={}, on_ray=True))


def test_a_worker_that_dies_has_its_piece_run_again_and_the_run_goes_on(ray_address, tmp_path):
    def dies_once(marker_dir: str, n: int) -> int:
        marker = Path(marker_dir) / str(n)
        if not marker.exists():
            marker.touch()
            os._exit(1)  # the worker process dies mid-piece
        return n * n

    assert dict(run_pieces(dies_once, range(3), context=str(tmp_path), on_ray=True)) == {0: 0, 1: 1, 2: 4}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["0", "1", "2"]  # each died once
    with pytest.raises(WorkerLost, match="a Ray worker died"):
        list(run_pieces(dies_once, [3], context=str(tmp_path), on_ray=True, max_retries=0))


def test_a_pieces_own_error_stops_the_run_and_is_raised_as_it_is(ray_address):
    def fails_at_one(_, n: int) -> int:
        if n == 1:
            raise ValueError("piece 1 is bad")
        return n

    with pytest.raises(ValueError, match="piece 1 is bad"):
        list(run_pieces(fails_at_one, range(4), on_ray=True, ordered=True))


def test_without_the_flag_nothing_imports_ray():
    code = (
        "import sys; import veragmil_suite.scripts.study, veragmil_suite.scripts.evaluate, "
        "veragmil_suite.scripts.collect_human_demonstrations; print('ray' in sys.modules)"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.stdout.strip() == "False", result.stderr[-2000:]


@pytest.mark.parametrize(
    "program,args",
    [
        ("veragmil_suite.scripts.study", ["--output-dir", "{tmp}/s"]),
        ("veragmil_suite.scripts.evaluate", ["--agent", "expert", "--output-dir", "{tmp}/e"]),
        ("veragmil_suite.scripts.collect_human_demonstrations", ["--device", "scripted", "--output", "{tmp}/a.hdf5"]),
    ],
)
def test_ray_flag_without_ray_installed_is_one_line_naming_the_extra(program, args, tmp_path, monkeypatch, capsys):
    import importlib

    monkeypatch.setitem(sys.modules, "ray", None)  # as Python reports a package that is not installed
    main = importlib.import_module(program).main
    code = main([a.format(tmp=tmp_path) for a in args] + ["--ray"])
    err = capsys.readouterr().err
    said = [line for line in err.splitlines() if line.strip() and not line.startswith(("usage:", " ", "[robosuite"))]
    assert code == 2 and len(said) == 1, err
    assert distributed.INSTALL_HINT in said[0] and "--ray needs Ray" in said[0]
    assert list(tmp_path.iterdir()) == []
