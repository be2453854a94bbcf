"""
Independent pieces of work (recording attempts, training runs, evaluation episodes) run through one function,
run_pieces: in local worker processes, or as tasks on Ray (an existing distributed engine) when a program is given
``--ray [ADDRESS]``.

Without Ray, nothing here imports it: pieces run in a process pool on this machine (or one after another in this
process), and Ray need not be installed. On Ray, each piece is a task asking for the CPUs (and GPU) it needs; Ray
places it on any node and runs it again when its worker process or node dies (``max_retries``), and the results
come back to the driver as they finish, so journals and output files are written by the driver alone and a driver
that dies leaves a run that resumes. What every piece needs besides itself (settled piles, the recording's
settings) is put once in Ray's object store and read by each task.
"""

from __future__ import annotations

import contextlib
import importlib.util
import multiprocessing
import os
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

from veragmil_suite.utils import cli

if TYPE_CHECKING:
    import argparse

    from ray import ObjectRef

# what the forkserver imports before it forks a worker: multiprocessing's default (the main module) and the package
FORKSERVER_PRELOAD = ["__main__", "veragmil_suite"]

Piece = TypeVar("Piece")
Result = TypeVar("Result")

# Ray is the optional extra "ray" of setup.py, which pins the version the tests ran with
INSTALL_HINT = 'pip install ".[ray]"'
# set to "0": Ray puts every node of an instance started here on the loopback address (its single-machine mode)
LOOPBACK_ONLY = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"
# ``--ray`` without an address: $RAY_ADDRESS when set, else a Ray instance started on this machine
THIS_MACHINE = ""
# times Ray runs a piece again after its worker process or node died (a piece's own exception is not retried)
MAX_RETRIES = 3
# pieces in flight per piece that can run at once: the next ones are queued while the last ones finish
AHEAD_PER_SLOT = 2


class RayMissing(RuntimeError):
    """--ray was asked for and Ray is not installed."""


class WorkerLost(RuntimeError):
    """A worker process (or Ray node) died while running a piece, and no retry was left."""


@dataclass(frozen=True)
class Resources:
    """What one piece holds on a Ray node while it runs."""

    cpus: float = 1.0
    gpus: float = 0.0


def require_ray() -> None:
    """Raises RayMissing (one line naming the install command) unless Ray can be imported; imports nothing."""
    if importlib.util.find_spec("ray") is None:
        raise RayMissing(f"--ray needs Ray, an optional extra: {INSTALL_HINT} in the repository")


def add_ray_argument(parser: argparse.ArgumentParser, pieces: str) -> None:
    """The ``--ray [ADDRESS]`` option of a console program whose ``pieces`` can run as Ray tasks."""
    parser.add_argument(
        "--ray",
        nargs="?",
        const=THIS_MACHINE,
        default=None,
        type=cli.ray_address,
        metavar="ADDRESS",
        help=f"run {pieces} as Ray tasks: without ADDRESS on $RAY_ADDRESS or a Ray instance started on this "
        "machine, with it on that cluster (its head's host:port, or 'auto' for one `ray start` began here); "
        f"needs {INSTALL_HINT}",
    )


def check_ray_argument(args: argparse.Namespace) -> None:
    """Raises RayMissing (one line) when ``--ray`` was given and Ray is not installed."""
    if getattr(args, "ray", None) is not None:
        require_ray()


def _blas_threads_env() -> dict:
    """Ray's runtime_env giving its workers the BLAS thread count of this process's children.

    Ray starts workers with OMP_NUM_THREADS=1; OpenBLAS then rounds the controller's small solves differently from
    a process with a thread per core, and a pile turns that round-off into another episode (a study's Ray and local
    runs disagreed on one CPU). OpenBLAS reads OPENBLAS_NUM_THREADS before OMP_NUM_THREADS, and uses every core
    the process may run on when neither is set.
    """
    threads = os.environ.get("OPENBLAS_NUM_THREADS") or os.environ.get("OMP_NUM_THREADS")
    return {"env_vars": {"OPENBLAS_NUM_THREADS": threads or str(len(os.sched_getaffinity(0)))}}


