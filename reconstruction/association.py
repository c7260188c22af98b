"""Inter-frame association of triangulated tracks (003 eq (9)–(10)).

Between epochs t and t + Δt, each camera in turn is the *primary*: its features are matched
across the two epochs by descriptor (nearest neighbour with the ratio test of 003's intra-frame
match criterion, λ = 0.6), and a match is kept only if it is *consistent in the auxiliary views*: in every other
view that sees the track at both epochs, the same descriptor match must hold.  The matches of all
primaries are merged (pairs claimed inconsistently by two primaries are dropped), the camera
weights are updated by 003 eq (9) normalised per flag P003-5 (docs/papers.md#p003-5), and near-duplicate correspondences
are removed by the per-epoch AND test of flag P003-6 (docs/papers.md#p003-6), keeping the one with the smaller residual.

Descriptor matching is a brute-force L2 nearest-neighbour search (the selection of
``cv2.BFMatcher.knnMatch``, with distances exact in double precision: a compiled kernel,
:mod:`reconstruction._knn_kernel`, returning arrays); with one descriptor per track a single
search serves all views.  The consistency check, the merge and the
bookkeeping are numpy index-array operations over all tracks at once.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from reconstruction._geometry import as_float, check_positive

if TYPE_CHECKING:
    from reconstruction.triangulation import Triangulation
    from vision.observation import Observation

__all__ = ["Association", "camera_weights_from_counts", "associate", "associate_pairs",
           "associate_from_observations", "associate_observation_pairs"]


@dataclass(frozen=True)
class Association:
    """Track correspondences between two epochs.

    Attributes
    ----------
    idx_prev, idx_next : ndarray (K,) int
        Matched track indices at t and t + Δt (``X_prev[idx_prev[k]] ↔ X_next[idx_next[k]]``).
    n_per_primary : ndarray (n,) int
        N_ρ,k of 003 eq (9): consistent matches found with camera k as primary.
    camera_weights : ndarray (n,)
        W_k of 003 eq (9) with flag P003-5 (sums to 1); use them at the next frame pair.
    n_conflicts_removed : int
        Pairs dropped because two primaries disagreed.
    n_duplicates_removed : int
        Pairs dropped as near-duplicates (flag P003-6).
    ok : bool
        At least 3 correspondences (the minimum of a rigid fit, flag P003-8, docs/papers.md#p003-8).
    failure_reason : str
    """

    idx_prev: np.ndarray
    idx_next: np.ndarray
    n_per_primary: np.ndarray
    camera_weights: np.ndarray
    n_conflicts_removed: int
    n_duplicates_removed: int
    ok: bool
    failure_reason: str


def camera_weights_from_counts(n_per_primary: ArrayLike) -> np.ndarray:
    """003 eq (9) with flag P003-5 (docs/papers.md#p003-5): ``W_k = (1 + N_ρ,k) / (N_cam + Σ_j N_ρ,j)``; sums to 1.

    Parameters
    ----------
    n_per_primary : array_like (..., n) int
        Points obtained with each camera as primary (before merging).
    """
    N = as_float(n_per_primary, "n_per_primary")
    if N.ndim < 1 or np.any(N < 0) or not np.all(np.isfinite(N)):
        raise ValueError(f"n_per_primary: expected non-negative counts (..., n), got {N!r}")
    return (1.0 + N) / (N.shape[-1] + np.sum(N, -1, keepdims=True))


_K_SHARED = 8  # neighbours kept per track when one descriptor list serves all views


def _knn(d_prev: np.ndarray, d_next: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` nearest rows of ``d_next`` for each row of ``d_prev`` (L2): distances and indices
    (−1 past the last neighbour), nearest first, equal distances in index order.

    :func:`reconstruction._knn_kernel.knn_l2`: a compiled float32 Gram pass picks candidates, their
    distances are then computed exactly (double precision), so the order and the ratio test do not
    depend on the rounding of a float32 sum (``cv2.BFMatcher.knnMatch`` rounds each distance to
    float32; the two agree except where two distances, or a distance ratio and λ, agree to ~1e-7).
    """
    from reconstruction._knn_kernel import knn_l2

    return knn_l2(d_prev, d_next, int(k))


def _ratio_test(dist: np.ndarray, nidx: np.ndarray, ratio: float) -> np.ndarray:
    """Nearest index where both neighbours exist and ``d1 < ratio · d2`` (in double precision, as
    on ``DMatch`` distances), else −1."""
    d = dist.astype(np.float64)
    good = (nidx[:, 0] >= 0) & (nidx[:, 1] >= 0) & (d[:, 0] < ratio * d[:, 1])
    return np.where(good, nidx[:, 0], -1).astype(int)


def _ratio_matches(d_prev: np.ndarray, d_next: np.ndarray, ratio: float) -> np.ndarray:
    """For each row of ``d_prev`` the index of its nearest neighbour in ``d_next`` passing the
    ratio test ``d1 < ratio · d2`` (−1 otherwise); the result of ``cv2.BFMatcher.knnMatch(k=2)`` (see :func:`_knn`)."""
    if len(d_prev) == 0 or len(d_next) < 2:
        return np.full(len(d_prev), -1, dtype=int)
    return _ratio_test(*_knn(d_prev, d_next, 2), ratio)


def _shared_ratio_matches(dp: list, dn: list, vp: list, vn: list, VP: np.ndarray, VN: np.ndarray,
                          off_p: np.ndarray, off_n: np.ndarray, match: np.ndarray, ratio: float) -> None:
    """Per-view ratio-test matches with one descriptor per track, for several pairs of epochs at once.

    Pair ``p`` holds the tracks ``vp[p]`` / ``dp[p]`` at t and ``vn[p]`` / ``dn[p]`` at t + Δt; its
    rows of the stacked views ``VP`` start at ``off_p[p]``, its candidates in ``VN`` at ``off_n[p]``.
    Writes ``match (ΣM, n)``: per view the stacked index of the match at t + Δt, −1 for none.

    Per pair, one ``_K_SHARED``-nearest search over all the tracks seen at each epoch; in view v
    the two nearest candidates seen in v are the first two of them in that list (the list is the
    start of the stable distance order, so ties keep the order of a search over the view's tracks
    alone).  Queries whose full list holds fewer than two of the view's candidates are searched
    again among those candidates only.  The selection over the lists runs for all the pairs in one
    pass; the result is, pair by pair, that of :func:`_ratio_matches` per view.
    """
    n = VP.shape[1]
    rows_all, dist_all, cand_all, full_all = [], [], [], []
    for p in range(len(vp)):
        rows = np.nonzero(vp[p].any(axis=1))[0]
        cols = np.nonzero(vn[p].any(axis=1))[0]
        if rows.size == 0 or cols.size < 2:
            continue
        k = min(_K_SHARED, cols.size)
        dist, nidx = _knn(dp[p][rows], dn[p][cols], k)
        valid = nidx >= 0
        cand = np.full((rows.size, _K_SHARED), -1)                       # stacked indices at t + Δt
        cand[:, :k] = np.where(valid, off_n[p] + cols[np.maximum(nidx, 0)], -1)
        dist_k = np.full((rows.size, _K_SHARED), np.inf)
        dist_k[:, :k] = dist
        rows_all.append(off_p[p] + rows)
        dist_all.append(dist_k)
        cand_all.append(cand)
        full_all.append(valid[:, -1])
    if not rows_all:
        return
    rows, dist, cand, full = (np.concatenate(a) for a in (rows_all, dist_all, cand_all, full_all))
    valid = cand >= 0
    pair = np.searchsorted(off_p, rows, side="right") - 1
    r = np.arange(rows.size)
    for v in range(n):
        q = VP[rows, v]
        inv = valid & VN[np.maximum(cand, 0), v]
        cs = np.cumsum(inv, axis=1)
        has2 = cs[:, -1] >= 2
        p1 = np.argmax(cs >= 1, axis=1)
        p2 = np.argmax(cs >= 2, axis=1)
        d2 = np.stack([dist[r, p1], dist[r, p2]], axis=1)
        i2 = np.stack([np.where(cs[:, -1] >= 1, cand[r, p1], -1), np.where(has2, cand[r, p2], -1)],
                      axis=1)
        m = _ratio_test(d2, i2, ratio)
        again = q & ~has2 & full  # the view's two nearest may lie beyond the list
        use = q & ~again
        match[rows[use], v] = m[use]
        for p in np.unique(pair[again]):
            b = np.nonzero(vn[p][:, v])[0]
            if b.size < 2:
                continue
            a = rows[again & (pair == p)]
            mm = _ratio_matches(dp[p][a - off_p[p]], dn[p][b], ratio)
            match[a, v] = np.where(mm >= 0, off_n[p] + b[np.maximum(mm, 0)], -1)


def _check_views_desc(views, desc, name):
    """Views ``(M, n)`` and descriptors as given: ``(M, D)`` (one per track) or ``(M, n, D)``."""
    v = np.asarray(views, dtype=bool)
    if v.ndim != 2:
        raise ValueError(f"views_{name}: expected shape (n_tracks, n_views), got {v.shape}")
    d = np.asarray(desc)
    if d.dtype != np.float32:
        d = as_float(desc, f"descriptors_{name}")
    if not ((d.ndim == 2 and d.shape[0] == v.shape[0]) or (d.ndim == 3 and d.shape[:2] == v.shape)):
        raise ValueError(f"descriptors_{name}: expected (n_tracks, D) or (n_tracks, n_views, D) "
                         f"matching views {v.shape}, got {np.shape(desc)}")
    return v, d


def associate(views_prev: ArrayLike, descriptors_prev: ArrayLike, views_next: ArrayLike,
              descriptors_next: ArrayLike, *, X_prev: ArrayLike | None = None,
              X_next: ArrayLike | None = None, residual_prev: ArrayLike | None = None,
              residual_next: ArrayLike | None = None, ratio: float = 0.6,
              duplicate_distance_m: float = 0.05, min_matches: int = 3) -> Association:
    """Associate the tracks of two epochs (003 §1.5), with camera weights and de-duplication.

    Parameters
    ----------
    views_prev, views_next : array_like (M, n), (M', n) bool
        Which views see each track at t and t + Δt, e.g. ``tri.views_used & tri.valid[:, None]``.
    descriptors_prev, descriptors_next : array_like (M, D) or (M, n, D)
        One descriptor per track, or one per track and view (then the auxiliary-view check
        compares the auxiliary views' own descriptors).
    X_prev, X_next : array_like (M, 3), (M', 3), optional
        Triangulated points (W, m) for the duplicate test; without them no de-duplication.
    residual_prev, residual_next : array_like (M,), (M',), optional
        Point residuals W_ρ (``Triangulation.rms_reprojection_px``); of two duplicates the one
        with the smaller mean residual (003 eq 13) is kept.  Default: keep the first.
    ratio : float
        Nearest-neighbour ratio λ (003's intra-frame match criterion: 0.6).
    duplicate_distance_m : float
        ε_d of flag P003-6 (docs/papers.md#p003-6): two correspondences closer than this at both
        epochs are duplicates (about twice the triangulation σ: 0.05 m at 50 m).
    min_matches : int
        Fewer correspondences than this give ``ok=False``.

    Returns
    -------
    Association
    """
    vp, dp = _check_views_desc(views_prev, descriptors_prev, "prev")
    vn, dn = _check_views_desc(views_next, descriptors_next, "next")
    if vn.shape[1] != vp.shape[1]:
        raise ValueError(f"views_next: expected {vp.shape[1]} views like views_prev, got {vn.shape}")
    if dp.shape[-1] != dn.shape[-1]:
        raise ValueError(f"descriptors_next: length {dn.shape[-1]} differs from "
                         f"descriptors_prev {dp.shape[-1]}")
    X = None if X_prev is None or X_next is None else [as_float(X_prev, "X_prev"), as_float(X_next, "X_next")]
    res = [None if r is None else as_float(r, name)
           for r, name in ((residual_prev, "residual_prev"), (residual_next, "residual_next"))]
    return _associate_pairs([vp, vn], [dp, dn], [(0, 1)], X, res, ratio, duplicate_distance_m, min_matches)[0]


def associate_pairs(views: Sequence[ArrayLike], descriptors: Sequence[ArrayLike], pairs: Sequence[tuple[int, int]],
                    *, X: Sequence[ArrayLike] | None = None, residual: Sequence[ArrayLike | None] | None = None,
                    ratio: float = 0.6, duplicate_distance_m: float = 0.05,
                    min_matches: int = 3) -> list[Association]:
    """:func:`associate` for several pairs of epochs in one pass (e.g. every step of every trial of a cell).

    Epoch ``e`` holds ``views[e] (M_e, n)``, ``descriptors[e]`` and, optionally, ``X[e] (M_e, 3)``
    and ``residual[e] (M_e,)`` (an entry may be ``None``); pair ``(a, b)`` associates epoch ``a``
    (at t) with epoch ``b`` (at t + Δt).  Result ``p`` is exactly what
    ``associate(views[a], descriptors[a], views[b], descriptors[b], X_prev=X[a], X_next=X[b],
    residual_prev=residual[a], residual_next=residual[b], ...)`` returns: the descriptor searches
    run pair by pair, the selection, consistency check, merge and de-duplication for all the
    pairs together.  Every epoch is checked and converted once, however many pairs it is in.
    """
    checked = [_check_views_desc(v, d, f"[{e}]") for e, (v, d) in enumerate(zip(views, descriptors, strict=True))]
    vs, ds = [c[0] for c in checked], [c[1] for c in checked]
    for a, b in pairs:
        if vs[b].shape[1] != vs[a].shape[1] or ds[b].shape[-1] != ds[a].shape[-1]:
            raise ValueError(f"pairs: epochs {a} and {b} differ in views {vs[a].shape[1]}/{vs[b].shape[1]} "
                             f"or descriptor length {ds[a].shape[-1]}/{ds[b].shape[-1]}")
    if len({vs[a].shape[1] for a, _ in pairs}) > 1:
        raise ValueError("pairs: every pair must have the same number of views (call once per camera set)")
    Xs = None if X is None else [as_float(x, f"X[{e}]") for e, x in enumerate(X)]
    res = [None] * len(vs) if residual is None else [None if r is None else as_float(r, f"residual[{e}]")
                                                      for e, r in enumerate(residual)]
    return _associate_pairs(vs, ds, list(pairs), Xs, res, ratio, duplicate_distance_m, min_matches)


def _associate_pairs(vs: list, ds: list, pairs: list, Xs: list | None, res: list, ratio: float,
                     duplicate_distance_m: float, min_matches: int) -> list[Association]:
    """The association of checked epochs (see :func:`associate_pairs`), all pairs together.

    The tracks of the pairs are stacked: pair p's tracks at t are the rows ``off_p[p]:off_p[p+1]``
    of the stacked arrays, its tracks at t + Δt ``off_n[p]:off_n[p+1]``; every step below works on
    stacked indices, and per-pair quantities are counted with the pair of each row.
    """
    if not 0.0 < float(ratio) <= 1.0:
        raise ValueError(f"ratio: must lie in (0, 1], got {ratio!r}")
    eps = float(check_positive(duplicate_distance_m, "duplicate_distance_m"))
    P = len(pairs)
    n = vs[pairs[0][0]].shape[1] if P else 1
    vp = [vs[a] for a, _ in pairs]
    vn = [vs[b] for _, b in pairs]
    off_p = np.concatenate([[0], np.cumsum([v.shape[0] for v in vp])]).astype(int)
    off_n = np.concatenate([[0], np.cumsum([v.shape[0] for v in vn])]).astype(int)
    VP = np.concatenate(vp) if P else np.zeros((0, n), bool)
    VN = np.concatenate(vn) if P else np.zeros((0, n), bool)
    M = VP.shape[0]
    pid = np.repeat(np.arange(P), np.diff(off_p))  # pair of each stacked row at t

    # per-view matches (candidates: the tracks seen in that view at each epoch), stacked indices
    match = np.full((M, n), -1, dtype=int)
    shared = [p for p, (a, b) in enumerate(pairs) if ds[a].ndim == 2 and ds[b].ndim == 2]
    if shared:
        _shared_ratio_matches([ds[pairs[p][0]] for p in shared], [ds[pairs[p][1]] for p in shared],
                              [vp[p] for p in shared], [vn[p] for p in shared], VP, VN,
                              off_p[shared], off_n[shared], match, float(ratio))
    for p, (a, b) in enumerate(pairs):
        if ds[a].ndim == 2 and ds[b].ndim == 2:
            continue
        dp, dn = ds[a], ds[b]
        if dp.ndim == 2:  # one per track on one side, per view on the other
            dp = np.broadcast_to(dp[:, None, :], (dp.shape[0], n, dp.shape[1]))
        if dn.ndim == 2:
            dn = np.broadcast_to(dn[:, None, :], (dn.shape[0], n, dn.shape[1]))
        for v in range(n):
            ia = np.nonzero(vp[p][:, v])[0]
            ib = np.nonzero(vn[p][:, v])[0]
            m = _ratio_matches(dp[ia, v], dn[ib, v], float(ratio))
            hit = m >= 0
            match[off_p[p] + ia[hit], v] = off_n[p] + ib[m[hit]]

    # primary c keeps i ↔ j = match[i, c] if every auxiliary view seeing the track at both
    # epochs matches i to the same j
    counts = np.zeros((P, n), dtype=int)
    cl_c, cl_i, cl_j = [], [], []
    for c in range(n):
        i = np.nonzero(match[:, c] >= 0)[0]
        j = match[i, c]
        aux = VP[i] & VN[j]
        aux[:, c] = False
        ok_c = np.all(~aux | (match[i] == j[:, None]), axis=1)
        counts[:, c] = np.bincount(pid[i[ok_c]], minlength=P)
        cl_c.append(np.full(int(np.count_nonzero(ok_c)), c))
        cl_i.append(i[ok_c])
        cl_j.append(j[ok_c])
    ci, cj, cc = np.concatenate(cl_i), np.concatenate(cl_j), np.concatenate(cl_c)
    # merge: drop tracks claimed with different partners, and partners claimed twice; the pairs
    # are kept in order of first claim (primary, then track index), pair by pair
    first_c = np.full(M, n)
    np.minimum.at(first_c, ci, cc)
    j_min = np.full(M, np.iinfo(int).max)
    j_max = np.full(M, -1)
    np.minimum.at(j_min, ci, cj)
    np.maximum.at(j_max, ci, cj)
    claimed = np.nonzero(j_max >= 0)[0]
    claimed = claimed[np.lexsort((claimed, first_c[claimed], pid[claimed]))]
    single = j_min[claimed] == j_max[claimed]
    n_conflicts = np.bincount(pid[claimed[~single]], minlength=P)
    ip = claimed[single]
    jn = j_min[ip]
    twice = np.bincount(jn, minlength=1)[jn] > 1
    n_conflicts += np.bincount(pid[ip[twice]], minlength=P)
    ip, jn = ip[~twice], jn[~twice]

    n_dup = np.zeros(P, dtype=int)
    if Xs is not None and ip.size > 1:
        keep = _not_duplicates(ip, jn, pid, off_p, off_n, pairs, Xs, res, eps)
        n_dup = np.bincount(pid[ip[~keep]], minlength=P)
        ip, jn = ip[keep], jn[keep]

    weights = camera_weights_from_counts(counts) if P else counts.astype(float)
    bounds = np.searchsorted(pid[ip], np.arange(P + 1))
    out = []
    for p in range(P):
        sl = slice(bounds[p], bounds[p + 1])
        ok = sl.stop - sl.start >= int(min_matches)
        out.append(Association(
            idx_prev=ip[sl] - off_p[p], idx_next=jn[sl] - off_n[p], n_per_primary=counts[p],
            camera_weights=weights[p], n_conflicts_removed=int(n_conflicts[p]),
            n_duplicates_removed=int(n_dup[p]), ok=bool(ok),
            failure_reason="" if ok else f"fewer than {int(min_matches)} associated points",
        ))
    return out


def _not_duplicates(ip: np.ndarray, jn: np.ndarray, pid: np.ndarray, off_p: np.ndarray, off_n: np.ndarray,
                    pairs: list, Xs: list, res: list, eps: float) -> np.ndarray:
    """Which of the stacked correspondences ``ip ↔ jn`` survive the near-duplicate test of flag P003-6.

    Two correspondences of one pair closer than ``eps`` at both epochs are duplicates; in order of
    quality (smaller mean residual, then order of claim) a point is dropped if a better kept one is
    near it.  One k-d tree serves all the pairs: a fourth coordinate, the pair's index times
    ``2 eps``, keeps points of different pairs apart and leaves the distances within a pair as
    they are (it adds an exact 0).
    """
    from scipy.spatial import cKDTree

    p = pid[ip]
    Xp = np.empty((ip.size, 3))
    Xn = np.empty((ip.size, 3))
    r = np.zeros(ip.size)
    by_pair = np.argsort(p, kind="stable")
    qs, starts = np.unique(p[by_pair], return_index=True)
    for q, sel in zip(qs, np.split(by_pair, starts[1:]), strict=True):   # the rows of pair q
        a, b = pairs[q]
        Xp[sel] = Xs[a][ip[sel] - off_p[q]]
        Xn[sel] = Xs[b][jn[sel] - off_n[q]]
        if res[a] is not None:
            r[sel] = r[sel] + 0.5 * res[a][ip[sel] - off_p[q]]
        if res[b] is not None:
            r[sel] = r[sel] + 0.5 * res[b][jn[sel] - off_n[q]]
    r = np.where(np.isfinite(r), r, np.inf)
    order = np.lexsort((r, p))  # pair by pair, stable in the residual
    fin = np.all(np.isfinite(Xp), -1) & np.all(np.isfinite(Xn), -1)
    keep = np.ones(ip.size, bool)
    f = np.nonzero(fin)[0]  # a point not finite at both epochs is near no other at both
    close = f[cKDTree(np.column_stack([Xp[f], p[f] * (2.0 * eps)])).query_pairs(eps, output_type="ndarray")]
    if close.size:
        d_next = np.linalg.norm(Xn[close[:, 0]] - Xn[close[:, 1]], axis=-1)
        close = close[d_next < eps]
        rank = np.empty(ip.size, int)
        rank[order] = np.arange(ip.size)
        keep = _greedy_keep(rank, close)
    return keep


def _greedy_keep(rank: np.ndarray, close: np.ndarray) -> np.ndarray:
    """Points kept when, in order of ``rank``, each kept point drops its ``close`` neighbours of larger rank.

    A point is kept exactly when none of its neighbours of smaller rank is kept, which fixes the
    points layer by layer (first those without a smaller-ranked neighbour): the same set as the
    sequential pass over the points, in array operations over the neighbour pairs.
    """
    lo = np.where(rank[close[:, 0]] < rank[close[:, 1]], close[:, 0], close[:, 1])
    hi = np.where(rank[close[:, 0]] < rank[close[:, 1]], close[:, 1], close[:, 0])
    state = np.zeros(rank.size, np.int8)  # 0 undecided, 1 kept, 2 dropped
    while True:
        dropped = np.zeros(rank.size, bool)
        dropped[hi[state[lo] == 1]] = True
        waiting = np.zeros(rank.size, bool)
        waiting[hi[state[lo] == 0]] = True
        undecided = state == 0
        newly_dropped = undecided & dropped
        newly_kept = undecided & ~dropped & ~waiting
        if not (newly_dropped.any() or newly_kept.any()):
            return state != 2
        state[newly_dropped] = 2
        state[newly_kept] = 1


def associate_from_observations(obs_prev: Observation, obs_next: Observation,
                                tri_prev: Triangulation, tri_next: Triangulation,
                                **options: Any) -> Association:
    """:func:`associate` on two ``vision.observation.Observation`` s and their triangulations
    (:class:`reconstruction.triangulation.Triangulation`); ``options`` are passed on."""
    return associate_observation_pairs([obs_prev, obs_next], [tri_prev, tri_next], [(0, 1)], **options)[0]


def associate_observation_pairs(observations: Sequence[Observation], triangulations: Sequence[Triangulation],
                                pairs: Sequence[tuple[int, int]], **options: Any) -> list[Association]:
    """:func:`associate_pairs` on epochs given as observations and their triangulations (views: the
    triangulation's ``views_used & valid``; descriptors, points and residuals as in
    :func:`associate_from_observations`); ``options`` are passed on."""
    return associate_pairs([t.views_used & t.valid[:, None] for t in triangulations],
                           [o.descriptors for o in observations], pairs, X=[t.X_W for t in triangulations],
                           residual=[t.rms_reprojection_px for t in triangulations], **options)
