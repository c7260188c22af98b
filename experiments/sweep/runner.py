"""Run (or resume) a sweep on Dask: every cell one task, streamed into the store as it finishes.

Guarantees:

- **Reproducible whatever the worker count or order**: the streams of a cell depend on the sweep
  seed, its parameters and the trial number only (:mod:`experiments.sweep.seeds`).
- **Resumable**: each finished cell is written (metrics, then its ``done`` flag) as soon as it
  completes; running the same sweep again computes only the cells whose flag is not set
  (:mod:`experiments.sweep.store`).
- **A cell's failures are rows**: an exception inside a cell or a trial the cell reports as failed
  becomes NaN metrics plus a ``failure_reason`` string (:func:`experiments.sweep.cell.run_cell`
  never raises); the sweep goes on.
- **Infrastructure failures are not results**: every task carries its cell, so a task whose worker
  died is rescheduled by Dask (up to ``distributed.scheduler.allowed-failures`` times, default 3)
  on the surviving or restarted workers, and a task Dask gives up on is resubmitted ``retries``
  times.  A cell is marked done only with the metrics its task computed; a cell still lost after
  that stays undone (:attr:`SweepReport.n_undone`) and the next run computes it.
- **Nothing is written for a call that cannot run**: the output directory, an existing store's
  fingerprint and the scheduler connection are checked before the store is created.

The runner knows nothing of scenario kinds: the caller passes the cell and builds each cell's input.
"""

from __future__ import annotations

import json
import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from experiments.sweep.cell import SweepCell, run_cell
from experiments.sweep.seeds import cell_entropy
from experiments.sweep.spec import coord_names, grid_arrays, grid_cells
from experiments.sweep.store import (
    STORE_NAME,
    check_out,
    create_store,
    existing_done,
    fingerprint_of,
    open_sweep,
    write_cell,
)

__all__ = ["SweepReport", "run_sweep"]


#: default address of the local cluster's dashboard: loopback only, a free port
LOOPBACK_DASHBOARD = "127.0.0.1:0"
#: seconds without any worker after which a local cluster's sweep stops (cells left undone)
LOCAL_NO_WORKER_TIMEOUT_S = 60.0


@dataclass(frozen=True)
class SweepReport:
    """What :func:`run_sweep` did.

    Attributes
    ----------
    store : Path
        The ``sweep.zarr`` store.
    n_cells : int
        Cells in the grid.
    n_computed : int
        Cells computed and written by this call (the others were already done, or are undone).
    n_failed_trials : int
        Trials in the whole store with a non-empty ``failure_reason``.
    wall_s : float
        Wall time of this call, seconds.
    workers : int
        Number of Dask workers used.
    peak_worker_rss_mb : dict
        Peak resident memory of each worker process (MiB) at the end of the sweep, as reported by
        ``getrusage``; empty when the workers could not report it.
    n_undone : int
        Cells of the grid still not done after this call: their tasks were lost to infrastructure
        failures (workers killed, tasks cancelled, no worker left).  Running the same sweep again
        computes them; ``0`` when the store is complete.
    undone_reason : str
        The most frequent infrastructure failure behind the undone cells (``""`` when none).
    """

    store: Path
    n_cells: int
    n_computed: int
    n_failed_trials: int
    wall_s: float
    workers: int
    peak_worker_rss_mb: dict[str, float]
    n_undone: int = 0
    undone_reason: str = ""


