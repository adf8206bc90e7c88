"""``posicast.sweep``: map a function over a parameter space, on Dask, persisting as results arrive.

The points are cut into batches (one task each, one chunk of the store each); the
tasks run on Dask's distributed scheduler: a :class:`distributed.LocalCluster` of
worker *processes* started for the call (the default), an existing cluster given
by its scheduler address (``client="tcp://host:8786"``) or a
:class:`distributed.Client`; ``client="serial"`` runs the batches in this process,
in order, without Dask (the reference the parallel runs must reproduce).  The
calling process writes each batch to the store as it completes (any order) and
advances the progress bar (tqdm).

Each point is evaluated inside ``try``: an exception there is recorded for that
point (``status 'error'`` and ``"<Type>: <first line>"``) and the sweep goes on.
"""

from __future__ import annotations

import logging
import math
import os
import sys
import time
import uuid
from typing import Any, Callable, Iterator, Mapping, NamedTuple

import numpy as np

from .. import _validate as v
from .result import SweepResult, Timing
from .space import Space, check_arguments, function_name, make_space
from .store import Store, open_store

__all__ = ["sweep", "local_cluster", "run_batch", "BatchOutput", "SchedulerUnreachable", "WorkerFailure", "scalars",
           "default_batch_size"]

#: Batches aim at this many per worker (load balance: the last task of a sweep leaves the other workers idle)
#: and hold at most MAX_BATCH points.
BATCHES_PER_WORKER = 16
MAX_BATCH = 64
#: Tasks in flight per worker (the rest are submitted as these finish).
IN_FLIGHT_PER_WORKER = 4


class SchedulerUnreachable(ConnectionError):
    """No Dask scheduler answered at the address given (``client=`` / ``--scheduler``)."""


class WorkerFailure(RuntimeError):
    """A task failed outside the swept function (a worker died, a result could not be sent back)."""


class BatchOutput(NamedTuple):
    """One batch's results: status codes (1 ok, 2 error), messages, values per point, seconds per point."""

    status: np.ndarray
    errors: list[str]
    values: list[dict[str, Any] | None]
    seconds: np.ndarray


def _scalar(x: Any, name: str) -> bool | float | str | None:
    if x is None or isinstance(x, (bool, np.bool_)):
        return None if x is None else bool(x)
    if isinstance(x, str):
        return x
    if isinstance(x, (int, float, np.integer, np.floating)):
        return float(x)
    raise TypeError(f"value {name!r} is a {type(x).__name__}: a sweep stores numbers, bools and strings "
                    "(return a dict of them)")


def scalars(out: Any) -> dict[str, bool | float | str | None]:
    """The values of one point: a scalar is ``{"value": x}``; a mapping, NamedTuple or dataclass its fields.

    >>> scalars(1.5), scalars({"stable": True, "abscissa": -0.2})
    ({'value': 1.5}, {'stable': True, 'abscissa': -0.2})
    """
    if hasattr(out, "_asdict"):
        out = out._asdict()
    elif hasattr(out, "__dataclass_fields__") and not isinstance(out, type):
        out = {k: getattr(out, k) for k in out.__dataclass_fields__}
    if isinstance(out, Mapping):
        res = {}
        for k, x in out.items():
            if not isinstance(k, str) or not k:
                raise TypeError(f"value names must be non-empty strings, got {k!r}")
            res[k] = _scalar(x, k)
        return res
    return {"value": _scalar(out, "value")}


