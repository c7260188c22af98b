"""Camera model of paper 001: focal-plane image of known feature points and its Jacobian.

* Image (001 eq 7): focal-plane coordinates in metres of the inverted image behind the lens,
  ``x = −f X_C / Z_C``, ``y = −f Y_C / Z_C``.  :func:`focal_plane_from_pixels` and
  :func:`pixels_from_focal_plane` convert to and from OpenCV pixel coordinates
  ``u = c_u + (f / p) X_C / Z_C``.  The camera frame ``C`` is the project's
  (``docs/conventions.md``): ``z`` along the boresight, ``x`` right, ``y`` down.
* Jacobian (001 eq 18, 25): ``A_j = J_c [2[X_r×] | I]`` with the corrected projection Jacobian of
  flag P001-1 (docs/papers.md#p001-1), ``J_c = [[−f/Z̄, 0, f X̄/Z̄²], [0, −f/Z̄, f Ȳ/Z̄²]]``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from attitude.gibbs import shuster_matrix_from_gibbs_set
from chaser.rodrigues_pose.pose import GibbsPose

__all__ = [
    "check_positive",
    "project_focal_plane",
    "focal_plane_from_pixels",
    "pixels_from_focal_plane",
    "predict_image_jacobian",
    "projection_jacobian",
]


def check_positive(value: float, name: str) -> float:
    """``value`` as a float; ``ValueError`` naming ``name`` unless it is finite and > 0."""
    v = float(value)
    if not np.isfinite(v) or v <= 0:
        raise ValueError(f"{name}: must be a positive finite number, got {value!r}")
    return v


def project_focal_plane(points_T: ArrayLike, R_CT: ArrayLike, r_TC_C: ArrayLike, *,
                        focal_length_m: float) -> tuple[np.ndarray, np.ndarray]:
    """001 eq (6)–(7): focal-plane image ``x = −f X_C/Z_C``, ``y = −f Y_C/Z_C`` of body-frame points.

    Parameters
    ----------
    points_T : (..., M, 3) array
        Feature points in the target body frame, m.
    R_CT : (..., 3, 3) array
        Target→camera rotation.
    r_TC_C : (..., 3) array
        Target origin relative to the camera, camera components, m.
    focal_length_m : float

    Returns
    -------
    xy_m : (..., M, 2) ndarray
        Focal-plane coordinates, m (inverted image; NaN where ``Z_C <= 0``).
    depth_m : (..., M) ndarray
        ``Z_C`` of each point, m.
    """
    f = check_positive(focal_length_m, "focal_length_m")
    P = np.asarray(points_T, dtype=float)
    R = np.asarray(R_CT, dtype=float)
    t = np.asarray(r_TC_C, dtype=float)
    if P.ndim < 2 or P.shape[-1] != 3:
        raise ValueError(f"points_T: expected shape (..., M, 3), got {P.shape}")
    if R.ndim < 2 or R.shape[-2:] != (3, 3):
        raise ValueError(f"R_CT: expected shape (..., 3, 3), got {R.shape}")
    if t.ndim < 1 or t.shape[-1] != 3:
        raise ValueError(f"r_TC_C: expected shape (..., 3), got {t.shape}")
    Xc = np.einsum("...ij,...mj->...mi", R, P) + t[..., None, :]
    Z = Xc[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = np.where((Z > 0)[..., None], -f * Xc[..., :2] / Z[..., None], np.nan)
    return xy, Z


def _image_pairs(values: ArrayLike, name: str, principal_point_px: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Image coordinates ``(..., 2)`` and the principal point ``(2,)`` as float arrays, shapes checked."""
    arr = np.asarray(values, dtype=float)
    c = np.asarray(principal_point_px, dtype=float)
    if arr.ndim == 0 or arr.shape[-1] != 2:
        raise ValueError(f"{name}: expected shape (..., 2), got {arr.shape}")
    if c.shape != (2,):
        raise ValueError(f"principal_point_px: expected shape (2,), got {c.shape}")
    return arr, c


def focal_plane_from_pixels(uv_px: ArrayLike, *, pixel_size_m: float, principal_point_px: ArrayLike) -> np.ndarray:
    """Focal-plane coordinates of 001 eq (7) from OpenCV pixels: ``x = −(u − c_u) p``, ``y = −(v − c_v) p``."""
    p = check_positive(pixel_size_m, "pixel_size_m")
    uv, c = _image_pairs(uv_px, "uv_px", principal_point_px)
    return -(uv - c) * p


