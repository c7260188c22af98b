"""Result of a rigid registration ``Q ≈ R P + t`` and the failure reasons it reports.

Rotation error convention (for ``cov``): the true motion is ``R = exp([δθ×]) R̂``, ``t = t̂ + δt``,
so δθ is a small rotation vector in Q's frame (rad) and ``cov`` is the covariance of
``[δθ, δt]`` (rad², rad·m, m²).  Degenerate input (fewer than 3 usable points, collinear points)
is reported in ``ok`` / ``failure_reason`` with NaN R and t; no exception inside a batch.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["KABSCH_REASONS", "RigidRegistration"]

#: Failure reason of each Kabsch failure code (index = code; 0 is ok).
KABSCH_REASONS = ("", "fewer than 3 usable points", "points are collinear",
                  "points are coincident")


@dataclass(frozen=True)
class RigidRegistration:
    """Result of a rigid fit ``Q ≈ R P + t`` (batch axes ``...``, ``N`` correspondences).

    Attributes
    ----------
    R : ndarray (..., 3, 3)
        Rotation taking P's frame to Q's (for inter-frame registration in W, the attitude
        increment ΔR of 003 eq 31).  NaN when not ok.
    t : ndarray (..., 3)
        Translation, m.  NaN when not ok.
    cov : ndarray (..., 6, 6)
        Covariance of ``[δθ (rad), δt (m)]`` with ``R_true = exp([δθ×]) R``; NaN when the
        method does not provide one (Kabsch, RANSAC) or when not ok.
    inliers : ndarray (..., N) bool
        Correspondences used in the final fit.
    n_inliers : ndarray (...,) int
    rms_m : ndarray (...,)
        RMS Euclidean residual ``‖Q − R P − t‖`` over the inliers, m.
    chi2 : ndarray (...,)
        Sum of squared Mahalanobis residuals over the inliers (NaN without covariances);
        compare with ``dof``.
    dof : ndarray (...,) int
        ``3 n_inliers − 6``.
    ok : bool or ndarray (...,) bool
    failure_reason : str or ndarray (...,) str
        ``""`` when ok.
    method : str
        ``"kabsch"``, ``"ransac"``, ``"ml"``, ``"icp"`` or ``"fpfh_ransac"``.
    """

    R: np.ndarray
    t: np.ndarray
    cov: np.ndarray
    inliers: np.ndarray
    n_inliers: np.ndarray
    rms_m: np.ndarray
    chi2: np.ndarray
    dof: np.ndarray
    ok: bool | np.ndarray
    failure_reason: str | np.ndarray
    method: str

    @property
    def rotation_sigma_rad(self) -> np.ndarray:
        """Predicted RMS of the rotation error ``‖δθ‖``, ``sqrt(tr cov_θθ)``, rad."""
        return np.sqrt(np.trace(self.cov[..., :3, :3], axis1=-2, axis2=-1))
