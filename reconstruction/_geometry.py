"""Private kernels shared by the reconstruction modules: input checks, pinhole projection and its
Jacobian, small closed-form 3×3 algebra.

Everything here is vectorised over leading axes and tolerant of NaN rows (a NaN input gives a NaN
output, never an exception), because the public functions run inside sweeps.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike
from scipy.stats import chi2 as _chi2

__all__: list[str] = []


@lru_cache(maxsize=64)
def chi2_quantile(probability: float, dof: int) -> float:
    """The χ² quantile of ``probability`` with ``dof`` degrees of freedom (SciPy's, cached: the gates
    ask for the same few values thousands of times in a run)."""
    return float(_chi2.ppf(probability, dof))


def scalar_or_array(a: np.ndarray) -> object:
    """``a`` as a Python scalar when it is 0-d (an unbatched result field), else unchanged."""
    a = np.asarray(a)
    return a.item() if a.ndim == 0 else a


# --------------------------------------------------------------------------- input checks
def as_float(a: ArrayLike, name: str) -> np.ndarray:
    try:
        arr = np.asarray(a, dtype=float)
    except (TypeError, ValueError) as exc:  # pragma: no cover - message path
        raise ValueError(f"{name}: not convertible to a float array ({exc})") from None
    return arr


def check_intrinsics(K: ArrayLike, name: str = "K") -> np.ndarray:
    """``(..., n, 3, 3)`` upper-triangular pinhole matrices with last row ``[0, 0, 1]``."""
    K = as_float(K, name)
    if K.ndim < 3 or K.shape[-2:] != (3, 3):
        raise ValueError(f"{name}: expected shape (..., n_views, 3, 3), got {K.shape}")
    if not np.all(np.isfinite(K)):
        raise ValueError(f"{name}: contains non-finite values")
    if not np.allclose(K[..., 2, :], [0.0, 0.0, 1.0]) or not np.allclose(K[..., 1, 0], 0.0):
        raise ValueError(f"{name}: not a pinhole matrix (last row must be [0, 0, 1], K[1, 0] = 0)")
    if np.any(K[..., 0, 0] <= 0) or np.any(K[..., 1, 1] <= 0):
        raise ValueError(f"{name}: focal lengths K[0, 0], K[1, 1] must be > 0, got "
                         f"{np.min(K[..., 0, 0])!r}, {np.min(K[..., 1, 1])!r}")
    return K


def check_poses(T_CW: ArrayLike, name: str = "T_CW") -> np.ndarray:
    """``(..., n, 4, 4)`` camera-from-world rigid transforms."""
    T = as_float(T_CW, name)
    if T.ndim < 3 or T.shape[-2:] != (4, 4):
        raise ValueError(f"{name}: expected shape (..., n_views, 4, 4), got {T.shape}")
    if not np.all(np.isfinite(T)):
        raise ValueError(f"{name}: contains non-finite values")
    if not np.allclose(T[..., 3, :], [0.0, 0.0, 0.0, 1.0]):
        raise ValueError(f"{name}: last row must be [0, 0, 0, 1]")
    R = T[..., :3, :3]
    err = np.max(np.abs(R @ np.swapaxes(R, -1, -2) - np.eye(3)))
    if err > 1e-6 or np.any(np.linalg.det(R) < 0):
        raise ValueError(f"{name}: rotation block is not a rotation matrix (max |R Rᵀ − I| = {err:.3g})")
    return T


def check_positive(x: ArrayLike, name: str, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """Finite, strictly positive values; broadcast (read-only view) to ``shape`` when given."""
    arr = as_float(x, name)
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"{name}: must be finite and > 0, got {x!r}")
    if shape is None:
        return arr
    try:
        return np.broadcast_to(arr, shape)
    except ValueError:
        raise ValueError(f"{name}: shape {arr.shape} does not broadcast to {shape}") from None


def check_probability(p: float, name: str) -> float:
    p = float(p)
    if not 0.0 < p < 1.0:
        raise ValueError(f"{name}: must lie in (0, 1), got {p!r}")
    return p


def check_points(X: ArrayLike, name: str, *, allow_nan: bool = True, scan: bool = True) -> np.ndarray:
    """``(..., N, 3)`` points; ``scan=False`` skips the value scan (the caller detects infinities
    in the problems whose moments come out non-finite)."""
    X = as_float(X, name)
    if X.ndim < 2 or X.shape[-1] != 3:
        raise ValueError(f"{name}: expected shape (..., n_points, 3), got {X.shape}")
    if not scan:
        return X
    if np.any(np.isinf(X)) or (not allow_nan and np.any(np.isnan(X))):
        raise ValueError(f"{name}: contains non-finite values")
    return X


def check_covariances(C: ArrayLike, name: str, points_shape: tuple[int, ...]) -> np.ndarray:
    C = as_float(C, name)
    if C.shape[-2:] != (3, 3):
        raise ValueError(f"{name}: expected shape (..., n_points, 3, 3), got {C.shape}")
    try:
        np.broadcast_shapes(C.shape[:-2], points_shape[:-1])
    except ValueError:
        raise ValueError(f"{name}: shape {C.shape} does not match the points {points_shape}") from None
    if np.any(np.isinf(C)):
        raise ValueError(f"{name}: contains infinite values")
    return C


# --------------------------------------------------------------------------- 3×3 algebra
def sym3_inv(C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse and determinant of symmetric 3×3 matrices ``(..., 3, 3)`` by the adjugate.

    Much faster than ``np.linalg.inv`` on millions of tiny matrices; singular or NaN input
    gives NaN (never raises).
    """
    a, b, c = C[..., 0, 0], C[..., 0, 1], C[..., 0, 2]
    d, e = C[..., 1, 1], C[..., 1, 2]
    f = C[..., 2, 2]
    A = d * f - e * e
    B = c * e - b * f
    Cc = b * e - c * d
    D = a * f - c * c
    E = b * c - a * e
    F = a * d - b * b
    det = a * A + b * B + c * Cc
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_det = np.where(det != 0, 1.0 / det, np.nan)
    out = np.empty(C.shape, dtype=float)
    out[..., 0, 0] = A
    out[..., 0, 1] = out[..., 1, 0] = B
    out[..., 0, 2] = out[..., 2, 0] = Cc
    out[..., 1, 1] = D
    out[..., 1, 2] = out[..., 2, 1] = E
    out[..., 2, 2] = F
    return out * inv_det[..., None, None], det