def _message(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def run_batch(function: Callable[..., Any], columns: Mapping[str, np.ndarray]) -> BatchOutput:
    """Evaluate ``function`` at every point of a batch (on a worker); an exception fails that point only."""
    n = len(next(iter(columns.values())))
    status = np.ones(n, dtype=np.int8)
    errors = [""] * n
    values: list[dict[str, Any] | None] = [None] * n
    seconds = np.zeros(n)
    for j in range(n):
        kwargs = {k: c[j].item() for k, c in columns.items()}
        t0 = time.perf_counter()
        try:
            values[j] = scalars(function(**kwargs))
        except Exception as exc:  # recorded, not fatal: the point's status says it failed and why
            status[j], errors[j] = 2, _message(exc)
        seconds[j] = time.perf_counter() - t0
    return BatchOutput(status, errors, values, seconds)


def default_batch_size(n_points: int, workers: int) -> int:
    """About :data:`BATCHES_PER_WORKER` tasks per worker, at most :data:`MAX_BATCH` points a task.

    >>> default_batch_size(400, 2)
    13
    """
    n_points, workers = v.integer(n_points, "n_points", 1), v.integer(workers, "workers", 1)
    return int(max(1, min(MAX_BATCH, math.ceil(n_points / (BATCHES_PER_WORKER * max(1, workers))))))


# ---------------------------------------------------------------------- where the tasks run
class _Runner:
    """Serial execution in this process (``client="serial"``)."""

    workers = 1

    def start(self) -> None:
        pass

    def run(self, function: Callable[..., Any], batches: list[int], columns: Callable[[int], dict[str, np.ndarray]]
            ) -> Iterator[tuple[int, BatchOutput]]:
        for b in batches:
            yield b, run_batch(function, columns(b))

    def close(self) -> None:
        pass


# The local cluster's own background work, kept small beside the sweep's (it shares the cores): no statistical
# profiler sampling the task thread every 10 ms, the system and memory monitors every 2 s and 1 s (not 0.5 s
# and 0.1 s), and glibc's default heap trimming: Dask's MALLOC_TRIM_THRESHOLD_=65536 returns memory to the
# system after every few numpy temporaries and made a certified stability point 17 % slower (measured,
# bench_sweep.py).  One BLAS thread per worker, as Dask sets.  A cluster given by the user keeps its own.
_QUIET_CLUSTER = {"distributed.worker.profile.enabled": False, "distributed.admin.system-monitor.interval": "2s",
                  "distributed.worker.memory.monitor-interval": "1s",
                  "distributed.nanny.pre-spawn-environ": {"OMP_NUM_THREADS": 1, "MKL_NUM_THREADS": 1,
                                                          "OPENBLAS_NUM_THREADS": 1}}


class _DaskRunner(_Runner):
    """Tasks on a Dask cluster: one given (a Client or an address) or a LocalCluster of processes made here."""

    def __init__(self, client: Any = None, address: str | None = None, workers: int | None = None,
                 connect_timeout: float = 10.0) -> None:
        self.client, self.own_cluster, self.own_client = client, None, False
        self.n_workers = workers
        if address is not None:
            from distributed import Client  # lazy: Dask only when a sweep runs on it

            try:
                self.client = Client(address, timeout=f"{connect_timeout}s", set_as_default=False)
            except Exception as exc:  # OSError, TimeoutError, ValueError (a malformed address)
                raise SchedulerUnreachable(f"no Dask scheduler at {address!r} ({_message(exc)}); start one with "
                                           "`dask scheduler` and `dask worker ADDRESS`, or omit --scheduler "
                                           "to run on local processes") from None
            self.own_client = True
            try:
                self.client.wait_for_workers(1, timeout=connect_timeout)
            except Exception:  # TimeoutError: a scheduler without workers would hold the tasks forever
                self.client.close()
                raise SchedulerUnreachable(f"the Dask scheduler at {address!r} has no worker (waited "
                                           f"{connect_timeout:g} s); start one with `dask worker {address}`") from None

    @property
    def workers(self) -> int:  # type: ignore[override]
        if self.client is None:
            return self.n_workers or 1
        return max(1, len(self.client.scheduler_info().get("workers", {})))

    def start(self) -> None:
        if self.client is not None:
            return
        from distributed import Client

        self.own_cluster = local_cluster(self.n_workers)
        self.client = Client(self.own_cluster, set_as_default=False)
        self.own_client = True

    def run(self, function: Callable[..., Any], batches: list[int], columns: Callable[[int], dict[str, np.ndarray]]
            ) -> Iterator[tuple[int, BatchOutput]]:
        """Submit the batches in a bounded window (a few per worker in flight: memory and the scheduler's
        queue stay small for a million-point sweep, and an interrupt cancels little), yield as they finish."""
        from distributed import as_completed

        client = self.client
        fn = client.scatter(function, broadcast=True, hash=False)
        token = uuid.uuid4().hex[:8]
        window = max(8, IN_FLIGHT_PER_WORKER * self.workers)
        todo = iter(batches)
        live: dict[Any, int] = {}

        def submit() -> Any:
            b = next(todo, None)
            if b is None:
                return None
            fut = client.submit(run_batch, fn, columns(b), key=f"posicast-sweep-{token}-{b}", pure=False)
            live[fut] = b
            return fut

        first = [f for f in (submit() for _ in range(window)) if f is not None]
        queue = as_completed(first, loop=client.loop)
        try:
            for fut in queue:
                b = live.pop(fut)
                try:
                    out = fut.result()
                except Exception as exc:
                    raise WorkerFailure(f"batch {b} failed on the cluster: {_message(exc)} (the batches stored "
                                        "so far are kept: run the same sweep again to resume)") from None
                nxt = submit()
                if nxt is not None:
                    queue.add(nxt)
                yield b, out
        finally:
            client.cancel(list(live) + [fn])  # a cluster that outlives the sweep keeps nothing of it

    def close(self) -> None:
        if self.own_client and self.client is not None:
            self.client.close()
        if self.own_cluster is not None:
            self.own_cluster.close()


def local_cluster(workers: int | None = None) -> Any:
    """A Dask ``LocalCluster`` of ``workers`` single-threaded processes (default: the CPU count), as
    :func:`sweep` starts for a call; start one yourself to share it between sweeps
    (``sweep(..., client=cluster)``) and pay its start-up once.  Close it (or use ``with``) when done.
    """
    import dask
    from distributed import LocalCluster

    n = (os.cpu_count() or 1) if workers is None else v.integer_in_range(workers, "workers", 1, 4096)
    with dask.config.set(_QUIET_CLUSTER):
        return LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                            silence_logs=logging.ERROR)