def pixels_from_focal_plane(xy_m: ArrayLike, *, pixel_size_m: float, principal_point_px: ArrayLike) -> np.ndarray:
    """OpenCV pixels ``u = c_u − x/p``, ``v = c_v − y/p`` of 001 focal-plane coordinates (inverse of the above)."""
    p = check_positive(pixel_size_m, "pixel_size_m")
    xy, c = _image_pairs(xy_m, "xy_m", principal_point_px)
    return c - xy / p


def predict_image_jacobian(P: np.ndarray, g: np.ndarray, i: np.ndarray, t: np.ndarray,
                           f: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq (14), (17), (20) and (25) for a flat batch: returns x̄ (B, M, 2), Z̄ (B, M), A_j (B, M, 2, 6).

    ``P`` (B, M, 3) body-frame points (m), ``g`` (B, 3) Gibbs vectors of sets ``i`` (B,), ``t``
    (B, 3) translations ``r_TC_C`` (m), ``f`` the focal length (m).

    ``A_j = J_c · (matrix of eq 18)`` is written out product by product: with ``a = −f/Z̄``,
    ``b_x = f X̄/Z̄²``, ``b_y = f Ȳ/Z̄²`` (flag P001-1), row x is ``a·(18)₁ + b_x·(18)₃`` and row y is
    ``a·(18)₂ + b_y·(18)₃``.
    """
    R = shuster_matrix_from_gibbs_set(g, i)
    Xr = P @ np.swapaxes(R, -1, -2)  # (17)
    Xc = Xr + t[:, None, :]  # (14)
    X, Y, Z = Xc[..., 0], Xc[..., 1], Xc[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_z = 1.0 / Z
        a = -f * inv_z
        bx = -a * X * inv_z
        by = -a * Y * inv_z
    xbar = np.empty(Z.shape + (2,))
    xbar[..., 0] = a * X  # (20)
    xbar[..., 1] = a * Y
    xr, yr, zr = 2.0 * Xr[..., 0], 2.0 * Xr[..., 1], 2.0 * Xr[..., 2]
    A = np.zeros(Z.shape + (2, 6))
    A[..., 0, 0] = -yr * bx
    A[..., 0, 1] = -zr * a + xr * bx
    A[..., 0, 2] = yr * a
    A[..., 0, 3] = a
    A[..., 0, 5] = bx
    A[..., 1, 0] = zr * a - yr * by
    A[..., 1, 1] = xr * by
    A[..., 1, 2] = -xr * a
    A[..., 1, 4] = a
    A[..., 1, 5] = by
    return xbar, Z, A


def projection_jacobian(points_T: ArrayLike, pose: GibbsPose, *, focal_length_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Predicted image (001 eq 20) and the 2×6 Jacobian ``A_j`` (eq 25) of every point.

    ``A_j = J_c [2[X_r×] | I]`` with the corrected ``J_c`` of flag P001-1 (docs/papers.md#p001-1); columns are
    ``[δg, Δt]`` where ``δg`` is the left (error) Gibbs vector of 001 eq (10) and ``Δt`` the additive
    translation correction (eq 11).

    Parameters
    ----------
    points_T : (M, 3) or (..., M, 3) array
        Feature points in the target body frame, m.
    pose : GibbsPose
        Linearisation point, batch shape ``...``.
    focal_length_m : float

    Returns
    -------
    xy_m : (..., M, 2) ndarray
    A : (..., M, 2, 6) ndarray
    """
    f = check_positive(focal_length_m, "focal_length_m")
    P = np.asarray(points_T, dtype=float)
    if P.ndim < 2 or P.shape[-1] != 3:
        raise ValueError(f"points_T: expected shape (..., M, 3), got {P.shape}")
    shape = pose.shape
    M = P.shape[-2]
    Pb = np.broadcast_to(P, shape + (M, 3)).reshape(-1, M, 3)
    xbar, _, A = predict_image_jacobian(Pb, pose.g.reshape(-1, 3), pose.gibbs_set.reshape(-1), pose.r_TC_C.reshape(-1, 3), f)
    return xbar.reshape(shape + (M, 2)), A.reshape(shape + (M, 2, 6))
