"""Input validators shared by the orbits modules (private).

Every public entry point of :mod:`orbits` validates with these, so bad input raises ``ValueError``
naming the parameter and the offending value (``docs/architecture.md``, Contracts).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def check_last_axis(a: ArrayLike, size: int, *, name: str) -> np.ndarray:
    """Float array of shape ``(..., size)`` with finite entries, else ``ValueError`` naming ``name``."""
    arr = np.asarray(a, dtype=float)
    if arr.ndim == 0 or arr.shape[-1] != size:
        raise ValueError(f"{name}: expected shape (..., {size}), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: contains non-finite values")
    return arr


def check_finite(a: ArrayLike, *, name: str) -> np.ndarray:
    """Float array (any shape) with finite entries, else ``ValueError`` naming ``name``."""
    arr = np.asarray(a, dtype=float)
    if not np.all(np.isfinite(arr)):
        bad = arr[~np.isfinite(arr)].ravel()[0]
        raise ValueError(f"{name}: contains non-finite value {bad!r}")
    return arr


def check_positive(a: ArrayLike, *, name: str) -> np.ndarray:
    """Finite float array with every entry > 0, else ``ValueError`` naming ``name`` and the value."""
    arr = check_finite(a, name=name)
    if np.any(arr <= 0.0):
        bad = arr[arr <= 0.0].ravel()[0]
        raise ValueError(f"{name}: must be > 0, got {bad!r}")
    return arr


def check_times(t_s: ArrayLike, *, name: str = "t_s") -> np.ndarray:
    """Finite 1-D array of epochs (a scalar becomes shape ``(1,)``)."""
    arr = check_finite(t_s, name=name)
    if arr.ndim == 0:
        arr = arr[None]
    if arr.ndim != 1:
        raise ValueError(f"{name}: expected a 1-D array of epochs, got shape {arr.shape}")
    return arr
