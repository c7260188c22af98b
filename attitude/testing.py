"""Test assertions for rotations: quaternions compared as attitudes (``q`` and ``−q`` are equal)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["assert_quat_equal"]


def assert_quat_equal(actual: ArrayLike, expected: ArrayLike, *, atol: float = 1e-12,
                      err_msg: str = "") -> None:
    """Assert that quaternions describe the same attitudes, component-wise within ``atol``.

    Each row of ``actual`` is compared with the row of ``expected`` after flipping its sign when
    the two point into opposite half-spaces (``q`` and ``−q`` are the same rotation), so the
    check is sign-invariant but otherwise as strict as ``np.testing.assert_allclose`` with
    ``rtol=0``.  NaN rows must be NaN in both.

    Parameters
    ----------
    actual, expected : array_like, shape (..., 4)
        Scalar-first quaternions; the leading axes broadcast against each other.
    atol : float
        Absolute tolerance per component (dimensionless).
    err_msg : str
        Prepended to the failure message.

    Raises
    ------
    AssertionError
        If a row differs by more than ``atol`` in some component for both signs.
    ValueError
        If an input does not have a last axis of length 4.
    """
    a = np.asarray(actual, dtype=float)
    b = np.asarray(expected, dtype=float)
    for name, arr in (("actual", a), ("expected", b)):
        if arr.ndim == 0 or arr.shape[-1] != 4:
            raise ValueError(f"{name}: expected shape (..., 4), got {arr.shape}")
    sign = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    np.testing.assert_allclose(sign * a, b, rtol=0.0, atol=atol,
                               err_msg=f"{err_msg} (compared up to the sign of each quaternion)".lstrip())
