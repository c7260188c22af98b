"""Cramér–Rao bound of the monocular pose of paper 001 from isotropic image noise.

Measurement model (001 eq 6–7): each visible feature point ``X_T`` gives the focal-plane image
``x = −f X_C/Z_C``, ``y = −f Y_C/Z_C`` of ``X_C = R_CT X_T + r_TC_C``, with independent zero-mean
Gaussian noise of standard deviation ``σ`` (m on the focal plane, ``σ = noise_px · pixel_size``) on
both coordinates.  The pose error is ``x = [φ, δr]``: ``φ`` the rotation vector of the attitude error
in camera axes (``R_CT = exp([φ×]) R̂_CT``, rad) and ``δr`` the position error of ``r_TC_C`` (m).

The Jacobian of one point is the module's own 001 eq (25), ``A_j = J_c [2[X_r×] | I]`` with the
corrected ``J_c`` of flag P001-1 (docs/papers.md#p001-1), taken at the true pose.  Its attitude
columns are with respect to the Gibbs error vector ``δg`` of eq (10) in Shuster's convention, for
which ``A(δg) ≈ I − 2[δg×]``, so ``φ = −2 δg`` and ``H_j = A_j diag(−½ I₃, I₃)``.  The Fisher
information is ``F = Σ_j H_jᵀ H_j / σ²`` and the bound on the covariance of any unbiased estimator
is ``F⁻¹``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from attitude.quaternion import quat_from_matrix
from chaser.rodrigues_pose.pose import GibbsPose
from chaser.rodrigues_pose.projection import (
    check_positive,
    project_focal_plane,
    projection_jacobian,
)

__all__ = ["PoseBound", "pose_crlb"]

#: Values of :attr:`PoseBound.failure_reason` ("" means the bound exists).
BOUND_FAILURE_REASONS = ("too_few_points", "behind_camera", "rank_deficient")


@dataclass(frozen=True)
class PoseBound:
    """The Cramér–Rao bound of one pose (batch shape ``...``); NaN where ``ok`` is false.

    Attributes
    ----------
    covariance : (..., 6, 6) ndarray
        ``F⁻¹`` for ``[φ (rad, camera axes), δr_TC_C (m, camera axes)]``.
    sigma_along_los_m : (...,) ndarray
        ``√(uᵀ C_r u)``, ``u = r_TC_C/|r_TC_C|``: the position error along the line of sight, m.
    sigma_across_los_m : (...,) ndarray
        ``√(tr C_r − uᵀ C_r u)``: the RMS of the norm of the position error across the line of sight, m.
    sigma_attitude_rad : (...,) ndarray
        ``√(tr C_φ)``: the RMS attitude error angle, rad.
    n_points : (...,) int ndarray
        Points in the information.
    ok : (...,) bool ndarray
    failure_reason : (...,) str ndarray
        ``""`` or one of ``too_few_points`` (fewer than 3 visible points), ``behind_camera``,
        ``rank_deficient`` (the Fisher information is singular to within ``rcond``).
    """

    covariance: np.ndarray
    sigma_along_los_m: np.ndarray
    sigma_across_los_m: np.ndarray
    sigma_attitude_rad: np.ndarray
    n_points: np.ndarray
    ok: np.ndarray
    failure_reason: np.ndarray


def pose_crlb(points_T: ArrayLike, R_CT: ArrayLike, r_TC_C: ArrayLike, *, focal_length_m: float,
              pixel_sigma_m: float, visible: ArrayLike | None = None, rcond: float = 1e-12) -> PoseBound:
    """Cramér–Rao bound of the 6-DoF pose from the images of known feature points (001 eq 6, 7, 25).

    Parameters
    ----------
    points_T : (M, 3) or (..., M, 3) array
        Feature points in the target body frame, m.
    R_CT : (..., 3, 3) array
        True target→camera rotation.
    r_TC_C : (..., 3) array
        True target origin relative to the camera, camera components, m.
    focal_length_m : float
        ``f``, m.
    pixel_sigma_m : float
        Standard deviation of the image noise on each focal-plane coordinate, m (pixels × pixel size).
    visible : (..., M) bool array, optional
        Points measured (default all).
    rcond : float
        The information is singular when its smallest eigenvalue, after scaling to unit diagonal,
        is below ``rcond``.

    Returns
    -------
    PoseBound
        Batch shape: the broadcast of ``R_CT``'s, ``r_TC_C``'s, ``points_T``'s and ``visible``'s.
    """
    f = check_positive(focal_length_m, "focal_length_m")
    sigma = check_positive(pixel_sigma_m, "pixel_sigma_m")
    P = np.asarray(points_T, dtype=float)
    R = np.asarray(R_CT, dtype=float)
    r = np.asarray(r_TC_C, dtype=float)
    if P.ndim < 2 or P.shape[-1] != 3 or not np.all(np.isfinite(P)):
        raise ValueError(f"points_T: expected finite array of shape (..., M, 3), got shape {P.shape}")
    if R.ndim < 2 or R.shape[-2:] != (3, 3) or not np.all(np.isfinite(R)):
        raise ValueError(f"R_CT: expected finite array of shape (..., 3, 3), got shape {R.shape}")
    if r.ndim < 1 or r.shape[-1] != 3 or not np.all(np.isfinite(r)):
        raise ValueError(f"r_TC_C: expected finite array of shape (..., 3), got shape {r.shape}")
    M = P.shape[-2]
    vis = np.ones(M, bool) if visible is None else np.asarray(visible)
    if vis.dtype != bool or vis.shape[-1:] != (M,):
        raise ValueError(f"visible: expected a bool array of shape (..., {M}), got {vis.dtype} {vis.shape}")
    shape = np.broadcast_shapes(R.shape[:-2], r.shape[:-1], P.shape[:-2], vis.shape[:-1])
    R = np.broadcast_to(R, shape + (3, 3))
    r = np.broadcast_to(r, shape + (3,))
    P = np.broadcast_to(P, shape + (M, 3))
    vis = np.broadcast_to(vis, shape + (M,))

    _, depth = project_focal_plane(P, R, r, focal_length_m=f)
    behind = np.any(vis & ~(depth > 0), -1)
    pose = GibbsPose.from_quat(quat_from_matrix(R), r)
    _, A = projection_jacobian(P, pose, focal_length_m=f)  # (..., M, 2, 6), columns [δg, Δt]
    H = A * np.array([-0.5, -0.5, -0.5, 1.0, 1.0, 1.0])  # φ = −2 δg
    H = np.where((vis & ~behind[..., None])[..., None, None], H, 0.0).reshape(shape + (2 * M, 6))
    F = np.einsum("...ki,...kj->...ij", H, H) / sigma**2
    n = vis.sum(-1)
    d = np.sqrt(np.abs(F.diagonal(0, -2, -1)))
    dd = np.where(d > 0, d, 1.0)
    Fs = F / (dd[..., :, None] * dd[..., None, :])
    lam = np.linalg.eigvalsh(Fs)
    singular = ~(lam[..., 0] > rcond * lam[..., -1]) | ~np.all(d > 0, -1)
    reason = np.where(n < 3, "too_few_points", np.where(behind, "behind_camera",
                                                        np.where(singular, "rank_deficient", "")))
    ok = reason == ""
    Fs = np.where(ok[..., None, None], Fs, np.eye(6))
    C = np.linalg.inv(Fs) / (dd[..., :, None] * dd[..., None, :])
    C = np.where(ok[..., None, None], C, np.nan)
    u = r / np.linalg.norm(r, axis=-1, keepdims=True)
    Cr = C[..., 3:, 3:]
    along2 = np.einsum("...i,...ij,...j->...", u, Cr, u)
    tr_r = np.trace(Cr, axis1=-2, axis2=-1)
    return PoseBound(
        covariance=C,
        sigma_along_los_m=np.sqrt(along2),
        sigma_across_los_m=np.sqrt(np.maximum(tr_r - along2, 0.0)),
        sigma_attitude_rad=np.sqrt(np.trace(C[..., :3, :3], axis1=-2, axis2=-1)),
        n_points=n,
        ok=ok,
        failure_reason=reason.astype(str),
    )