def peak_rss_mb() -> float:
    """Peak resident memory of this process, MiB (``getrusage``)."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_sweep(
    cell: SweepCell,
    grid: Mapping[str, Sequence[Any]],
    *,
    trials: int,
    out: Path | str,
    seed: int = 0,
    make_input: Callable[[dict[str, Any]], Any] | None = None,
    identity: str = "",
    seed_keys: Sequence[str] | None = None,
    attrs: Mapping[str, Any] | None = None,
    workers: int = 1,
    scheduler: str | None = None,
    processes: bool = True,
    progress: Callable[[int, int], None] | None = None,
    dashboard_address: str | None = LOOPBACK_DASHBOARD,
    connect_timeout_s: float = 5.0,
    retries: int = 1,
    no_worker_timeout_s: float | None = None,
    on_connect: Callable[[str], None] | None = None,
) -> SweepReport:
    """Run (or resume) a sweep on Dask and stream every cell into ``out/sweep.zarr``.

    Parameters
    ----------
    cell : SweepCell
        The cell function and its metrics.
    grid : mapping of str to sequence
        Dotted key → the values to sweep; the grid is their Cartesian product, in the mapping's order.
    trials : int
        Trials per cell (>= 1).
    out : path
        Output directory; the store is ``out/sweep.zarr``.
    seed : int
        Sweep seed (>= 0); see :func:`cell_seed_sequences`.
    make_input : callable, optional
        ``make_input(params) -> cell_input`` run on the driver for every cell *before* any work
        starts (so a bad grid value fails early); default: the parameter dict itself.
    identity : str
        Text describing everything fixed in the sweep (e.g. the base config as JSON); part of the
        store's fingerprint, so a changed config is not resumed into an old store.
    seed_keys : sequence of str, optional
        The swept keys the random streams depend on (default: all).  Cells that agree on these
        keys share their trial streams: common random numbers, e.g. ``[]`` gives every cell the
        same initial attitudes so that neighbouring cells and 2 vs 3 views are compared on the
        same draws.
    attrs : mapping, optional
        Extra dataset attributes (JSON-able scalars or strings).
    workers : int
        Workers of the ``LocalCluster`` (one thread each) when no ``scheduler`` is given.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``, a dask-jobqueue cluster …).
    processes : bool
        Local workers as processes (default) or threads.
    progress : callable, optional
        ``progress(done_cells, total_cells)``; called once at the start (with the cells already done)
        and after each cell (the first call comes once the cluster is up).
    dashboard_address : str or None
        ``HOST:PORT`` of the local cluster's dashboard (port 0: a free one); default loopback only,
        ``None`` turns it off.  The local scheduler and workers always listen on 127.0.0.1.
        Ignored with ``scheduler``.
    connect_timeout_s : float
        Seconds to wait for ``scheduler`` to answer (> 0).
    retries : int
        Times a cell whose task Dask gave up on (``KilledWorker`` after its workers died
        ``distributed.scheduler.allowed-failures`` + 1 times, a cancelled or lost task) is
        resubmitted (>= 0).
    no_worker_timeout_s : float, optional
        Stop when the cluster has had no worker for this long (seconds), leaving the remaining cells
        undone; default 60 s on a local cluster (its nannies restart dead workers within seconds) and
        no limit with ``scheduler`` (its workers may be queued on a batch system).
    on_connect : callable, optional
        ``on_connect(dashboard_url)`` once connected to a cluster (``""`` without a dashboard); not
        called when every cell is already done.

    Returns
    -------
    SweepReport
        With ``n_undone > 0`` when cells remain undone after infrastructure failures.

    Raises
    ------
    ValueError
        Bad ``trials``/``seed``/``workers``/grid/``dashboard_address``/``retries``/timeouts, a
        ``make_input`` failure, an ``out`` that is a file, not writable or holds a different sweep,
        a ``scheduler`` that does not answer within ``connect_timeout_s``, or a local cluster that
        cannot start.  Nothing is written in these cases.
    """
    if not isinstance(trials, int | np.integer) or trials < 1:
        raise ValueError(f"trials: must be an integer >= 1, got {trials!r}")
    if not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed: must be an integer >= 0, got {seed!r}")
    if scheduler is None and (not isinstance(workers, int | np.integer) or workers < 1):
        raise ValueError(f"workers: must be an integer >= 1, got {workers!r}")
    if not isinstance(retries, int | np.integer) or retries < 0:
        raise ValueError(f"retries: must be an integer >= 0, got {retries!r}")
    _check_dashboard_address(dashboard_address)
    for name, value in (("connect_timeout_s", connect_timeout_s), ("no_worker_timeout_s", no_worker_timeout_s)):
        if value is not None and not (isinstance(value, int | float) and np.isfinite(value) and value > 0):
            raise ValueError(f"{name}: must be a number of seconds > 0, got {_short(value)}")
    for name, m in cell.metrics.items():
        if name in ("failure_reason", "done", "trial"):
            raise ValueError(f"cell.metrics: {name!r} is a reserved name")
        for d in m.dims:
            if d not in cell.coords:
                raise ValueError(f"cell.metrics.{name}: dimension {d!r} has no coordinate in cell.coords")
    garr = grid_arrays(grid)
    names = coord_names(list(garr))
    keys = list(garr) if seed_keys is None else list(seed_keys)
    for k in keys:
        if k not in garr:
            raise ValueError(f"seed_keys: {k!r} is not a swept key ({', '.join(garr)})")
    cells = list(grid_cells(garr))
    inputs = [(make_input or dict)(params) for _, params in cells]  # validates every cell first
    fingerprint = fingerprint_of(cell, garr, int(trials), int(seed), identity + json.dumps(sorted(keys)))
    store = Path(out) / STORE_NAME
    base_attrs = {"cell": cell.name, "seed": int(seed), "trials": int(trials),
                  "swept_keys": json.dumps(list(garr)), "seed_keys": json.dumps(keys), **(attrs or {})}
    check_out(Path(out))
    gshape = tuple(len(v) for v in garr.values())
    done = existing_done(store, fingerprint, gshape)

    todo = [(i, idx) for i, (idx, _) in enumerate(cells) if done is None or not done[idx]]
    total = len(cells)
    if progress and not todo:
        progress(total, total)
    t0 = time.perf_counter()
    peak: dict[str, float] = {}
    n_workers = int(workers)
    n_computed = 0
    lost: dict[tuple[int, ...], str] = {}
    if todo:
        client, cluster = _connect(scheduler, int(workers), processes, dashboard_address, float(connect_timeout_s))
        try:
            if done is None:  # the store appears only once there is a cluster to fill it
                create_store(store, cell, garr, names, int(trials), fingerprint, base_attrs)
            if on_connect:
                on_connect(_dashboard_url(client) if scheduler is not None or dashboard_address else "")
            if progress:
                progress(total - len(todo), total)
            n_workers = len(client.scheduler_info().get("workers", {})) or n_workers
            if no_worker_timeout_s is None and scheduler is None:
                no_worker_timeout_s = LOCAL_NO_WORKER_TIMEOUT_S
            entropies = [cell_entropy(int(seed), {k: v for k, v in params.items() if k in keys})
                         for _, params in cells]

            def submit(i: int, attempt: int) -> Any:
                # the cell object travels with every task (about 1 kB): Dask can rerun a task after
                # its worker died, which it cannot do with data scattered to the workers only
                return client.submit(run_cell, cell, inputs[i], entropies[i], int(trials),
                                     key=f"cell-{fingerprint[:12]}-{i}-{attempt}", pure=False)

            def on_result(i: int, result: Mapping[str, np.ndarray]) -> None:
                nonlocal n_computed
                write_cell(store, cells[i][0], names, result, cell)
                n_computed += 1
                if progress:
                    progress(total - len(todo) + n_computed, total)

            lost = _drain(client, {submit(i, 0): (i, 0) for i, _ in todo}, submit, on_result,
                          int(retries), no_worker_timeout_s, cells)
            if processes or scheduler is not None:
                try:
                    peak = {str(k): float(v) for k, v in client.run(peak_rss_mb).items()}
                except Exception:  # noqa: BLE001 - memory reporting is best effort
                    peak = {}
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    final = open_sweep(store)
    n_failed = int((final["failure_reason"].values != "").sum())
    n_undone = int((~final["done"].values.astype(bool)).sum())
    reason = Counter(lost.values()).most_common(1)[0][0] if lost else ""
    return SweepReport(store=store, n_cells=total, n_computed=n_computed, n_failed_trials=n_failed,
                       wall_s=time.perf_counter() - t0, workers=n_workers, peak_worker_rss_mb=peak,
                       n_undone=n_undone, undone_reason=reason)


def _drain(client: Any, pending: dict[Any, tuple[int, int]], submit: Callable[[int, int], Any],
           on_result: Callable[[int, Mapping[str, np.ndarray]], None], retries: int,
           no_worker_timeout_s: float | None, cells: list[tuple[tuple[int, ...], dict[str, Any]]],
           poll_s: float = 0.05) -> dict[tuple[int, ...], str]:
    """Collect the tasks as they finish; resubmit lost ones; return the cells given up on → why.

    ``pending`` maps each future to ``(cell number, attempt)``.  A future that finished hands its
    metrics to ``on_result``; any other end (an error, ``KilledWorker``, a cancelled or lost task)
    is an infrastructure failure: the cell is resubmitted while ``attempt < retries``, else given
    up on (never written).  When the cluster has had no worker for ``no_worker_timeout_s``, every
    pending cell is given up on.
    """
    from distributed import as_completed

    lost: dict[tuple[int, ...], str] = {}
    queue = as_completed(list(pending))
    no_worker_since: float | None = None
    next_check = time.monotonic()
    while not queue.is_empty():
        if not queue.has_ready():
            now = time.monotonic()
            if no_worker_timeout_s is not None and now >= next_check:
                next_check = now + 1.0
                if client.nthreads():
                    no_worker_since = None
                elif no_worker_since is None:
                    no_worker_since = now
                elif now - no_worker_since >= no_worker_timeout_s:
                    for fut, (i, _) in pending.items():
                        lost[cells[i][0]] = f"no Dask worker for {no_worker_timeout_s:g} s"
                        fut.cancel()
                    queue.clear()
                    break
            time.sleep(poll_s)
            continue
        for fut in queue.next_batch(block=False):
            i, attempt = pending.pop(fut)
            status = fut.status
            if status not in ("finished", "error", "cancelled"):
                # "lost": its worker died after the task ran (the data went with it); Dask reruns
                # the task, so wait for it again
                pending[fut] = (i, attempt)
                queue.add(fut)
                continue
            why = ""
            try:
                result = fut.result()
            except Exception as exc:  # noqa: BLE001 - KilledWorker, CancelledError, a worker-side error
                why = _reason(exc)
            fut.release()
            if not why:
                on_result(i, result)
            elif attempt < retries:
                again = submit(i, attempt + 1)
                pending[again] = (i, attempt + 1)
                queue.add(again)
            else:
                lost[cells[i][0]] = why
    return lost


def _reason(exc: BaseException | None) -> str:
    """One line naming an infrastructure failure."""
    if exc is None:
        return "task lost"
    if type(exc).__name__ == "KilledWorker":
        return "KilledWorker: every worker that ran the cell died"
    return _short(f"{type(exc).__name__}: {exc}".rstrip(": "), 160)


def _check_dashboard_address(address: str | None) -> None:
    """``ValueError`` naming ``dashboard_address`` unless it is ``None`` or ``HOST:PORT``."""
    if address is None:
        return
    host, sep, port = str(address).rpartition(":")
    if not isinstance(address, str) or not sep or not port.isdigit() or int(port) > 65535 or " " in host:
        raise ValueError(f"dashboard_address: expected HOST:PORT (port 0 for a free one), got {_short(address)}")


def _connect(scheduler: str | None, workers: int, processes: bool, dashboard_address: str | None,
             connect_timeout_s: float) -> tuple[Any, Any]:
    """A client of ``scheduler`` or of a new loopback ``LocalCluster``: ``(client, cluster or None)``."""
    import logging

    import dask
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            return Client(scheduler, timeout=connect_timeout_s), None
        except Exception as exc:  # noqa: BLE001 - refused, unreachable, malformed: one line
            why = (f"no Dask scheduler answered within {connect_timeout_s:g} s"
                   if isinstance(exc, OSError | TimeoutError) else _reason(exc)[:80])
            raise ValueError(f"scheduler: cannot connect to {_short(scheduler)} ({why})") from None
    # everything on loopback: worker processes through ``host``; thread workers (in-process, no
    # address of their own) through their HTTP server's address, which otherwise takes every interface
    local: dict[str, Any] = {"host": "127.0.0.1"} if processes else {"worker_dashboard_address": LOOPBACK_DASHBOARD}
    if dashboard_address is None:  # no dashboard; its HTTP server (health, metrics) on a free loopback port
        local["scheduler_kwargs"] = {"dashboard": False, "dashboard_address": LOOPBACK_DASHBOARD}
    try:
        # one task at a time on each worker (saturation 1.0, not 1.1): a cell is seconds of work,
        # and a worker that dies then takes only its own cell down with it
        with dask.config.set({"distributed.scheduler.worker-saturation": 1.0}):
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes,
                                   dashboard_address=dashboard_address, silence_logs=logging.ERROR, **local)
    except Exception as exc:  # noqa: BLE001 - e.g. a dashboard host that is not this machine's
        raise ValueError(f"workers/dashboard_address: cannot start a local Dask cluster of {workers} "
                         f"workers on {dashboard_address!r} ({_reason(exc)[:60]})") from None
    try:
        return Client(cluster), cluster
    except BaseException:
        cluster.close()
        raise


def _dashboard_url(client: Any) -> str:
    """The client's dashboard URL (``""`` when the scheduler has none)."""
    try:
        return str(client.dashboard_link or "")
    except Exception:  # noqa: BLE001 - a scheduler without an HTTP dashboard
        return ""


def _short(value: object, n_chars: int = 60) -> str:
    """``repr``-like text of ``value`` on one line, cut to ``n_chars`` characters."""
    text = " ".join((value if isinstance(value, str) else repr(value)).split())
    return text if len(text) <= n_chars else text[: n_chars - 1] + "…"
