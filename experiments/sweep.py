"""Parameter sweeps on Dask: a grid over any config keys × trials, streamed cell by cell to zarr.

A sweep evaluates one *cell function* at every point of a grid (the Cartesian product of the
values given for some dotted config keys, e.g. ``formation.distance_m``), for ``trials`` independent
trials per grid point.  One grid point, with all its trials, is a *cell*: one Dask task, one region
write into ``DIR/sweep.zarr``.

Guarantees (ARCHITECTURE §4, §6, §7):

- **Reproducible whatever the worker count or order.** The random stream of trial ``t`` of a cell
  is ``SeedSequence(entropy=[seed, *hash(cell parameters)], spawn_key=(t,))``: it depends on the
  sweep seed, the cell's parameter values and the trial number only.  Adding a value to the grid
  or trials to the sweep leaves the existing cells' numbers unchanged.
- **Resumable.** Each finished cell is written (metrics, then its ``done`` flag) as soon as it
  completes; running the same sweep again computes only the cells whose flag is not set.  zarr
  writes chunk files atomically, and every cell is its own chunk, so a ``SIGKILL`` at any moment
  leaves either a finished cell or one that will be recomputed.
- **Failures are rows.** An exception inside a cell, a trial the cell reports as failed, or a
  worker that dies becomes NaN metrics plus a ``failure_reason`` string; the sweep goes on.

The dataset: coordinates are the swept parameters (named after the last part of the dotted key,
the full key in ``attrs["config_key"]``), ``trial`` and any extra dimensions of the cell's metrics
(e.g. ``time_s``); data variables are the metrics (units in ``attrs``), ``failure_reason`` and
``done``.  Figures are drawn from the stored dataset only (:func:`redraw`).

``coobs sweep CONFIG --out DIR [--workers N] [--scheduler ADDRESS]`` runs the ``[sweep]`` table of
a scenario config (see :class:`SweepSpec`); the scenario kind provides the cell function through
``sweep_cell(cfg) -> SweepCell``.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import time
import traceback
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pydantic
import typer
import xarray as xr

from experiments.cli import app, console, fail

__all__ = [
    "Metric",
    "SweepCell",
    "SweepReport",
    "SweepSpec",
    "GridRange",
    "run_sweep",
    "open_sweep",
    "parse_overrides",
    "prepare_config_sweep",
    "sweep_summary",
    "cell_seed_sequences",
    "child_seeds",
    "redraw",
]

STORE_NAME = "sweep.zarr"
#: longest failure reason kept (characters)
_REASON_MAX = 300


# ----------------------------------------------------------------------------- cell description


@dataclass(frozen=True)
class Metric:
    """Description of one measured quantity of a cell.

    Attributes
    ----------
    units : str
        Units written into the variable's ``attrs["units"]`` (``"deg"``, ``"s"``, ``"1"``).
    dims : tuple of str
        Extra dimensions after ``trial`` (their coordinates in :attr:`SweepCell.coords`).
    per_trial : bool
        ``False`` for a quantity computed once per cell (e.g. a predicted Cramér–Rao bound):
        the array then has no ``trial`` axis.
    long_name : str
        Human description, written into ``attrs["long_name"]``.
    """

    units: str
    dims: tuple[str, ...] = ()
    per_trial: bool = True
    long_name: str = ""


@dataclass(frozen=True)
class SweepCell:
    """A cell function and the metrics it returns.

    Attributes
    ----------
    fn : callable
        ``fn(cell_input, seeds) -> dict[str, ndarray]``, a picklable module-level function (or a
        ``functools.partial`` of one).  ``cell_input`` is what the driver built for the cell (the
        parameter dict, or a validated scenario config); ``seeds`` is a list of
        ``numpy.random.SeedSequence``, one per trial.  It returns every metric of :attr:`metrics`
        with shape ``(trials, *dims)`` (``(*dims)`` when ``per_trial`` is false) and optionally
        ``"failure_reason"``, shape ``(trials,)``, ``""`` for a good trial.
    metrics : mapping of str to Metric
        The metrics, in the order they are stored.
    coords : mapping of str to ndarray
        Coordinate values of the extra metric dimensions.
    coord_units : mapping of str to str
        Units of those coordinates.
    name : str
        Name of the cell function (stored in the dataset's attrs).
    """

    fn: Callable[[Any, list[np.random.SeedSequence]], Mapping[str, Any]]
    metrics: Mapping[str, Metric]
    coords: Mapping[str, np.ndarray] = field(default_factory=dict)
    coord_units: Mapping[str, str] = field(default_factory=dict)
    name: str = ""

    def metric_shape(self, name: str, trials: int) -> tuple[int, ...]:
        m = self.metrics[name]
        extra = tuple(len(self.coords[d]) for d in m.dims)
        return (trials, *extra) if m.per_trial else extra


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


# ----------------------------------------------------------------------------- grid and seeds


def _coord_names(keys: Sequence[str]) -> list[str]:
    names = [k.split(".")[-1] for k in keys]
    for n, k in zip(names, keys, strict=True):
        if not n.isidentifier():
            raise ValueError(f"grid: key {k!r} does not end in a valid name")
        if n == "trial" or names.count(n) > 1:
            raise ValueError(f"grid: key {k!r} gives coordinate name {n!r}, which is not unique")
    return names


def _grid_arrays(grid: Mapping[str, Sequence[Any]]) -> dict[str, np.ndarray]:
    if not grid:
        raise ValueError("grid: at least one swept key is required")
    out = {}
    for key, values in grid.items():
        arr = np.asarray(list(values))
        if arr.ndim != 1 or arr.size == 0:
            raise ValueError(f"grid.{key}: expected a non-empty list of scalar values, got {values!r}")
        if len(set(arr.tolist())) != arr.size:
            raise ValueError(f"grid.{key}: values are not distinct: {arr.tolist()!r}")
        out[key] = arr
    return out


def _cells(grid: Mapping[str, np.ndarray]) -> Iterator[tuple[tuple[int, ...], dict[str, Any]]]:
    keys = list(grid)
    for idx in itertools.product(*(range(len(grid[k])) for k in keys)):
        yield idx, {k: grid[k][i].item() for k, i in zip(keys, idx, strict=True)}


def _params_key(params: Mapping[str, Any]) -> str:
    return json.dumps(sorted((k, repr(v)) for k, v in params.items()))


def _cell_entropy(seed: int, params: Mapping[str, Any]) -> list[int]:
    digest = hashlib.sha256(_params_key(params).encode()).digest()
    return [int(seed), *np.frombuffer(digest[:16], dtype="<u4").tolist()]


def cell_seed_sequences(seed: int, params: Mapping[str, Any], trials: int) -> list[np.random.SeedSequence]:
    """The per-trial seed sequences of one cell (ARCHITECTURE §6).

    Parameters
    ----------
    seed : int
        The sweep's seed.
    params : mapping
        The cell's swept values, dotted key → Python scalar.
    trials : int
        Number of trials.

    Returns
    -------
    list of numpy.random.SeedSequence
        ``SeedSequence(entropy=[seed, *sha256(params)], spawn_key=(t,))`` for ``t < trials``;
        spawn children from each for spacecraft and sensors.
    """
    entropy = _cell_entropy(seed, params)
    return [np.random.SeedSequence(entropy, spawn_key=(t,)) for t in range(trials)]


def child_seeds(ss: np.random.SeedSequence, n: int) -> list[np.random.SeedSequence]:
    """The ``n`` children of ``ss`` that ``ss.spawn(n)`` gives on a fresh object, without mutating ``ss``.

    ``SeedSequence.spawn`` is stateful (a second call gives other children); cell functions derive
    their per-role streams with this pure form so that calling them twice with the same seeds gives
    the same numbers.
    """
    return [np.random.SeedSequence(ss.entropy, spawn_key=(*ss.spawn_key, i), pool_size=ss.pool_size)
            for i in range(int(n))]


# ----------------------------------------------------------------------------- one cell (on a worker)


def _failure_rows(cell: SweepCell, trials: int, reason: str) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {
        name: np.full(cell.metric_shape(name, trials), np.nan) for name in cell.metrics
    }
    out["failure_reason"] = np.array([reason[:_REASON_MAX]] * trials, dtype=object)
    return out


def _run_cell(cell: SweepCell, cell_input: Any, entropy: list[int], trials: int) -> dict[str, np.ndarray]:
    """Evaluate one cell; never raises (an exception becomes failure rows)."""
    seeds = [np.random.SeedSequence(entropy, spawn_key=(t,)) for t in range(trials)]
    try:
        raw = cell.fn(cell_input, seeds)
    except Exception as exc:  # noqa: BLE001 - a cell failure must become a row, never a crash
        where = traceback.extract_tb(exc.__traceback__)[-1]
        return _failure_rows(cell, trials, f"{type(exc).__name__}: {exc} [{Path(where.filename).name}:{where.lineno}]")
    out: dict[str, np.ndarray] = {}
    for name in cell.metrics:
        if name not in raw:
            return _failure_rows(cell, trials, f"cell function did not return metric {name!r}")
        arr = np.asarray(raw[name], dtype=float)
        shape = cell.metric_shape(name, trials)
        if arr.shape != shape:
            return _failure_rows(cell, trials, f"metric {name!r} has shape {arr.shape}, expected {shape}")
        out[name] = arr
    reason = raw.get("failure_reason")
    if reason is None:
        reason = np.array([""] * trials, dtype=object)
    reason = np.array([str(r)[:_REASON_MAX] for r in np.asarray(reason, dtype=object).reshape(-1)], dtype=object)
    if reason.shape != (trials,):
        return _failure_rows(cell, trials, f"failure_reason has shape {reason.shape}, expected ({trials},)")
    failed = reason != ""
    for name, m in cell.metrics.items():
        if m.per_trial and failed.any():
            out[name][failed] = np.nan
    out["failure_reason"] = reason
    return out


def _peak_rss_mb() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


# ----------------------------------------------------------------------------- the store


def _fingerprint(cell: SweepCell, grid: Mapping[str, np.ndarray], trials: int, seed: int, identity: str) -> str:
    spec = {
        "cell": cell.name,
        "metrics": {k: [m.units, list(m.dims), m.per_trial] for k, m in cell.metrics.items()},
        "coords": {k: np.asarray(v).tolist() for k, v in cell.coords.items()},
        "grid": {k: v.tolist() for k, v in grid.items()},
        "trials": trials,
        "seed": seed,
        "identity": identity,
    }
    return hashlib.sha256(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()


def _template(cell: SweepCell, grid: Mapping[str, np.ndarray], names: list[str], trials: int,
              attrs: Mapping[str, Any]) -> tuple[xr.Dataset, dict[str, dict]]:
    gshape = tuple(len(v) for v in grid.values())
    coords: dict[str, Any] = {}
    for (key, values), name in zip(grid.items(), names, strict=True):
        coords[name] = xr.Variable((name,), values, attrs={"config_key": key})
    coords["trial"] = np.arange(trials)
    for d, v in cell.coords.items():
        coords[d] = xr.Variable((d,), np.asarray(v), attrs={"units": cell.coord_units.get(d, "")})
    data_vars: dict[str, Any] = {}
    encoding: dict[str, dict] = {}
    ones = (1,) * len(gshape)
    for name, m in cell.metrics.items():
        extra = tuple(len(cell.coords[d]) for d in m.dims)
        dims = (*names, "trial", *m.dims) if m.per_trial else (*names, *m.dims)
        shape = (*gshape, trials, *extra) if m.per_trial else (*gshape, *extra)
        data_vars[name] = xr.Variable(dims, np.full(shape, np.nan),
                                      attrs={"units": m.units, "long_name": m.long_name})
        encoding[name] = {"chunks": ones + shape[len(gshape):]}
    data_vars["failure_reason"] = xr.Variable((*names, "trial"), np.full((*gshape, trials), "", dtype=object),
                                              attrs={"long_name": "why the trial failed; empty when it succeeded"})
    encoding["failure_reason"] = {"chunks": (*ones, trials)}
    data_vars["done"] = xr.Variable(names, np.zeros(gshape, dtype=bool),
                                    attrs={"long_name": "cell finished and written"})
    encoding["done"] = {"chunks": ones}
    ds = xr.Dataset(data_vars, coords=coords, attrs=dict(attrs))
    return ds, encoding


def open_sweep(out: Path | str) -> xr.Dataset:
    """Load ``out/sweep.zarr`` (or the store path itself) into memory as an xarray Dataset."""
    path = Path(out)
    if path.name != STORE_NAME:
        path = path / STORE_NAME
    if not path.exists():
        raise FileNotFoundError(f"out: no {STORE_NAME} in {path.parent}")
    with xr.open_zarr(path, consolidated=False) as ds:
        loaded = ds.load()
    if "failure_reason" in loaded:
        loaded["failure_reason"] = loaded["failure_reason"].astype(object)
    return loaded


def _write_cell(store: Path, idx: tuple[int, ...], names: list[str], result: Mapping[str, np.ndarray],
                cell: SweepCell) -> None:
    region = {n: slice(i, i + 1) for n, i in zip(names, idx, strict=True)}
    lead = (1,) * len(names)
    data = {}
    for name, m in cell.metrics.items():
        arr = np.asarray(result[name], dtype=float)
        dims = (*names, "trial", *m.dims) if m.per_trial else (*names, *m.dims)
        data[name] = (dims, arr.reshape(lead + arr.shape))
    reason = np.asarray(result["failure_reason"], dtype=object)
    data["failure_reason"] = ((*names, "trial"), reason.reshape(lead + reason.shape))
    xr.Dataset(data).to_zarr(store, region={**region, "trial": slice(None),
                                            **{d: slice(None) for d in cell.coords}},
                             consolidated=False)
    # the done flag goes last, in its own write: a kill before it means the cell is recomputed
    xr.Dataset({"done": (names, np.ones(lead, dtype=bool))}).to_zarr(store, region=region, consolidated=False)


def _prepare_store(store: Path, cell: SweepCell, grid: Mapping[str, np.ndarray], names: list[str],
                   trials: int, fingerprint: str, attrs: Mapping[str, Any]) -> np.ndarray:
    """Create the store, or check that an existing one belongs to this sweep; return ``done``."""
    if store.exists():
        try:
            with xr.open_zarr(store, consolidated=False) as old:
                old_fp = old.attrs.get("sweep_fingerprint")
                done = old["done"].values.astype(bool)
        except Exception as exc:  # noqa: BLE001 - an unreadable store is reported, not crashed on
            raise ValueError(f"out: {store} exists but cannot be read as a sweep ({exc})") from None
        if old_fp != fingerprint:
            raise ValueError(f"out: {store} holds a different sweep (other grid, trials, seed or config); "
                             "use another --out or delete it")
        return done
    ds, encoding = _template(cell, grid, names, trials, {**attrs, "sweep_fingerprint": fingerprint})
    store.parent.mkdir(parents=True, exist_ok=True)
    tmp = store.with_name(store.name + ".creating")
    import shutil

    shutil.rmtree(tmp, ignore_errors=True)
    ds.to_zarr(tmp, mode="w", encoding=encoding, consolidated=False)
    tmp.rename(store)  # the store appears complete or not at all
    return np.zeros(tuple(len(v) for v in grid.values()), dtype=bool)


# ----------------------------------------------------------------------------- driver


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
    garr = _grid_arrays(grid)
    names = _coord_names(list(garr))
    keys = list(garr) if seed_keys is None else list(seed_keys)
    for k in keys:
        if k not in garr:
            raise ValueError(f"seed_keys: {k!r} is not a swept key ({', '.join(garr)})")
    cells = list(_cells(garr))
    inputs = [(make_input or dict)(params) for _, params in cells]  # validates every cell first
    fingerprint = _fingerprint(cell, garr, int(trials), int(seed), identity + json.dumps(sorted(keys)))
    store = Path(out) / STORE_NAME
    base_attrs = {"cell": cell.name, "seed": int(seed), "trials": int(trials),
                  "swept_keys": json.dumps(list(garr)), "seed_keys": json.dumps(keys), **(attrs or {})}
    done = _prepare_store(store, cell, garr, names, int(trials), fingerprint, base_attrs)

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
                fut = client.submit(_run_cell, cell_future, inputs[i], _cell_entropy(int(seed), seed_params),
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
                    result = _failure_rows(cell, int(trials), f"worker failure: {why}")
                fut.release()
                _write_cell(store, idx, names, result, cell)
                n_done += 1
                if progress:
                    progress(n_done, total)
            if processes or scheduler is not None:
                try:
                    peak = {str(k): float(v) for k, v in client.run(_peak_rss_mb).items()}
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


# ----------------------------------------------------------------------------- config and CLI


class GridRange(pydantic.BaseModel):
    """Inclusive arithmetic range ``{start = 30, stop = 100, step = 5}`` (or ``num`` points)."""

    model_config = pydantic.ConfigDict(extra="forbid")
    start: float
    stop: float
    step: float | None = None
    num: int | None = pydantic.Field(default=None, ge=1)

    @pydantic.model_validator(mode="after")
    def _one_of(self) -> GridRange:
        if (self.step is None) == (self.num is None):
            raise ValueError("give exactly one of step or num")
        if self.step is not None and (self.step <= 0 or self.stop < self.start):
            raise ValueError(f"needs step > 0 and stop >= start (got start={self.start}, stop={self.stop}, step={self.step})")
        return self

    def values(self) -> list[float]:
        if self.num is not None:
            return np.linspace(self.start, self.stop, self.num).tolist()
        n = int(math.floor((self.stop - self.start) / self.step + 1e-9)) + 1
        return (self.start + self.step * np.arange(n)).round(12).tolist()


class SweepSpec(pydantic.BaseModel):
    """The ``[sweep]`` table of a scenario config.

    Example::

        [sweep]
        cell = "error_map"
        trials = 100
        seed = 2021
        [sweep.grid]
        "formation.distance_m" = {start = 30, stop = 100, step = 10}
        "formation.axis_angle_deg" = [5, 10, 15, 20]
        "formation.n_views" = [2, 3]
    """

    model_config = pydantic.ConfigDict(extra="forbid")
    cell: str = pydantic.Field(min_length=1)
    trials: int = pydantic.Field(ge=1, le=1_000_000)
    seed: int = pydantic.Field(default=0, ge=0)
    seed_keys: list[str] | None = pydantic.Field(
        default=None, description="swept keys the random streams depend on (default all; [] = common random numbers)")
    grid: dict[str, list[float | int | bool | str] | GridRange]

    @pydantic.field_validator("grid")
    @classmethod
    def _check_grid(cls, grid: dict) -> dict:
        if not grid:
            raise ValueError("at least one swept key is required")
        for key, v in grid.items():
            if isinstance(v, list) and not v:
                raise ValueError(f"{key}: empty list of values")
            if key == "sweep" or key.startswith("sweep.") or key == "kind":
                raise ValueError(f"{key}: cannot be swept")
        return grid

    @pydantic.model_validator(mode="after")
    def _seed_keys_swept(self) -> SweepSpec:
        for k in self.seed_keys or []:
            if k not in self.grid:
                raise ValueError(f"seed_keys: {k!r} is not a key of sweep.grid")
        return self

    def grid_values(self) -> dict[str, list[Any]]:
        return {k: (v.values() if isinstance(v, GridRange) else list(v)) for k, v in self.grid.items()}


def parse_overrides(items: Sequence[str] | None) -> dict[str, Any]:
    """``["formation.n_views=2", 'observation.mode="rendered"']`` → ``{dotted key: value}``.

    Values are read as TOML (numbers, booleans, quoted strings, arrays); a bare word is a string.
    Raises ``ValueError`` naming ``--set`` for an item without ``=``.
    """
    import tomllib

    out: dict[str, Any] = {}
    for item in items or []:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"--set: expected KEY=VALUE, got {item!r}")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = text.strip()
        out[key] = value
    return out


def prepare_config_sweep(config: Path | str, overrides: Mapping[str, Any] | None = None
                         ) -> tuple[Any, Any, SweepCell, dict[str, list[Any]], list[Any]]:
    """Validate a sweep config and every cell's config; nothing is computed or written.

    ``overrides`` (dotted key → value) are applied to the file before validation.  Returns
    ``(module, cfg, cell, grid, inputs)``; raises ``experiments.scenarios.ConfigError`` (one line
    naming the key) when anything is wrong.
    """
    from experiments.scenarios import ConfigError, load_config

    overrides = dict(overrides or {})
    module, cfg = load_config(config, overrides=overrides)
    spec = getattr(cfg, "sweep", None)
    if spec is None:
        raise ConfigError("sweep: missing [sweep] table (cell, trials, grid)")
    if not hasattr(module, "sweep_cell"):
        raise ConfigError(f"kind: scenario kind {cfg.kind!r} has no sweep cells")
    try:
        cell = module.sweep_cell(cfg)
    except ValueError as exc:
        raise ConfigError(f"sweep.cell: {exc}") from None
    grid = spec.grid_values()
    try:
        _coord_names(list(grid))
        garr = _grid_arrays(grid)
    except ValueError as exc:
        raise ConfigError(f"sweep.{exc}") from None
    inputs = []
    for _, params in _cells(garr):
        try:
            inputs.append(load_config(config, overrides={**overrides, **params})[1])
        except ConfigError as exc:
            raise ConfigError(f"{exc} [in sweep.grid]") from None
    return module, cfg, cell, grid, inputs


def sweep_summary(ds: xr.Dataset, report: SweepReport | None = None) -> dict[str, Any]:
    """JSON-able summary of a stored sweep: sizes, failures by reason, metric ranges."""
    reasons = ds["failure_reason"].values.astype(object).ravel()
    counts: dict[str, int] = {}
    for r in reasons[reasons != ""]:
        counts[str(r)] = counts.get(str(r), 0) + 1
    swept = json.loads(ds.attrs.get("swept_keys", "[]"))
    summary: dict[str, Any] = {
        "cell": ds.attrs.get("cell", ""),
        "kind": ds.attrs.get("kind", ""),
        "grid": {str(d): ds[d].values.tolist() for d in ds["done"].dims},
        "swept_keys": swept,
        "trials": int(ds.sizes["trial"]),
        "cells": int(ds["done"].size),
        "cells_done": int(ds["done"].values.sum()),
        "trials_failed": int(sum(counts.values())),
        "failure_reasons": dict(sorted(counts.items(), key=lambda kv: -kv[1])[:20]),
        "metrics": {},
    }
    for name, var in ds.data_vars.items():
        if name in ("failure_reason", "done"):
            continue
        vals = var.values[np.isfinite(var.values)]
        summary["metrics"][name] = {
            "units": var.attrs.get("units", ""),
            "median": float(np.median(vals)) if vals.size else None,
            "min": float(vals.min()) if vals.size else None,
            "max": float(vals.max()) if vals.size else None,
        }
    if report is not None:
        summary.update({"wall_s": report.wall_s, "cells_computed_this_run": report.n_computed,
                        "workers": report.workers, "peak_worker_rss_mb": report.peak_worker_rss_mb})
    return summary


def redraw(out: Path | str) -> list[Path]:
    """Redraw the figures of a stored sweep from ``out/sweep.zarr`` into ``out/figures``.

    Uses the scenario kind's ``plot_sweep(dataset, fig_dir)`` when the sweep came from a config
    whose kind defines one, else a generic map of every per-trial metric's trial mean.
    """
    from experiments import plots

    out = Path(out)
    ds = open_sweep(out)
    fig_dir = out / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    kind = ds.attrs.get("kind")
    if kind:
        from experiments.scenarios import kind_module

        module = kind_module(kind)
        if hasattr(module, "plot_sweep"):
            return list(module.plot_sweep(ds, fig_dir))
    return plots.sweep_overview_figures(ds, fig_dir)


def _write_summary(out: Path, summary: dict[str, Any]) -> Path:
    path = out / "summary.json"
    tmp = out / ".summary.json.tmp"
    from experiments.scenarios import json_default

    tmp.write_text(json.dumps(summary, indent=2, default=json_default) + "\n")
    tmp.replace(path)
    return path


@app.command()
def sweep(
    config: Path = typer.Argument(..., help="Scenario config (TOML) with a sweep table (cell, trials, seed, grid)."),
    out: Path = typer.Option(..., "--out", help="Output directory: sweep.zarr, summary.json, figures/."),
    workers: int = typer.Option(2, "--workers", help="Dask LocalCluster workers (one thread each)."),
    scheduler: str = typer.Option(None, "--scheduler", help="Address of a running Dask scheduler instead of a LocalCluster."),
    no_figures: bool = typer.Option(False, "--no-figures", help="Skip drawing figures."),
    set_: list[str] = typer.Option(None, "--set", help="Override a config key, KEY=VALUE (TOML value); repeatable."),
) -> None:
    """Sweep config keys over a grid × trials on Dask, streaming each cell to DIR/sweep.zarr.

    Running the same command again resumes: finished cells are not recomputed.
    """
    from experiments.scenarios import ConfigError, _progress_bar

    if workers < 1:
        raise fail(f"--workers: must be >= 1, got {workers}")
    try:
        overrides = parse_overrides(set_)
        module, cfg, cell, grid, inputs = prepare_config_sweep(config, overrides)
    except (ConfigError, ValueError) as exc:
        raise fail(str(exc)) from None
    spec = cfg.sweep
    identity = cfg.model_dump_json(exclude={"sweep"})
    config_text = Path(config).read_text()
    by_params = {_params_key(p): inp for (_, p), inp in zip(_cells(_grid_arrays(grid)), inputs, strict=True)}
    update, stop = _progress_bar()
    try:
        report = run_sweep(cell, grid, trials=spec.trials, out=out, seed=spec.seed,
                           make_input=lambda params: by_params[_params_key(params)], identity=identity,
                           seed_keys=spec.seed_keys,
                           attrs={"kind": cfg.kind, "config_toml": config_text,
                                  "overrides": json.dumps(overrides)},
                           workers=workers, scheduler=scheduler, progress=update)
    except ValueError as exc:
        raise fail(str(exc)) from None
    finally:
        stop()
    ds = open_sweep(out)
    summary = sweep_summary(ds, report)
    path = _write_summary(out, summary)
    figures = [] if no_figures else redraw(out)
    console.print(f"cells: {summary['cells_done']}/{summary['cells']} done "
                  f"({report.n_computed} computed now, {report.wall_s:.1f} s on {report.workers} workers); "
                  f"failed trials: {summary['trials_failed']}", markup=False, highlight=False)
    console.print(f"results: {report.store}, {path}", markup=False, highlight=False)
    for f in figures:
        console.print(f"figure: {f}", markup=False, highlight=False)