def _runner(client: Any, workers: int | None, connect_timeout: float) -> _Runner:
    if workers is not None:
        workers = v.integer_in_range(workers, "workers", 1, 4096)
    if isinstance(client, str) and client == "serial":
        if workers not in (None, 1):
            raise ValueError(f"workers must be None or 1 with client='serial', got {workers!r}")
        return _Runner()
    if isinstance(client, str):
        if workers is not None:
            raise ValueError("workers applies to the local cluster only; a scheduler's cluster has its own workers")
        if "://" not in client and ":" not in client:
            raise ValueError(f"client must be 'serial', a scheduler address like 'tcp://host:8786' or a "
                             f"distributed.Client, got {client!r}")
        return _DaskRunner(address=client, connect_timeout=connect_timeout)
    if client is None:
        return _DaskRunner(workers=(os.cpu_count() or 1) if workers is None else workers)
    if isinstance(getattr(client, "scheduler_address", None), str) and not hasattr(client, "submit"):
        if workers is not None:  # a cluster object (local_cluster(), LocalCluster, ...): its scheduler
            raise ValueError("workers applies to the local cluster only; a cluster has its own workers")
        return _DaskRunner(address=client.scheduler_address, connect_timeout=connect_timeout)
    if callable(getattr(client, "submit", None)) and callable(getattr(client, "scheduler_info", None)):
        if workers is not None:
            raise ValueError("workers applies to the local cluster only; a client's cluster has its own workers")
        return _DaskRunner(client=client)
    raise TypeError(f"client must be None (local processes), 'serial', a scheduler address, a Dask cluster or a "
                    f"distributed.Client, got {type(client).__name__}")


def _progress_bar(progress: Any, total: int, initial: int, desc: str) -> Any:
    from tqdm import tqdm  # lazy, like Dask

    show = sys.stderr.isatty() if progress is None else bool(progress)
    return tqdm(total=total, initial=initial, unit="pt", desc=desc, disable=not show, file=sys.stderr,
                dynamic_ncols=True, mininterval=0.5)


