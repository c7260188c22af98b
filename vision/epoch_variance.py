"""The a posteriori variance factor of one epoch's keypoints, from its tracks' epipolar residuals.

How far a rendered keypoint lies from its surface point's true projection depends on the scene far
more than on the keypoint: the same target at the same range and camera spread gives a mean
triangulation NEES of 1 under one attitude and Sun and of 10 under another (with the σ per SIFT
size; ``docs/vision.md``, "Measured σ per epoch").  The cameras see that scale in the epoch's own
residuals.  For every pair of views ``(i, j)`` of every track seen by both, the algebraic epipolar
residual ``e = x_iᵀ F_ij x_j`` (003 eq (2), the fundamental matrix of flag P003-2) has, to first
order, the variance

    var(e) = σ_i² ‖(F_ij x_j)₁,₂‖² + σ_j² ‖(F_ijᵀ x_i)₁,₂‖²

so ``χ² = e² / var(e)`` is χ²(1) when the σ are right.  The factor is the mean χ² of the pairs
below the χ²(1) gate of ``gate_probability`` (the pairs a matcher's outliers put far beyond it
would otherwise set it), with ``prior_pairs`` pseudo-pairs at 1 so that an epoch with few tracks
stays near its σ: ``(Σ χ² + prior_pairs) / (m + prior_pairs)``.  Over the epochs of
``coobs calibrate`` (rendered FY-1 and TOPEX, 96 attitudes per range, random Sun), its logarithm
correlates with the log of the epoch's mean NEES at 0.81 and 0.72, and dividing by it shrinks the
spread of the epochs' NEES from a factor 1.9 to 1.4 (FY-1) and 1.6 to 1.4 (TOPEX) (log standard
deviations 0.62 → 0.37 and 0.44 → 0.30; ``epoch_log_nees_spread`` in the calibration file).  The rest of the scale (the part
of a keypoint's error common to all views, which no residual shows) is the calibration's
``epoch_sigma2_inflation`` (:meth:`vision.calibration.SiftCalibration.track_sigma_px`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["EPOCH_PRIOR_PAIRS", "epipolar_chi2", "epoch_variance_factor"]

#: pseudo-pairs at factor 1 added to an epoch's pairs
EPOCH_PRIOR_PAIRS = 10.0


def epipolar_chi2(uv_px: ArrayLike, K: ArrayLike, T_CW: ArrayLike, sigma_uv_px: ArrayLike) -> np.ndarray:
    """χ² (1 dof each) of the epipolar residual of every (track, view pair) seen in both views.

    Parameters
    ----------
    uv_px : array_like, shape (M, n, 2)
        Keypoints per track and view (NaN where a track is absent).
    K : array_like, shape (n, 3, 3)
    T_CW : array_like, shape (n, 4, 4)
        Camera-from-world poses.
    sigma_uv_px : array_like, shape (M, n)
        σ of each keypoint, px.
    """
    from vision.features import epipolar_residual, fundamental_from_poses

    uv = np.asarray(uv_px, dtype=float)
    sig = np.asarray(sigma_uv_px, dtype=float)
    K = np.asarray(K, dtype=float)
    T = np.asarray(T_CW, dtype=float)
    n = uv.shape[1]
    out = []
    for i in range(n):
        for j in range(i + 1, n):
            both = np.isfinite(uv[:, i, 0]) & np.isfinite(uv[:, j, 0])
            if not both.any():
                continue
            F = fundamental_from_poses(K[i], T[i], K[j], T[j])
            e, l_i, l_j = epipolar_residual(F, uv[both, i], uv[both, j])   # lines in image i and in image j
            var = sig[both, i] ** 2 * (l_i[:, 0] ** 2 + l_i[:, 1] ** 2) + sig[both, j] ** 2 * (l_j[:, 0] ** 2 + l_j[:, 1] ** 2)
            out.append(e ** 2 / var)
    return np.concatenate(out) if out else np.zeros(0)


def epoch_variance_factor(uv_px: ArrayLike, K: ArrayLike, T_CW: ArrayLike, sigma_uv_px: ArrayLike, *,
                          gate_probability: float = 0.999, prior_pairs: float = EPOCH_PRIOR_PAIRS) -> float:
    """Factor on σ² that the epoch's epipolar residuals ask for (module docstring); 1 with no pairs."""
    from scipy.stats import chi2

    if not 0.0 < gate_probability < 1.0:
        raise ValueError(f"gate_probability must be in (0, 1), got {gate_probability!r}")
    if not prior_pairs > 0:
        raise ValueError(f"prior_pairs must be > 0, got {prior_pairs!r}")
    c2 = epipolar_chi2(uv_px, K, T_CW, sigma_uv_px)
    c2 = c2[c2 < chi2.isf(1.0 - gate_probability, 1)]
    return float((c2.sum() + prior_pairs) / (c2.size + prior_pairs))
