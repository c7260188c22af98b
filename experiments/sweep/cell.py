"""A sweep cell: the function evaluated at one grid point, its metrics, and its safe evaluation.

A *cell* is one grid point with all its trials: one Dask task, one region write into the store.
:func:`run_cell` evaluates it on a worker and never raises: an exception, a trial the cell reports as
failed, or a malformed return value becomes NaN metrics plus a ``failure_reason`` string.
"""

from __future__ import annotations

import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["Metric", "SweepCell", "REASON_MAX_CHARS", "failure_rows", "run_cell"]

#: longest failure reason kept (characters)
REASON_MAX_CHARS = 300


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
        """Shape of metric ``name`` for ``trials`` trials: ``(trials, *dims)``, or ``(*dims)`` when
        the metric is computed once per cell."""
        m = self.metrics[name]
        extra = tuple(len(self.coords[d]) for d in m.dims)
        return (trials, *extra) if m.per_trial else extra


def failure_rows(cell: SweepCell, trials: int, reason: str) -> dict[str, np.ndarray]:
    """NaN metrics and ``failure_reason = reason`` (truncated) for every trial of a failed cell."""
    out: dict[str, np.ndarray] = {
        name: np.full(cell.metric_shape(name, trials), np.nan) for name in cell.metrics
    }
    out["failure_reason"] = np.array([reason[:REASON_MAX_CHARS]] * trials, dtype=object)
    return out


def run_cell(cell: SweepCell, cell_input: Any, entropy: list[int], trials: int) -> dict[str, np.ndarray]:
    """Evaluate one cell; never raises (an exception becomes failure rows)."""
    seeds = [np.random.SeedSequence(entropy, spawn_key=(t,)) for t in range(trials)]
    try:
        raw = cell.fn(cell_input, seeds)
    except Exception as exc:  # noqa: BLE001 - a cell failure must become a row, never a crash
        where = traceback.extract_tb(exc.__traceback__)[-1]
        return failure_rows(cell, trials, f"{type(exc).__name__}: {exc} [{Path(where.filename).name}:{where.lineno}]")
    out: dict[str, np.ndarray] = {}
    for name in cell.metrics:
        if name not in raw:
            return failure_rows(cell, trials, f"cell function did not return metric {name!r}")
        arr = np.asarray(raw[name], dtype=float)
        shape = cell.metric_shape(name, trials)
        if arr.shape != shape:
            return failure_rows(cell, trials, f"metric {name!r} has shape {arr.shape}, expected {shape}")
        out[name] = arr
    reason = raw.get("failure_reason")
    if reason is None:
        reason = np.array([""] * trials, dtype=object)
    reason = np.array([str(r)[:REASON_MAX_CHARS] for r in np.asarray(reason, dtype=object).reshape(-1)], dtype=object)
    if reason.shape != (trials,):
        return failure_rows(cell, trials, f"failure_reason has shape {reason.shape}, expected ({trials},)")
    failed = reason != ""
    for name, m in cell.metrics.items():
        if m.per_trial and failed.any():
            out[name][failed] = np.nan
    out["failure_reason"] = reason
    return out