@contextlib.contextmanager
def ray_session(address: str | None, num_cpus: int | None = None) -> Iterator[str | None]:
    """
    Connected to Ray for the block, unless ``address`` is None (then nothing happens and None is yielded).

    Yields the cluster's address (host:port of its head), which child processes attach with. An address of
    THIS_MACHINE attaches to $RAY_ADDRESS when it is set, else starts a Ray instance of ``num_cpus`` CPUs (default:
    this machine's) that listens on the loopback address only and is stopped when the block ends. A process
    already connected stays connected, and the block reuses its connection.
    """
    if address is None:
        yield None
        return
    require_ray()
    start_here = address == THIS_MACHINE and not os.environ.get("RAY_ADDRESS")
    if start_here and LOOPBACK_ONLY not in os.environ:
        # Ray's single-machine mode: nodes take the loopback address (read when ray is first imported; child
        # processes that attach during the block inherit it)
        os.environ[LOOPBACK_ONLY] = "0"
        set_here = True
    else:
        set_here = False
    import ray  # optional extra: ray

    connected_here = not ray.is_initialized()
    if connected_here:
        kwargs: dict[str, Any] = dict(logging_level="WARNING", configure_logging=True, runtime_env=_blas_threads_env())
        if start_here:
            ray.init(address="local", num_cpus=num_cpus, include_dashboard=False, **kwargs)  # a new instance
        else:
            ray.init(address=address or None, **kwargs)
    try:
        yield ray.get_runtime_context().gcs_address
    finally:
        if connected_here:
            ray.shutdown()
        if set_here:
            del os.environ[LOOPBACK_ONLY]


def cluster_resources() -> dict[str, float]:
    """The connected Ray cluster's resources (CPU, GPU, memory...)."""
    import ray  # optional extra: ray

    return dict(ray.cluster_resources())


