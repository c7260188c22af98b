"""Shape checks of point and angle-pair arrays shared by the cylindrical-imaging modules."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def as_points(X: ArrayLike, name: str) -> np.ndarray:
    """``X`` as a float array of shape ``(..., 3)``; ``ValueError`` naming ``name`` otherwise."""
    arr = np.asarray(X, dtype=float)
    if arr.ndim == 0 or arr.shape[-1] != 3:
        raise ValueError(f"{name}: expected shape (..., 3), got {arr.shape}")
    return arr


def as_pairs(x: ArrayLike, name: str) -> np.ndarray:
    """``x`` as a float array of shape ``(..., 2)``; ``ValueError`` naming ``name`` otherwise."""
    arr = np.asarray(x, dtype=float)
    if arr.ndim == 0 or arr.shape[-1] != 2:
        raise ValueError(f"{name}: expected shape (..., 2), got {arr.shape}")
    return arr
