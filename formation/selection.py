"""Observer selection over time: the best feasible k-subset at each epoch, with hysteresis.

At every epoch all k-subsets of the N candidates are scored at once (vectorised over epochs and
subsets); a subset is feasible when each member passes its own constraints and every pair passes the
pairwise ones (:mod:`formation.constraints`).  The active set changes only when it stops being
feasible or when another feasible subset predicts an error smaller by more than the hysteresis
fraction, so it does not flicker between near-equal subsets.

Quality: by default the geometric dilution of precision of a point at the target's centre,
``σ_p² = tr(Λ⁻¹)`` with ``Λ = Σ_i (I − b_i b_iᵀ) / (σ_θ d_i)²`` (each camera at range ``d_i`` with
line of sight ``b_i`` measures the two directions across it with angular noise ``σ_θ``); lower is
better.  Any other predictor, such as the Cramér–Rao bound of the attitude increment
(``reconstruction.accuracy``), can be passed as ``score_fn``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike

from formation.constraints import PAIRWISE, ConstraintEvaluation

__all__ = ["SelectionTimeline", "point_dop", "select_observers"]


def point_dop(r_ST_H: ArrayLike, *, angular_sigma_rad: float = 1.0) -> np.ndarray:
    """Position standard deviation (m) of a triangulated point at the target centre.

    ``r_ST_H (..., k, 3)`` → ``(...)``; ``inf`` when the cameras cannot triangulate (k < 2 or
    collinear lines of sight).
    """
    r = np.asarray(r_ST_H, dtype=float)
    d = np.linalg.norm(r, axis=-1)
    b = r / d[..., None]
    P = np.eye(3) - b[..., :, None] * b[..., None, :]
    Lam = np.sum(P / (angular_sigma_rad * d[..., None, None]) ** 2, axis=-3)
    ev = np.linalg.eigvalsh(Lam)
    with np.errstate(divide="ignore"):
        var = np.where(ev[..., 0] > 1e-12 * ev[..., -1], np.sum(1.0 / np.maximum(ev, 1e-300), -1), np.inf)
    return np.sqrt(var)


@dataclass(frozen=True)
class SelectionTimeline:
    """Active observers over time.

    Attributes
    ----------
    active : (T, N) bool ndarray
        Membership of each candidate in the active set at each epoch.
    subset : (T, k) int ndarray
        Indices of the active set (−1 entries where fewer than k are feasible).
    score : (T,) ndarray
        Predicted error of the active set (``score_fn`` units; inf where none is feasible).
    n_feasible : (T,) int ndarray
        Number of feasible k-subsets at each epoch.
    switches : int
        Number of changes of the active set.
    excluded : list[dict[int, str]]
        Per epoch, for each inactive candidate, why it was excluded.
    """

    active: np.ndarray
    subset: np.ndarray
    score: np.ndarray
    n_feasible: np.ndarray
    switches: int
    excluded: list[dict[int, str]]

    @property
    def short(self) -> np.ndarray:
        """(T,) bool: epochs where no k-subset satisfies the constraints."""
        return self.n_feasible == 0


def select_observers(
    evaluation: ConstraintEvaluation,
    r_ST_H: ArrayLike,
    k: int,
    *,
    score_fn: Callable[[np.ndarray], np.ndarray] | None = None,
    hysteresis: float = 0.1,
) -> SelectionTimeline:
    """Choose a k-subset at each epoch.

    Parameters
    ----------
    evaluation : ConstraintEvaluation
        From :func:`formation.constraints.evaluate` on ``r_ST_H``; margins ``(T, N)``/``(T, N, N)``.
    r_ST_H : (T, N, 3) array_like
        Candidate positions relative to the target, H, m.
    k : int
        Number of observers wanted.
    score_fn : callable, optional
        Maps positions ``(T, S, k, 3)`` of every subset to predicted errors ``(T, S)`` (lower is
        better); default :func:`point_dop`.
    hysteresis : float
        Keep the current set unless the best feasible one is better by more than this fraction.
    """
    r = np.asarray(r_ST_H, dtype=float)
    if r.ndim != 3 or r.shape[-1] != 3:
        raise ValueError(f"r_ST_H: expected shape (T, N, 3), got {r.shape}")
    T, N, _ = r.shape
    if not 1 <= k <= N:
        raise ValueError(f"k: must be between 1 and the number of candidates {N}, got {k!r}")
    if hysteresis < 0:
        raise ValueError(f"hysteresis: must be >= 0, got {hysteresis!r}")
    subsets = np.array(list(combinations(range(N), k)), dtype=int)  # (S, k)
    single = evaluation.single_ok  # (T, N)
    pair = evaluation.pair_ok  # (T, N, N)
    feas = np.all(single[:, subsets], axis=-1) & np.all(
        pair[:, subsets[:, :, None], subsets[:, None, :]], axis=(-1, -2))  # (T, S)
    pos = r[:, subsets]  # (T, S, k, 3)
    scores = (score_fn or point_dop)(pos)
    scores = np.where(feas, scores, np.inf)

    active = np.zeros((T, N), dtype=bool)
    chosen = np.full((T, k), -1, dtype=int)
    score = np.full(T, np.inf)
    current: int | None = None
    switches = 0
    for t in range(T):
        best = int(np.argmin(scores[t]))
        if not np.isfinite(scores[t, best]):
            nxt = None
        elif current is not None and np.isfinite(scores[t, current]) and \
                scores[t, current] <= (1.0 + hysteresis) * scores[t, best]:
            nxt = current
        else:
            nxt = best
        if nxt != current and current is not None and nxt is not None:
            switches += 1
        if nxt is not None:
            current = nxt
            chosen[t] = subsets[nxt]
            active[t, subsets[nxt]] = True
            score[t] = scores[t, nxt]
        else:
            current = None
    # why the others are out: Python lists, so the per-candidate checks cost no numpy call
    single_l, active_l, short_l = single.tolist(), active.tolist(), (chosen[:, 0] < 0).tolist()
    excluded = [_exclusion_reasons(evaluation, t, active_l[t], single_l[t], pair[t], short_l[t], k)
                for t in range(T)]
    return SelectionTimeline(active=active, subset=chosen, score=score, n_feasible=feas.sum(-1),
                             switches=switches, excluded=excluded)


def _exclusion_reasons(ev: ConstraintEvaluation, t: int, active: list[bool], single: list[bool],
                       pair: np.ndarray, none_feasible: bool, k: int) -> dict[int, str]:
    out: dict[int, str] = {}
    members = [j for j, a in enumerate(active) if a]
    alone = [j for j, ok in enumerate(single) if ok]
    pair_l = None
    fails: dict[str, list] = {}

    def names(i, js):
        if not fails:
            fails.update({name: (ev.margins[name][t] < 0).tolist() for name in PAIRWISE})
        return "/".join(name for name in PAIRWISE if any(fails[name][i][j] for j in js))

    for i, a in enumerate(active):
        if a:
            continue
        if not single[i]:
            own = ev.reasons((t,), i)
            if own:
                out[i] = "; ".join(own)
                continue
        if pair_l is None:
            pair_l = pair.tolist()
        bad = [j for j in members if not pair_l[i][j]]
        if bad:
            out[i] = f"pairwise {names(i, bad)} with {bad}"
        elif none_feasible:
            clash = [j for j in alone if j != i and not pair_l[i][j]]
            if clash:
                out[i] = f"no feasible set of the wanted size (pairwise {names(i, clash)} with {clash})"
            elif len(alone) < k:
                out[i] = (f"no feasible set of the wanted size (only {len(alone)} candidates pass "
                          "their own constraints)")
            else:
                out[i] = "no feasible set of the wanted size (pairwise conflicts among the others)"
        else:
            out[i] = "feasible but lower predicted quality"
    return out