def run_pieces(
    function: Callable[[Any, Piece], Result],
    pieces: Iterable[Piece],
    *,
    context: Any = None,
    processes: int = 1,
    on_ray: bool = False,
    ordered: bool = False,
    setup: Callable[[], None] | None = None,
    resources: Resources = Resources(),
    max_retries: int = MAX_RETRIES,
) -> Iterator[tuple[Piece, Result]]:
    """
    Yields (piece, ``function(context, piece)``) for every piece, computed where the caller asked: on Ray
    (``on_ray``, inside a ray_session: a task per piece holding ``resources``), else in ``processes`` local worker
    processes, else (``processes`` 0) one after another in this process.

    ``function`` and ``setup`` are module-level functions (pickled by name); ``setup`` runs once in each worker
    process before its first piece. ``pieces`` is read lazily (it may be endless): a few run ahead of the results
    taken. Results come in the order pieces finish, or with ``ordered`` in the order of ``pieces``. The first piece
    that raises stops the run: the pieces under way are cancelled and its exception is raised here (WorkerLost
    when its worker process died, on Ray after ``max_retries`` runs elsewhere). Closing the iterator cancels the
    pieces under way.
    """
    if on_ray:
        backend: _Backend = _RayBackend(function, context, setup, resources, max_retries)
        slots = max(processes, int(cluster_resources().get("CPU", 1) // max(resources.cpus, 1e-9)), 1)
    elif processes > 0:
        backend = _ProcessBackend(function, context, setup, processes)
        slots = processes
    else:
        for piece in pieces:
            yield piece, function(context, piece)
        return
    pending: dict[Any, Piece] = {}  # handle -> piece, in submission order
    source = iter(pieces)
    more = True
    try:
        while True:
            while more and len(pending) < AHEAD_PER_SLOT * slots:
                piece = next(source, _END)
                if piece is _END:
                    more = False
                else:
                    pending[backend.submit(piece)] = piece
            if not pending:
                return
            handle = backend.wait_one([next(iter(pending))] if ordered else list(pending))
            piece = pending.pop(handle)
            yield piece, backend.result(handle)
    finally:
        backend.stop(list(pending))


_END = object()


class _Backend:
    """Where run_pieces' pieces run: submit one, wait for one of several, take its result, stop the rest."""

    def submit(self, piece: Any) -> Any:
        raise NotImplementedError

    def wait_one(self, handles: list) -> Any:
        raise NotImplementedError

    def result(self, handle: Any) -> Any:
        raise NotImplementedError

    def stop(self, handles: list) -> None:
        raise NotImplementedError


_LOCAL_CONTEXT: dict[str, Any] = {}  # per local worker process: the run's context


def _local_init(setup: Callable[[], None] | None, context: Any) -> None:
    if setup is not None:
        setup()
    _LOCAL_CONTEXT["value"] = context


def _local_piece(function: Callable[[Any, Any], Any], piece: Any) -> Any:
    return function(_LOCAL_CONTEXT["value"], piece)


class _ProcessBackend(_Backend):
    """A pool of fresh worker processes (forked from a server that imported the package, where the platform has
    one), each given the context once."""

    def __init__(self, function, context, setup, processes: int):
        methods = multiprocessing.get_all_start_methods()
        if "forkserver" in methods:
            mp_context = multiprocessing.get_context("forkserver")
            # workers fork from a server that imported the package once (robosuite, MuJoCo: 1.3 s a worker);
            # a server already started by an earlier pool of this program keeps what it imported
            mp_context.set_forkserver_preload(FORKSERVER_PRELOAD)
        else:
            mp_context = multiprocessing.get_context("spawn")
        self.function = function
        self.pool = ProcessPoolExecutor(
            max_workers=processes, mp_context=mp_context, initializer=_local_init, initargs=(setup, context)
        )

    def submit(self, piece: Any) -> Future:
        return self.pool.submit(_local_piece, self.function, piece)

    def wait_one(self, handles: list[Future]) -> Future:
        done, _ = wait(handles, return_when=FIRST_COMPLETED)
        return next(h for h in handles if h in done)  # the earliest submitted of those done

    def result(self, handle: Future) -> Any:
        try:
            return handle.result()
        except BrokenProcessPool as error:
            raise WorkerLost(f"a worker process died: {error}") from error

    def stop(self, handles: list[Future]) -> None:
        for handle in handles:
            handle.cancel()
        self.pool.shutdown(wait=True, cancel_futures=True)  # at most the pieces under way


_SET_UP: set[str] = set()  # per Ray worker process: the setups already run


def _ray_piece(function: Callable[[Any, Any], Any], setup: Callable[[], None] | None, context: Any, piece: Any) -> Any:
    """A Ray task: the worker's setup (once per process), then the piece."""
    if setup is not None:
        name = f"{setup.__module__}.{setup.__qualname__}"
        if name not in _SET_UP:
            setup()
            _SET_UP.add(name)
    return function(context, piece)


class _RayBackend(_Backend):
    """A Ray task per piece; the context is put in the object store once and handed to every task."""

    def __init__(self, function, context, setup, resources: Resources, max_retries: int):
        import ray  # optional extra: ray

        self.ray = ray
        self.function, self.setup = function, setup
        self.context = ray.put(context)
        self.remote = ray.remote(_ray_piece).options(
            num_cpus=resources.cpus, num_gpus=resources.gpus, max_retries=max_retries, retry_exceptions=False
        )

    def submit(self, piece: Any) -> ObjectRef:
        return self.remote.remote(self.function, self.setup, self.context, piece)

    def wait_one(self, handles: list[ObjectRef]) -> ObjectRef:
        ready, _ = self.ray.wait(handles, num_returns=1)
        return ready[0]

    def result(self, handle: ObjectRef) -> Any:
        exceptions = self.ray.exceptions
        try:
            return self.ray.get(handle)
        except exceptions.RayTaskError as error:
            cause = getattr(error, "cause", None)
            if isinstance(cause, Exception) and not isinstance(cause, exceptions.RayError):
                raise cause from None  # the piece's own exception, as a local worker would raise it
            raise WorkerLost(str(error)) from error
        except exceptions.RayError as error:  # its worker process or node died, Ray's retries included
            raise WorkerLost(f"a Ray worker died: {error}") from error

    def stop(self, handles: list[ObjectRef]) -> None:
        for handle in handles:
            with contextlib.suppress(Exception):  # a task that ended meanwhile
                self.ray.cancel(handle)
