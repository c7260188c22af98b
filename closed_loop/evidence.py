"""Evidence before use: the checks a registration passes before any estimator sees it.

A registered increment reaches a filter or the smoother only with

* at least ``min_inliers`` inlier point pairs (a 3-point fit of 8 matches can be 16° wrong and
  still claim a σ of 3°);
* a conditioned geometry: the inliers' spread about their centroid,
  ``Σ (|q̃|² I − q̃ q̃ᵀ)``, has a condition number at most ``max_condition`` (points on a line
  leave a rotation about it unobserved);
* residuals consistent with their covariances: ``Σ rᵢᵀ (C_Qᵢ + R C_Pᵢ Rᵀ)⁻¹ rᵢ`` within the
  ``residual_probability`` quantile of χ² with ``3 n − 6`` degrees of freedom.

:func:`check_evidence` gives ``""`` or the reason, recorded per epoch.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

__all__ = ["Evidence", "check_evidence", "spread_information"]


def spread_information(Q: np.ndarray) -> np.ndarray:
    """``Σ [q̃×]ᵀ[q̃×] = Σ (|q̃|² I − q̃ q̃ᵀ)`` of points ``(k, 3)`` about their centroid: the rotation
    information of a rigid fit per unit isotropic residual variance."""
    qc = Q - Q.mean(axis=0)
    return np.sum(qc * qc) * np.eye(3) - qc.T @ qc


@dataclass(frozen=True)
class Evidence:
    """Thresholds of :func:`check_evidence`.

    Attributes
    ----------
    min_inliers : int
    max_condition : float
    residual_probability : float
        χ² quantile the residual cost must not exceed (0 < p < 1).
    """

    min_inliers: int = 10
    max_condition: float = 1e3
    residual_probability: float = 0.9999


def check_evidence(P: np.ndarray, Q: np.ndarray, cov_P: np.ndarray, cov_Q: np.ndarray, R: np.ndarray, t: np.ndarray,
                   inliers: np.ndarray, evidence: Evidence) -> str:
    """``""`` when a rigid fit ``Q ≈ R P + t`` of the pairs passes :class:`Evidence`, else why not.

    Parameters
    ----------
    P, Q : ndarray (k, 3)
        Matched points, m.
    cov_P, cov_Q : ndarray (k, 3, 3)
        Their covariances, m².
    R, t : ndarray (3, 3), (3,)
        The fit.
    inliers : ndarray (k,) bool
        The pairs the fit used.
    evidence : Evidence

    Returns
    -------
    str
    """
    inl = np.asarray(inliers, bool) & np.all(np.isfinite(P), -1) & np.all(np.isfinite(Q), -1)
    n = int(inl.sum())
    if n < evidence.min_inliers:
        return f"evidence: {n} inlier pairs, fewer than {evidence.min_inliers}"
    q = Q[inl]
    ev = np.linalg.eigvalsh(spread_information(q))
    cond = float(ev[-1] / ev[0]) if ev[0] > 0 else float("inf")
    if not cond <= evidence.max_condition:
        return f"evidence: inlier geometry condition number {cond:.3g} above {evidence.max_condition:g}"
    r = q - P[inl] @ R.T - t
    C = cov_Q[inl] + R @ cov_P[inl] @ R.T
    try:
        cost = float(np.sum(r * np.linalg.solve(C, r[..., None])[..., 0]))
    except np.linalg.LinAlgError:
        return "evidence: singular point covariances"
    dof = 3 * n - 6
    lim = float(chi2.ppf(evidence.residual_probability, dof))
    if not cost <= lim:
        return f"evidence: residual chi2 {cost:.4g} above {lim:.4g} ({dof} dof)"
    return ""