# ---------------------------------------------------------------------- the entry point
def sweep(function: Callable[..., Any], parameters: Mapping[str, Any], *, n: int | None = None,
          seed: int | None = None, store: str | os.PathLike[str] | None = None, client: Any = None,
          workers: int | None = None, batch_size: int | None = None, progress: bool | None = None,
          overwrite: bool = False, connect_timeout: float = 10.0) -> SweepResult:
    """Evaluate ``function(**point)`` at every point of a grid or of seeded draws; labelled results.

    Parameters
    ----------
    function : callable
        Called with one keyword argument per parameter; returns a number, bool or string
        (stored as ``"value"``), or a mapping / NamedTuple / dataclass of them (one value each).
        For worker processes it must be picklable (a module-level function, or a
        ``functools.partial`` of one: cloudpickle also takes lambdas).
    parameters : mapping
        ``name -> 1-D sequence`` (a grid axis; the grid is their Cartesian product, first
        name slowest) or ``name -> distribution`` (scipy.stats-like, with ``rvs``): ``n`` seeded draws.
    n, seed : int
        For distributions: the number of draws and the seed (both required).
    store : path, optional
        A Zarr directory the results are written to as they arrive.  Running the same sweep
        again with the same store resumes it: stored points are not recomputed.
    client : None, 'serial', str, a cluster or distributed.Client
        None (default): a LocalCluster of ``workers`` processes for this call; ``'serial'``:
        this process, no Dask; ``'tcp://host:port'``: the Dask scheduler there; a cluster
        (:func:`local_cluster`, any Dask cluster object); or a Client.
    workers : int, optional
        Processes of the local cluster (default: the CPU count).
    batch_size : int, optional
        Points per task (default :func:`default_batch_size`; a resumed store keeps its own).
    progress : bool, optional
        A progress bar on stderr (default: when stderr is a terminal).
    overwrite : bool
        Discard what ``store`` holds instead of resuming.
    connect_timeout : float
        Seconds to wait for a scheduler given by address.

    Returns
    -------
    SweepResult

    Raises
    ------
    ValueError, TypeError
        Bad parameters (empty grid, a parameter ``function`` does not accept, ...), a store
        holding another sweep (:class:`~posicast.sweeps.store.StoreMismatch`).
    SchedulerUnreachable
        No scheduler at the address given (a ``ConnectionError``).
    WorkerFailure
        A task died outside ``function`` (what was stored stays; run again to resume).

    Examples
    --------
    >>> import posicast
    >>> r = posicast.sweep(lambda a, b: a * b, {"a": [1, 2], "b": [10, 20, 30]}, client="serial")
    >>> r["value"]
    array([[10., 20., 30.],
           [20., 40., 60.]])
    >>> r.status[1, 2]
    np.str_('ok')
    """
    if not callable(function):
        raise TypeError(f"function must be callable, got {type(function).__name__}")
    space: Space = make_space(parameters, n, seed)
    check_arguments(function, space.names)
    connect_timeout = v.positive(connect_timeout, "connect_timeout")
    if not isinstance(overwrite, bool):
        raise TypeError(f"overwrite must be a bool, got {type(overwrite).__name__}")
    if progress is not None and not isinstance(progress, bool):
        raise TypeError(f"progress must be None or a bool, got {type(progress).__name__}")
    runner = _runner(client, workers, connect_timeout)
    try:
        if batch_size is None:
            batch_size = default_batch_size(space.n_points, runner.workers)
        batch_size = v.integer_in_range(batch_size, "batch_size", 1, space.n_points)
        fname = function_name(function)
        st: Store = open_store(store, space, fname, batch_size, overwrite)
        return _execute(function, st, runner, progress, fname)
    finally:
        runner.close()


def _execute(function: Callable[..., Any], st: Store, runner: _Runner, progress: Any, fname: str) -> SweepResult:
    pending = st.pending()
    todo = sum(st.bounds(b)[1] - st.bounds(b)[0] for b in pending)
    if not pending:
        return st.result(0, Timing(0.0, 0.0, 0, runner.workers))
    runner.start()
    t0, compute, done = time.perf_counter(), 0.0, 0
    bar = _progress_bar(progress, st.space.n_points, st.space.n_points - todo, fname)
    try:
        for b, out in runner.run(function, pending, lambda b: st.space.columns(*st.bounds(b))):
            st.write(b, out.status, out.errors, out.values, out.seconds)
            compute += float(np.sum(out.seconds))
            done += out.status.size
            bar.update(out.status.size)
    finally:
        bar.close()
    timing = Timing(time.perf_counter() - t0, compute, len(pending), runner.workers)
    return st.result(done, timing)
