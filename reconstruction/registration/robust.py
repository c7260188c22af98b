"""Robust rigid fit: minimal 3-point RANSAC with a chi-square gate, then weighted Kabsch refits.

The consensus check of flag P003-6 (docs/papers.md#p003-6): a correspondence is an inlier when its
residual passes the chi-square gate ``rᵀ (C_Q + R C_P Rᵀ)⁻¹ r < χ²₃(p)`` (point covariances
given) or a Euclidean threshold.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from reconstruction._geometry import (
    check_positive,
    check_probability,
    chi2_quantile,
    scalar_or_array,
)
from reconstruction.registration.kabsch import check_second_moments, kabsch_flat, prepare_clouds
from reconstruction.registration.residuals import (
    check_covariance_pair,
    mahalanobis2,
    residual_information,
    residual_rms,
)
from reconstruction.registration.result import KABSCH_REASONS, RigidRegistration

__all__ = ["fit_rigid_robust"]


def fit_rigid_robust(P: ArrayLike, Q: ArrayLike, *, weights: ArrayLike | None = None,
                     cov_P: ArrayLike | None = None, cov_Q: ArrayLike | None = None,
                     threshold_m: float | None = None,
                     gate_probability: float = 0.9973, max_iterations: int = 1000,
                     confidence: float = 0.999, refits: int = 3,
                     rng: np.random.Generator | int | None = None) -> RigidRegistration:
    """Minimal 3-point RANSAC for ``Q ≈ R P + t``, then weighted Kabsch refits on the inliers.

    Hypotheses are drawn in batches over all problems at once; each problem stops contributing
    once the standard bound ``log(1 − confidence) / log(1 − ε³)`` (ε: its best inlier ratio) is met.
    A correspondence is an inlier when its residual passes the gate: the chi-square gate
    ``rᵀ (C_Q + R C_P Rᵀ)⁻¹ r < χ²₃(gate_probability)`` when the point covariances are given
    (right for the anisotropic triangulation errors), else ``‖r‖ < threshold_m``.

    Parameters
    ----------
    P, Q : array_like (..., N, 3)
        Matched clouds, m; NaN rows are ignored.
    weights : array_like (..., N), optional
        Weights of the refits (003 eq 12).
    cov_P, cov_Q : array_like (..., N, 3, 3), optional
        Per-point covariances, m² (both or neither): symmetric positive semi-definite, at each
        point at least one positive definite, NaN for an absent point
        (:func:`reconstruction.registration.residuals.check_covariance_pair`).
    threshold_m : float, optional
        Euclidean inlier threshold, m; required when no covariances are given.
    gate_probability : float
        Chi-square gate probability (with covariances).
    max_iterations : int
        Maximum hypotheses per problem.
    confidence : float
        Probability that an all-inlier sample was drawn.
    refits : int
        Inlier re-selection / refit rounds after the best hypothesis (local optimisation).
    rng : numpy.random.Generator or int or None
        Random source.

    Returns
    -------
    RigidRegistration
        ``method="ransac"``; ``chi2`` is filled when covariances are given, ``cov`` is NaN.
    """
    P, Q, w = prepare_clouds(P, Q, weights)
    batch, N = P.shape[:-2], P.shape[-2]
    B = int(np.prod(batch, dtype=np.int64))
    covs = check_covariance_pair(cov_P, cov_Q, P.shape)
    if covs is None and threshold_m is None:
        raise ValueError("threshold_m: required when cov_P and cov_Q are not given")
    if threshold_m is not None:
        threshold_m = float(check_positive(threshold_m, "threshold_m"))
    gate_probability = check_probability(gate_probability, "gate_probability")
    confidence = check_probability(confidence, "confidence")
    if int(max_iterations) < 1:
        raise ValueError(f"max_iterations: must be >= 1, got {max_iterations!r}")
    rng = np.random.default_rng(rng)
    gate2 = chi2_quantile(gate_probability, 3) if covs is not None else threshold_m**2

    Pf = P.reshape((B, N, 3))
    Qf = Q.reshape((B, N, 3))
    wf = np.ones((B, N)) if w is None else w.reshape((B, N))
    valid = np.all(np.isfinite(Pf), -1) & np.all(np.isfinite(Qf), -1) & (wf > 0)
    if covs is not None:
        cPf = np.broadcast_to(covs[0], P.shape + (3,)).reshape((B, N, 3, 3))
        cQf = np.broadcast_to(covs[1], P.shape + (3,)).reshape((B, N, 3, 3))
        valid &= np.all(np.isfinite(cPf), (-2, -1)) & np.all(np.isfinite(cQf), (-2, -1))
    Pz = np.where(valid[..., None], Pf, 0.0)
    Qz = np.where(valid[..., None], Qf, 0.0)
    check_second_moments(Pz, Qz, None if w is None else np.where(valid, wf, 0.0))
    nvalid = np.sum(valid, -1)

    def score(R: np.ndarray, t: np.ndarray, sel: np.ndarray) -> np.ndarray:
        """Inlier mask of problems ``sel`` under hypotheses R (b, H, 3, 3), t (b, H, 3)."""
        out = np.empty((len(sel), R.shape[1], N), bool)
        step = max(1, 200_000 // (R.shape[1] * max(N, 1)))
        for a in range(0, len(sel), step):
            s, Ra, ta = sel[a:a + step], R[a:a + step], t[a:a + step]
            r = Qz[s][:, None] - Pz[s][:, None] @ np.swapaxes(Ra, -1, -2) - ta[..., None, :]
            if covs is None:
                d2 = np.sum(r * r, -1)
            else:
                d2 = mahalanobis2(r, residual_information(Ra, cPf[s][:, None], cQf[s][:, None]))
            out[a:a + step] = (d2 < gate2) & valid[s][:, None]
        return out

    best_count = np.zeros(B, dtype=int)
    best_R = np.full((B, 3, 3), np.nan)
    best_t = np.full((B, 3), np.nan)
    done = np.zeros(B, dtype=int)
    need = np.full(B, int(max_iterations))
    need[nvalid < 3] = 0
    H = 16
    while True:
        active = np.nonzero(done < need)[0]
        if active.size == 0:
            break
        keys = rng.random((active.size, H, N))
        keys[~np.broadcast_to(valid[active][:, None, :], keys.shape)] = 2.0
        idx = np.argpartition(keys, 2, axis=-1)[..., :3]
        ar = active[:, None, None]
        p3 = Pz[ar, idx]
        q3 = Qz[ar, idx]
        R, t, code, *_ = kabsch_flat(p3.reshape(-1, 3, 3), q3.reshape(-1, 3, 3), None)
        R = R.reshape(active.size, H, 3, 3)
        t = t.reshape(active.size, H, 3)
        good_h = (code == 0).reshape(active.size, H)
        inl = score(np.nan_to_num(R), np.nan_to_num(t), active)
        cnt = np.where(good_h, np.sum(inl, -1), -1)
        h = np.argmax(cnt, axis=-1)
        c = cnt[np.arange(active.size), h]
        better = c > best_count[active]
        ab = active[better]
        best_count[ab] = c[better]
        best_R[ab] = R[better, h[better]]
        best_t[ab] = t[better, h[better]]
        done[active] += H
        eps = best_count[active] / np.maximum(nvalid[active], 1)
        with np.errstate(divide="ignore"):
            k = np.log(1.0 - confidence) / np.log(np.clip(1.0 - eps**3, 1e-300, 1.0 - 1e-16))
        need[active] = np.minimum(need[active], np.maximum(np.ceil(k), H).astype(int))
        need[active] = np.maximum(need[active], 0)

    # local optimisation: refit on the consensus set, re-select inliers
    found = best_count >= 3
    R, t = best_R, best_t
    inl = np.zeros((B, N), bool)
    if np.any(found):
        sel = np.nonzero(found)[0]
        Rs, ts = R[sel], t[sel]
        m = score(Rs[:, None], ts[:, None], sel)[:, 0]
        for _ in range(max(int(refits), 0)):
            Rn, tn, code, *_ = kabsch_flat(Pz[sel], Qz[sel], np.where(m, wf[sel], 0.0))
            okr = code == 0
            Rs = np.where(okr[:, None, None], Rn, Rs)
            ts = np.where(okr[:, None], tn, ts)
            m_new = score(Rs[:, None], ts[:, None], sel)[:, 0]
            stable = np.array_equal(m_new, m)
            m = m_new
            if stable:
                break
        R = R.copy()
        t = t.copy()
        R[sel], t[sel], inl[sel] = Rs, ts, m
    n_in = np.sum(inl, -1)
    ok = found & (n_in >= 3)
    reason = np.where(nvalid < 3, KABSCH_REASONS[1],
                      np.where(~ok, "no consensus set of 3 or more inliers", ""))
    R = np.where(ok[:, None, None], R, np.nan)
    t = np.where(ok[:, None], t, np.nan)
    inl &= ok[:, None]
    rms = residual_rms(Pz, Qz, np.nan_to_num(R), np.nan_to_num(t), inl)
    if covs is not None:
        r = Qz - Pz @ np.swapaxes(np.nan_to_num(R), -1, -2) - np.nan_to_num(t)[:, None, :]
        Winv = residual_information(np.nan_to_num(R), np.where(valid[..., None, None], cPf, 0),
                                 np.where(valid[..., None, None], cQf, 0))
        chi2 = np.sum(np.where(inl, mahalanobis2(r, np.nan_to_num(Winv)), 0.0), -1)
        chi2 = np.where(ok, chi2, np.nan)
    else:
        chi2 = np.full(B, np.nan)
    return RigidRegistration(
        R=R.reshape(batch + (3, 3)), t=t.reshape(batch + (3,)),
        cov=np.full(batch + (6, 6), np.nan), inliers=inl.reshape(batch + (N,)),
        n_inliers=n_in.reshape(batch), rms_m=np.where(ok, rms, np.nan).reshape(batch),
        chi2=chi2.reshape(batch), dof=(3 * n_in - 6).reshape(batch),
        ok=scalar_or_array(ok.reshape(batch)), failure_reason=scalar_or_array(reason.reshape(batch)),
        method="ransac",
    )