def proper_rotation_from_svd(B: np.ndarray) -> np.ndarray:
    """``U diag(1, 1, det(U Vᵀ)) Vᵀ`` of ``B = U D Vᵀ``: the rotation maximising ``tr(Rᵀ B)``.

    000 eq (36)–(37) with the corrections (c), (d) of flag P000-10 (docs/papers.md#p000-10); NaN
    input gives NaN.
    """
    bad = ~np.all(np.isfinite(B), axis=(-2, -1))
    if np.any(bad):
        B = np.where(bad[..., None, None], np.eye(3), B)
    U, _, Vt = np.linalg.svd(B)
    d = np.sign(np.linalg.det(U @ Vt))
    d = np.where(d == 0, 1.0, d)
    U = U.copy()
    U[..., :, 2] *= d[..., None]
    R = U @ Vt
    if np.any(bad):
        R = np.where(bad[..., None, None], np.nan, R)
    return R


# --------------------------------------------------------------------------- projection
def project(X_W: np.ndarray, K: np.ndarray, T_CW: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Project world points through pinhole cameras (broadcast over leading axes).

    Parameters
    ----------
    X_W : (..., 3) points in the world frame W, m.
    K : (..., 3, 3) intrinsics, px.
    T_CW : (..., 4, 4) camera-from-world.

    Returns
    -------
    uv_px : (..., 2) pixel coordinates (OpenCV convention).
    X_C : (..., 3) points in the camera frame, m (depth ``X_C[..., 2]``).
    J_px_per_m : (..., 2, 3) Jacobian ``∂uv/∂X_W``.
    """
    R = T_CW[..., :3, :3]
    X_C = (R @ X_W[..., None])[..., 0] + T_CW[..., :3, 3]
    p = (K @ X_C[..., None])[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_z = 1.0 / p[..., 2]
    uv = p[..., :2] * inv_z[..., None]
    # ∂uv/∂X_C = (K[:2, :] − uv ⊗ K[2, :]) / z  with K[2, :] = [0, 0, 1]
    Jc = K[..., :2, :] - uv[..., :, None] * K[..., 2:3, :]
    Jc = Jc * inv_z[..., None, None]
    return uv, X_C, Jc @ R
