"""Inter-frame association of triangulated tracks (003 eq (9)–(10)).

Between epochs t and t + Δt, each camera in turn is the *primary*: its features are matched
across the two epochs by descriptor (nearest neighbour with the ratio test of 003's intra-frame
match criterion, λ = 0.6), and a match is kept only if it is *consistent in the auxiliary views*: in every other
view that sees the track at both epochs, the same descriptor match must hold.  The matches of all
primaries are merged (pairs claimed inconsistently by two primaries are dropped), the camera
weights are updated by 003 eq (9) normalised per flag P003-5 (docs/papers.md#p003-5), and near-duplicate correspondences
are removed by the per-epoch AND test of flag P003-6 (docs/papers.md#p003-6), keeping the one with the smaller residual.

Descriptor matching uses OpenCV's brute-force L2 nearest-neighbour search (``cv2.batchDistance``,
the kernel and selection behind ``cv2.BFMatcher.knnMatch``, returning arrays); with one
descriptor per track a single search serves all views.  The consistency check, the merge and the
bookkeeping are numpy index-array operations over all tracks at once.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from reconstruction._geometry import as_float, check_positive

if TYPE_CHECKING:
    from reconstruction.triangulation import Triangulation
    from vision.observation import Observation

__all__ = ["Association", "camera_weights_from_counts", "associate",
           "associate_from_observations"]


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
    """The ``k`` nearest rows of ``d_next`` for each row of ``d_prev`` (L2): distances (float32)
    and indices (−1 past the last neighbour), nearest first, equal distances in index order.

    ``cv2.batchDistance`` with ``K=k``: the kernel and the selection of ``cv2.BFMatcher.knnMatch``,
    returned as arrays instead of one Python ``DMatch`` object per query.
    """
    import cv2

    dist, nidx = cv2.batchDistance(np.ascontiguousarray(d_prev, np.float32),
                                   np.ascontiguousarray(d_next, np.float32), cv2.CV_32F,
                                   normType=cv2.NORM_L2, K=int(k))
    return dist, nidx


def _ratio_test(dist: np.ndarray, nidx: np.ndarray, ratio: float) -> np.ndarray:
    """Nearest index where both neighbours exist and ``d1 < ratio · d2`` (in double precision, as
    on ``DMatch`` distances), else −1."""
    d = dist.astype(np.float64)
    good = (nidx[:, 0] >= 0) & (nidx[:, 1] >= 0) & (d[:, 0] < ratio * d[:, 1])
    return np.where(good, nidx[:, 0], -1).astype(int)


def _ratio_matches(d_prev: np.ndarray, d_next: np.ndarray, ratio: float) -> np.ndarray:
    """For each row of ``d_prev`` the index of its nearest neighbour in ``d_next`` passing the
    ratio test ``d1 < ratio · d2`` (−1 otherwise); same result as ``cv2.BFMatcher.knnMatch(k=2)``."""
    if len(d_prev) == 0 or len(d_next) < 2:
        return np.full(len(d_prev), -1, dtype=int)
    return _ratio_test(*_knn(d_prev, d_next, 2), ratio)


def _shared_ratio_matches(d_prev, d_next, vp, vn, ratio: float) -> np.ndarray:
    """Per-view ratio-test matches ``(M, n)`` (−1: none) with one descriptor per track.

    One ``_K_SHARED``-nearest search over all tracks seen at each epoch; in view v the two
    nearest candidates seen in v are the first two of them in that list (the list is the start of
    the stable distance order, so ties keep the order of a search over the view's tracks alone).
    Queries whose full list holds fewer than two of the view's candidates are searched again
    among those candidates only.  Same result as :func:`_ratio_matches` per view.
    """
    M, n = vp.shape
    match = np.full((M, n), -1, dtype=int)
    rows = np.nonzero(vp.any(axis=1))[0]
    cols = np.nonzero(vn.any(axis=1))[0]
    if rows.size == 0 or cols.size < 2:
        return match
    k = min(_K_SHARED, cols.size)
    dist, nidx = _knn(d_prev[rows], d_next[cols], k)
    valid = nidx >= 0
    cand = np.where(valid, cols[np.maximum(nidx, 0)], -1)  # track indices at t + Δt
    full = valid[:, -1]
    r = np.arange(rows.size)
    for v in range(n):
        q = vp[rows, v]
        inv = valid & vn[np.maximum(cand, 0), v]
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
        b = np.nonzero(vn[:, v])[0]
        if np.any(again) and b.size >= 2:
            a = rows[again]
            mm = _ratio_matches(d_prev[a], d_next[b], ratio)
            match[a, v] = np.where(mm >= 0, b[np.maximum(mm, 0)], -1)
    return match


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
    n = vp.shape[1]
    if vn.shape[1] != n:
        raise ValueError(f"views_next: expected {n} views like views_prev, got {vn.shape}")
    if dp.shape[-1] != dn.shape[-1]:
        raise ValueError(f"descriptors_next: length {dn.shape[-1]} differs from "
                         f"descriptors_prev {dp.shape[-1]}")
    if not 0.0 < float(ratio) <= 1.0:
        raise ValueError(f"ratio: must lie in (0, 1], got {ratio!r}")
    eps = float(check_positive(duplicate_distance_m, "duplicate_distance_m"))
    if dp.ndim != dn.ndim:  # one per track on one side, per view on the other
        if dp.ndim == 2:
            dp = np.broadcast_to(dp[:, None, :], (dp.shape[0], n, dp.shape[1]))
        else:
            dn = np.broadcast_to(dn[:, None, :], (dn.shape[0], n, dn.shape[1]))

    # per-view matches (candidates: the tracks seen in that view at each epoch)
    M = vp.shape[0]
    if dp.ndim == 2:
        match = _shared_ratio_matches(dp, dn, vp, vn, float(ratio))
    else:
        match = np.full((M, n), -1, dtype=int)
        for v in range(n):
            a = np.nonzero(vp[:, v])[0]
            b = np.nonzero(vn[:, v])[0]
            m = _ratio_matches(dp[a, v], dn[b, v], float(ratio))
            hit = m >= 0
            match[a[hit], v] = b[m[hit]]

    # primary c keeps i ↔ j = match[i, c] if every auxiliary view seeing the track at both
    # epochs matches i to the same j
    counts = np.zeros(n, dtype=int)
    cl_c, cl_i, cl_j = [], [], []
    for c in range(n):
        i = np.nonzero(match[:, c] >= 0)[0]
        j = match[i, c]
        aux = vp[i] & vn[j]
        aux[:, c] = False
        ok_c = np.all(~aux | (match[i] == j[:, None]), axis=1)
        counts[c] = int(np.count_nonzero(ok_c))
        cl_c.append(np.full(counts[c], c))
        cl_i.append(i[ok_c])
        cl_j.append(j[ok_c])
    ci, cj, cc = np.concatenate(cl_i), np.concatenate(cl_j), np.concatenate(cl_c)
    # merge: drop tracks claimed with different partners, and partners claimed twice; the pairs
    # are kept in order of first claim (primary, then track index)
    first_c = np.full(M, n)
    np.minimum.at(first_c, ci, cc)
    j_min = np.full(M, np.iinfo(int).max)
    j_max = np.full(M, -1)
    np.minimum.at(j_min, ci, cj)
    np.maximum.at(j_max, ci, cj)
    claimed = np.nonzero(j_max >= 0)[0]
    claimed = claimed[np.lexsort((claimed, first_c[claimed]))]
    single = j_min[claimed] == j_max[claimed]
    n_conflicts = int(claimed.size - np.count_nonzero(single))
    ip = claimed[single]
    jn = j_min[ip]
    shared = np.bincount(jn, minlength=1)[jn] > 1
    n_conflicts += int(np.count_nonzero(shared))
    ip, jn = ip[~shared], jn[~shared]

    n_dup = 0
    if X_prev is not None and X_next is not None and ip.size > 1:
        from scipy.spatial import cKDTree

        Xp = as_float(X_prev, "X_prev")[ip]
        Xn = as_float(X_next, "X_next")[jn]
        res = np.zeros(ip.size)
        if residual_prev is not None:
            res = res + 0.5 * as_float(residual_prev, "residual_prev")[ip]
        if residual_next is not None:
            res = res + 0.5 * as_float(residual_next, "residual_next")[jn]
        res = np.where(np.isfinite(res), res, np.inf)
        order = np.argsort(res, kind="stable")
        fin = np.all(np.isfinite(Xp), -1) & np.all(np.isfinite(Xn), -1)
        keep = np.ones(ip.size, bool)
        close = cKDTree(np.where(fin[:, None], Xp, 1e300)).query_pairs(eps, output_type="ndarray")
        if close.size:
            d_next = np.linalg.norm(Xn[close[:, 0]] - Xn[close[:, 1]], axis=-1)
            close = close[d_next < eps]
            rank = np.empty(ip.size, int)
            rank[order] = np.arange(ip.size)
            # process in order of quality: a point is dropped if a better kept one is near it
            nbrs: dict[int, list[int]] = {}
            for a, b in close:
                nbrs.setdefault(int(a), []).append(int(b))
                nbrs.setdefault(int(b), []).append(int(a))
            for k in order:
                if keep[k]:
                    for other in nbrs.get(int(k), []):
                        if rank[other] > rank[k]:
                            keep[other] = False
        n_dup = int(np.sum(~keep))
        ip, jn = ip[keep], jn[keep]

    ok = ip.size >= int(min_matches)
    return Association(
        idx_prev=ip, idx_next=jn, n_per_primary=counts,
        camera_weights=camera_weights_from_counts(counts), n_conflicts_removed=int(n_conflicts),
        n_duplicates_removed=n_dup, ok=bool(ok),
        failure_reason="" if ok else f"fewer than {int(min_matches)} associated points",
    )


def associate_from_observations(obs_prev: Observation, obs_next: Observation,
                                tri_prev: Triangulation, tri_next: Triangulation,
                                **options: Any) -> Association:
    """:func:`associate` on two ``vision.observation.Observation`` s and their triangulations
    (:class:`reconstruction.triangulation.Triangulation`); ``options`` are passed on."""
    return associate(
        tri_prev.views_used & tri_prev.valid[:, None], obs_prev.descriptors,
        tri_next.views_used & tri_next.valid[:, None], obs_next.descriptors,
        X_prev=tri_prev.X_W, X_next=tri_next.X_W, residual_prev=tri_prev.rms_reprojection_px,
        residual_next=tri_next.rms_reprojection_px, **options,
    )
