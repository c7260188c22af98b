"""Matching observed TOF key points to the model markers from distance consistency (paper 000 §3).

* :func:`match_markers_mrf` — mean-field deterministic annealing with the null label in the
  corrected form (flags P000-6..9, docs/papers.md#p000-6): four-index mismatch
  ``ρ_klij = d̃_kl − d_ij``, row-wise softmax over the labels, iteration to a fixed point at every
  temperature (damped, because undamped synchronous sweeps oscillate), optional Sinkhorn
  (softassign) normalisation, and a *truncated* pair potential ``min(ρ², (τα)²)`` (this project's
  robustification: with the paper's unbounded ``ρ²`` one spurious point outweighs every consistent
  pair and drives the field to the all-null state, see ``docs/tof.md``);
* :func:`match_markers_mrf_literal` — the paper's printed schedule (one sweep per temperature,
  unbounded ``ρ²``) for comparison;
* :func:`match_markers_hungarian` — a baseline: a robust distance-profile cost per
  (observation, model) pair and ``scipy.optimize.linear_sum_assignment`` with null columns;
* :func:`verify_labels` — a pose check of the labels (spurious points survive the matcher, so the
  match is checked against the SVD pose residual): triple consensus, re-solve, and re-assignment of
  every observation to the nearest predicted marker (Hungarian, gated).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linear_sum_assignment

from chaser.tof.pose import weighted_svd_pose

__all__ = [
    "MatchSettings",
    "LITERAL_SETTINGS",
    "MarkerMatch",
    "match_markers_mrf",
    "match_markers_mrf_literal",
    "match_markers_hungarian",
    "verify_labels",
]


@dataclass(frozen=True)
class MatchSettings:
    """Settings of the MRF deterministic-annealing matcher (000 §3; 000 gives no values, see ``docs/tof.md``).

    Attributes
    ----------
    alpha_m : float
        α, the distance-consistency threshold (3–5 × the 3-D point noise).
    truncation : float or None
        τ of the truncated pair potential ``min(ρ², (τα)²)``; None is the paper's ``ρ²``.
    beta0, beta_max : float
        Start and end inverse temperature, in units of ``1/α²``.
    rate : float
        Annealing rate ``c`` of eq (23), ``β ← c β``.
    damping : float
        Fraction of the new field taken per sweep, ``A ← (1−λ) A + λ softmax(·)`` (1 = undamped).
    tol : float
        Fixed point reached at a temperature when ``max |ΔA| < tol``.
    max_sweeps : int
        Sweeps per temperature at most (1 = the paper's single sweep).
    sinkhorn : bool
        Alternate row/column normalisation with a slack row and column (softassign).
    sinkhorn_iterations : int
    """

    alpha_m: float = 0.010
    truncation: float | None = 2.0
    beta0: float = 1e-3
    beta_max: float = 1e2
    rate: float = 1.2
    damping: float = 0.5
    tol: float = 1e-3
    max_sweeps: int = 50
    sinkhorn: bool = False
    sinkhorn_iterations: int = 20

    def __post_init__(self) -> None:
        for key in ("alpha_m", "beta0", "beta_max", "tol"):
            v = getattr(self, key)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{key}: must be finite and > 0, got {v!r}")
        if self.truncation is not None and (not np.isfinite(self.truncation) or self.truncation <= 1):
            raise ValueError(f"truncation: must be None or > 1, got {self.truncation!r}")
        if not self.rate > 1:
            raise ValueError(f"rate: must be > 1, got {self.rate!r}")
        if not 0 < self.damping <= 1:
            raise ValueError(f"damping: must lie in (0, 1], got {self.damping!r}")
        if int(self.max_sweeps) != self.max_sweeps or self.max_sweeps < 1:
            raise ValueError(f"max_sweeps: must be an integer >= 1, got {self.max_sweeps!r}")


#: The paper's schedule: one undamped sweep per temperature, unbounded ρ² potential.
LITERAL_SETTINGS = MatchSettings(truncation=None, beta0=1e-4, rate=1.1, damping=1.0, max_sweeps=1)


@dataclass(frozen=True)
class MarkerMatch:
    """Labels of the observed key points.

    Attributes
    ----------
    labels : (..., n) int ndarray
        Model index of every observation, −1 for the null label (no model counterpart).
    assignment : (..., n, q+1) ndarray
        The matrix ``A`` of eq (22) (column 0 = null); for the Hungarian baseline, the 0/1 assignment.
    n_temperatures, n_sweeps : int
        Temperatures visited and total fixed-point sweeps (0 for the Hungarian baseline).
    method : str
    """

    labels: np.ndarray
    assignment: np.ndarray
    n_temperatures: int
    n_sweeps: int
    method: str


def _check_points(model_C: ArrayLike, points_S: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    m = np.asarray(model_C, dtype=float)
    if m.ndim != 2 or m.shape[1] != 3 or len(m) < 3 or not np.all(np.isfinite(m)):
        raise ValueError(f"model_C: expected a finite (q >= 3, 3) array, got shape {m.shape}")
    p = np.asarray(points_S, dtype=float)
    if p.ndim < 2 or p.shape[-1] != 3 or not np.all(np.isfinite(p)):
        raise ValueError(f"points_S: expected a finite (..., n, 3) array, got shape {p.shape}")
    return m, p


def _pair_energy(model_C: np.ndarray, points_S: np.ndarray, alpha: float, truncation: float | None) -> np.ndarray:
    """``W[..., k, i, l, j] = V(ρ_klij) − α²`` reshaped to ``(..., n q, n q)`` (flag P000-6)."""
    q = len(model_C)
    n = points_S.shape[-2]
    dm = np.linalg.norm(model_C[:, None] - model_C[None], axis=-1)                       # (q, q)
    do = np.linalg.norm(points_S[..., :, None, :] - points_S[..., None, :, :], axis=-1)  # (..., n, n)
    rho2 = (do[..., :, :, None, None] - dm) ** 2                                           # (..., k, l, i, j)
    if truncation is not None:
        rho2 = np.minimum(rho2, (truncation * alpha) ** 2)
    w = rho2 - alpha**2
    w = np.swapaxes(w, -3, -2)                                                              # (..., k, i, l, j)
    return w.reshape(points_S.shape[:-2] + (n * q, n * q))


def _anneal(model_C: np.ndarray, points_S: np.ndarray, st: MatchSettings) -> tuple[np.ndarray, int, int]:
    """Mean-field annealing of eqs (19), (23)–(26) corrected; returns ``(A, n_temperatures, n_sweeps)``."""
    q = len(model_C)
    batch = points_S.shape[:-2]
    n = points_S.shape[-2]
    alpha = st.alpha_m
    W = _pair_energy(model_C, points_S, alpha, st.truncation)
    A = np.full(batch + (n, q + 1), 1.0 / (q + 1))
    beta = st.beta0 / alpha**2
    beta_end = st.beta_max / alpha**2
    n_t = n_s = 0
    while beta < beta_end:
        n_t += 1
        for _ in range(int(st.max_sweeps)):
            n_s += 1
            # E[k, i] = Σ_l Σ_j W[k,i,l,j] A[l,j]  (the null label's energy is 0: eq 19/24)
            e = (W @ A[..., 1:].reshape(batch + (n * q, 1))).reshape(batch + (n, q))
            logits = np.concatenate([np.zeros(batch + (n, 1)), -beta * e], axis=-1)
            logits -= logits.max(axis=-1, keepdims=True)
            F = np.exp(logits)
            new = _sinkhorn(F, st.sinkhorn_iterations) if st.sinkhorn else F / F.sum(-1, keepdims=True)
            new = (1.0 - st.damping) * A + st.damping * new
            delta = float(np.abs(new - A).max()) if new.size else 0.0
            A = new
            if delta < st.tol:
                break
        if A.size and float((1.0 - A.max(axis=-1)).max()) < 1e-3:
            break
        beta *= st.rate
    return A, n_t, n_s


def _sinkhorn(F: np.ndarray, iterations: int) -> np.ndarray:
    """Softassign: alternate row (observations, over labels 0..q) and column (model 1..q)
    normalisation with a slack row for unmatched model markers; returns row-stochastic A."""
    n = F.shape[-2]
    M = np.concatenate([F, np.ones(F.shape[:-2] + (1, F.shape[-1]))], axis=-2)
    M[..., n, 0] = 0.0
    for _ in range(iterations):
        M[..., :n, :] /= M[..., :n, :].sum(-1, keepdims=True)
        M[..., :, 1:] /= M[..., :, 1:].sum(-2, keepdims=True)
    A = M[..., :n, :]
    return A / A.sum(-1, keepdims=True)


def _decode(A: np.ndarray) -> np.ndarray:
    """Labels from ``A`` (flag P000-8: the label of row k is its arg max over 0..q), null when
    the winning probability is below ½, and one observation per model marker (the most probable)."""
    lab = A.argmax(axis=-1) - 1
    best = A.max(axis=-1)
    lab = np.where(best < 0.5, -1, lab)
    flat_lab = lab.reshape(-1, lab.shape[-1])
    flat_best = best.reshape(-1, lab.shape[-1])
    for row, pb in zip(flat_lab, flat_best, strict=True):
        for i in np.unique(row[row >= 0]):
            who = np.flatnonzero(row == i)
            if who.size > 1:
                row[who[who != who[np.argmax(pb[who])]]] = -1
    return flat_lab.reshape(lab.shape)


def match_markers_mrf(model_C: ArrayLike, points_S: ArrayLike, *, settings: MatchSettings | None = None) -> MarkerMatch:
    """MRF mean-field deterministic-annealing matcher with the null label, corrected (000 §3).

    Energies (flag P000-6): ``E_ki = Σ_l Σ_{j≥1} A_lj (V(ρ_klij) − α²)`` for labels ``i ≥ 1`` and
    ``E_k0 = 0``, with ``ρ_klij = d̃_kl − d_ij`` (eqs 13–14) and ``V = min(ρ², (τα)²)`` (τ =
    ``settings.truncation``; ``None`` gives the paper's ``ρ²``); the ``l = k`` terms are kept.
    Update (flag P000-7): row-wise softmax ``A_ki ∝ exp(−β E_ki)`` over ``i = 0..q`` (optionally
    Sinkhorn), iterated to a fixed point at every β (flag P000-9), then ``β ← c β`` (eq 23) from
    ``β0/α²`` to ``β_max/α²``.  Decoding: flag P000-8.

    Parameters
    ----------
    model_C : (q, 3) array_like
        Model marker positions in frame C (m).
    points_S : (..., n, 3) array_like
        Observed key points in frame S (m); leading axes are independent problems (vectorised).
    settings : MatchSettings, optional

    Returns
    -------
    MarkerMatch
    """
    m, p = _check_points(model_C, points_S)
    st = settings or MatchSettings()
    A, n_t, n_s = _anneal(m, p, st)
    return MarkerMatch(_decode(A), A, n_t, n_s, "mrf" + ("-sinkhorn" if st.sinkhorn else ""))


def match_markers_mrf_literal(model_C: ArrayLike, points_S: ArrayLike, *, alpha_m: float = 0.010) -> MarkerMatch:
    """The paper's matcher as printed, made executable (for comparison).

    Kept from the paper: the unbounded potential ``ρ²``, a single synchronous sweep per temperature
    (eq 24 uses ``A^(m−1)``), the schedule of eqs (23), (26).  Changed only where the printed text
    cannot be executed: the four-index ``ρ_klij`` (the printed ``ρ_kij`` has no ``l``, P000-6) and
    the row normaliser of eq (25) (the printed ``Σ_k F_kk`` is a diagonal that does not exist for
    ``n ≠ q``, P000-7).
    """

    st = replace(LITERAL_SETTINGS, alpha_m=alpha_m)
    m, p = _check_points(model_C, points_S)
    A, n_t, n_s = _anneal(m, p, st)
    return MarkerMatch(_decode(A), A, n_t, n_s, "mrf-literal")


def match_markers_hungarian(model_C: ArrayLike, points_S: ArrayLike, *, alpha_m: float = 0.010,
                            truncation: float = 2.0) -> MarkerMatch:
    """Baseline: linear assignment on distance-matrix consistency.

    Cost of observation k taking model label i: ``C_ki = Σ_{l≠k} min(min_{j≠i} |d̃_kl − d_ij|, τα)``
    (how badly k's distances to the other observations fit i's distances to the other markers,
    each term capped); ``n`` null columns cost ``½ (n − 1) τ α`` each.  Solved by
    ``scipy.optimize.linear_sum_assignment`` per problem.
    """
    m, p = _check_points(model_C, points_S)
    q = len(m)
    n = p.shape[-2]
    cap = truncation * alpha_m
    dm = np.linalg.norm(m[:, None] - m[None], axis=-1)
    dm_off = np.where(np.eye(q, dtype=bool), np.inf, dm)                                    # exclude j = i
    do = np.linalg.norm(p[..., :, None, :] - p[..., None, :, :], axis=-1)                   # (..., n, n)
    gap = np.abs(do[..., :, :, None, None] - dm_off).min(axis=-1)                           # (..., k, l, i)
    gap = np.minimum(gap, cap)
    off = ~np.eye(n, dtype=bool)
    cost = (gap * off[..., :, :, None]).sum(axis=-2)                                        # (..., k, i)
    null_cost = 0.5 * max(n - 1, 1) * cap
    flat = cost.reshape(-1, n, q)
    labels = np.full(flat.shape[:2], -1, dtype=int)
    A = np.zeros(flat.shape[:2] + (q + 1,))
    for b, c in enumerate(flat):
        full = np.concatenate([c, np.full((n, n), null_cost)], axis=1)
        rows, cols = linear_sum_assignment(full)
        lab = np.where(cols < q, cols, -1)
        labels[b, rows] = lab
        A[b, rows, lab + 1] = 1.0
    return MarkerMatch(labels.reshape(p.shape[:-1]), A.reshape(p.shape[:-1] + (q + 1,)), 0, 0, "hungarian")



def verify_labels(model_C: ArrayLike, points_S: ArrayLike, labels: ArrayLike, *, gate_m: float) -> np.ndarray:
    """Pose check of a labelling (after 000 §3, by the SVD pose of 000 §4): consensus, re-solve, re-assign.

    Among the labelled observations, every triple of matches gives a pose
    (:func:`weighted_svd_pose`, all triples in one batch); the pose that brings the most labelled
    observations within ``gate_m`` of their markers wins (ties: smallest summed residual), and is
    refitted on those inliers.  Every observation is then assigned to the predicted markers by
    linear assignment on the 3-D distance, keeping pairs closer than ``gate_m``: this drops
    spurious points that took a label, repairs swapped labels and recovers markers the matcher
    left null.  Fewer than three consistent matches: all null.

    Parameters
    ----------
    model_C : (q, 3) array_like
    points_S : (..., n, 3) array_like
    labels : (..., n) int array_like
    gate_m : float

    Returns
    -------
    (..., n) int ndarray of verified labels (−1 = null).
    """

    m, p = _check_points(model_C, points_S)
    lab_in = np.asarray(labels, dtype=int)
    if lab_in.shape != p.shape[:-1]:
        raise ValueError(f"labels: expected shape {p.shape[:-1]}, got {lab_in.shape}")
    if not np.isfinite(gate_m) or gate_m <= 0:
        raise ValueError(f"gate_m: must be finite and > 0, got {gate_m!r}")
    n = p.shape[-2]
    flat_p = p.reshape(-1, n, 3)
    flat_l = lab_in.reshape(-1, n)
    out = np.full_like(flat_l, -1)
    for b in range(len(flat_p)):
        idx = np.flatnonzero(flat_l[b] >= 0)
        if idx.size < 3:
            continue
        obs, mod = flat_p[b, idx], m[flat_l[b, idx]]
        tri = np.array(list(combinations(range(idx.size), 3)))
        fits = weighted_svd_pose(mod[tri], obs[tri])
        pred = np.einsum("tij,mj->tmi", fits.R_SC, mod) + fits.r_CS_S[:, None, :]
        res = np.linalg.norm(pred - obs, axis=-1)                                   # (triples, m)
        inl = res <= gate_m
        proper = fits.singular_values[:, 1] > 1e-6 * fits.singular_values[:, 0]
        score = np.where(proper, inl.sum(-1) - np.where(inl, res, 0).sum(-1) / (gate_m * idx.size + 1e-300), -1)
        best = int(np.argmax(score))
        keep = inl[best]
        if keep.sum() < 3 or not proper[best]:
            continue
        fit = weighted_svd_pose(mod[keep], obs[keep])
        pred = m @ fit.R_SC.T + fit.r_CS_S
        dist = np.linalg.norm(flat_p[b, :, None, :] - pred[None], axis=-1)
        rows, cols = linear_sum_assignment(np.where(dist <= gate_m, dist, 1e6 * gate_m))
        ok = dist[rows, cols] <= gate_m
        if ok.sum() >= 3:
            out[b, rows[ok]] = cols[ok]
    return out.reshape(lab_in.shape)
