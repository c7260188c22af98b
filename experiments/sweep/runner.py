"""Run (or resume) a sweep on Dask: every cell one task, streamed into the store as it finishes.

Guarantees:

- **Reproducible whatever the worker count or order**: the streams of a cell depend on the sweep
  seed, its parameters and the trial number only (:mod:`experiments.sweep.seeds`).
- **Resumable**: each finished cell is written (metrics, then its ``done`` flag) as soon as it
  completes; running the same sweep again computes only the cells whose flag is not set
  (:mod:`experiments.sweep.store`).
- **Failures are rows**: an exception inside a cell, a trial the cell reports as failed, or a worker
  that dies becomes NaN metrics plus a ``failure_reason`` string; the sweep goes on.

The runner knows nothing of scenario kinds: the caller passes the cell and builds each cell's input.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from experiments.sweep.cell import SweepCell, failure_rows, run_cell
from experiments.sweep.seeds import cell_entropy
from experiments.sweep.spec import coord_names, grid_arrays, grid_cells
from experiments.sweep.store import (
    STORE_NAME,
    fingerprint_of,
    open_sweep,
    prepare_store,
    write_cell,
)

__all__ = ["SweepReport", "run_sweep"]


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
        Cells computed by this call (the others were already done).
    n_failed_trials : int
        Trials in the whole store with a non-empty ``failure_reason``.
    wall_s : float
        Wall time of this call, seconds.
    workers : int
        Number of Dask workers used.
    peak_worker_rss_mb : dict
        Peak resident memory of each worker process (MiB) at the end of the sweep, as reported by
        ``getrusage``; empty when the workers could not report it.
    """

    store: Path
    n_cells: int
    n_computed: int
    n_failed_trials: int
    wall_s: float
    workers: int
    peak_worker_rss_mb: dict[str, float]


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
        and after each cell.

    Returns
    -------
    SweepReport

    Raises
    ------
    ValueError
        Bad ``trials``/``seed``/``workers``/grid, a ``make_input`` failure, or an ``out`` that holds
        a different sweep.  Nothing is written in these cases.
    """
    if not isinstance(trials, int | np.integer) or trials < 1:
        raise ValueError(f"trials: must be an integer >= 1, got {trials!r}")
    if not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed: must be an integer >= 0, got {seed!r}")
    if scheduler is None and (not isinstance(workers, int | np.integer) or workers < 1):
        raise ValueError(f"workers: must be an integer >= 1, got {workers!r}")
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
    done = prepare_store(store, cell, garr, names, int(trials), fingerprint, base_attrs)

    todo = [(i, idx, params) for i, (idx, params) in enumerate(cells) if not done[idx]]
    total = len(cells)
    n_done = total - len(todo)
    if progress:
        progress(n_done, total)
    t0 = time.perf_counter()
    peak: dict[str, float] = {}
    n_workers = int(workers)
    if todo:
        from distributed import Client, LocalCluster, as_completed

        cluster = None
        if scheduler is None:
            import logging

            cluster = LocalCluster(n_workers=int(workers), threads_per_worker=1, processes=processes,
                                   dashboard_address=":0", silence_logs=logging.ERROR)
            client = Client(cluster)
        else:
            client = Client(scheduler)
        try:
            n_workers = len(client.scheduler_info().get("workers", {})) or n_workers
            cell_future = client.scatter(cell, broadcast=True)
            futures = {}
            for i, idx, params in todo:
                seed_params = {k: v for k, v in params.items() if k in keys}
                fut = client.submit(run_cell, cell_future, inputs[i], cell_entropy(int(seed), seed_params),
                                    int(trials), key=f"cell-{fingerprint[:12]}-{i}", pure=False)
                futures[fut] = idx
            for fut in as_completed(futures):
                idx = futures.pop(fut)
                if fut.status == "finished":
                    result = fut.result()
                else:  # the worker died or the task was lost: a failure row, not a crash
                    try:
                        exc = fut.exception()
                        why = f"{type(exc).__name__}: {exc}"
                    except Exception as err:  # noqa: BLE001 - e.g. a cancelled future
                        why = f"{type(err).__name__}: {err}"
                    result = failure_rows(cell, int(trials), f"worker failure: {why}")
                fut.release()
                write_cell(store, idx, names, result, cell)
                n_done += 1
                if progress:
                    progress(n_done, total)
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
    return SweepReport(store=store, n_cells=total, n_computed=len(todo), n_failed_trials=n_failed,
                       wall_s=time.perf_counter() - t0, workers=n_workers, peak_worker_rss_mb=peak)
