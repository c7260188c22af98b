"""Filling and indexing the calibration's tables: bins without data take the nearest bin's value;
the bin of a value in a short table of edges."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["CalibrationTableEmpty", "bin_index", "fill_nearest", "table"]


class CalibrationTableEmpty(ValueError):
    """A calibration table without a single measured value (too few samples to fill it)."""


def fill_nearest(values: list) -> np.ndarray:
    """Bins without data (None/NaN) take the value of the nearest bin with data."""
    v = np.array([np.nan if x is None else float(x) for x in values])
    ok = np.nonzero(np.isfinite(v))[0]
    if ok.size == 0:
        raise CalibrationTableEmpty("calibration: a table has no measured value")
    idx = np.arange(len(v))
    near = ok[np.argmin(np.abs(idx[:, None] - ok[None, :]), axis=1)]
    return v[near]


def table(rows: list) -> np.ndarray:
    """A table ``(R, C)`` of rows with gaps, each row filled by :func:`fill_nearest`."""
    return np.stack([fill_nearest(r) for r in rows])


def bin_index(edges: np.ndarray, x: ArrayLike, side: str, lo: int, hi: int) -> np.ndarray:
    """``clip(searchsorted(edges, x, side) - 1, lo, hi)`` for a short sorted table ``edges``, by one
    comparison per edge between ``lo`` and ``hi`` (a binary search per element is several times
    slower on large ``x``); NaN sorts last, as in ``searchsorted``."""
    x = np.asarray(x, dtype=float)
    above = np.greater_equal if side == "right" else np.greater
    out = np.full(x.shape, lo, dtype=np.intp)
    for e in edges[lo + 1:hi + 1]:
        out += above(x, e)
    nan = np.isnan(x)
    if nan.any():
        out[nan] = hi
    return out
