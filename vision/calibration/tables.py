"""Filling the calibration's tables: bins without data take the nearest bin's value."""

from __future__ import annotations

import numpy as np

__all__ = ["CalibrationTableEmpty", "fill_nearest", "table"]


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
