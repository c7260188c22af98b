"""Inter-frame association: primary/auxiliary consistency, eq (9) weights, de-duplication."""

from __future__ import annotations

import numpy as np
import pytest

from reconstruction._synthetic import fy1_points, observe, ring_cameras
from reconstruction.association import (
    associate,
    associate_from_observations,
    camera_weights_from_counts,
)
from reconstruction.registration import fit_rigid_ml
from reconstruction.triangulation import triangulate


def _two_epochs(rng, M=150, n=3, D=64, noise=0.05, visible=0.9):
    """Track descriptors at t and (shuffled, noisy) at t + Δt; ``truth[i]`` = index at t + Δt."""
    desc = rng.standard_normal((M, D)).astype(np.float32)
    perm = rng.permutation(M)  # row k at t+Δt is track perm[k]
    truth = np.argsort(perm)
    vp = rng.random((M, n)) < visible
    vn = (rng.random((M, n)) < visible)[perm]
    dn = (desc + noise * rng.standard_normal((M, D)).astype(np.float32))[perm]
    return desc, vp, dn, vn, truth


def test_matches_recover_the_true_track_correspondence():
    rng = np.random.default_rng(0)
    desc, vp, dn, vn, truth = _two_epochs(rng)
    a = associate(vp, desc, vn, dn)
    assert a.ok and len(a.idx_prev) > 140
    np.testing.assert_array_equal(truth[a.idx_prev], a.idx_next)


def test_camera_weights_follow_eq_9_and_sum_to_one():
    np.testing.assert_allclose(camera_weights_from_counts([10, 0, 5]), [11 / 18, 1 / 18, 6 / 18])
    rng = np.random.default_rng(1)
    desc, vp, dn, vn, _ = _two_epochs(rng)
    vp[:, 2] &= rng.random(len(vp)) < 0.3  # camera 2 sees few tracks
    a = associate(vp, desc, vn, dn)
    assert a.camera_weights.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(a.camera_weights, (1 + a.n_per_primary) / (3 + a.n_per_primary.sum()))
    assert a.camera_weights[2] < min(a.camera_weights[:2])


def test_auxiliary_view_disagreement_rejects_a_primary_match():
    """Per-view descriptors: in view 1 track 0 looks like track 1 — the match found with view 0 as
    primary is then inconsistent in the auxiliary view 1 and dropped."""
    rng = np.random.default_rng(2)
    M, n, D = 40, 2, 32
    base = rng.standard_normal((M, D)).astype(np.float32)
    dp = np.repeat(base[:, None], n, 1)
    dn = dp + 0.01 * rng.standard_normal(dp.shape).astype(np.float32)
    dn[1, 1] = dp[0, 1] + 0.001  # at t+Δt, in view 1, track 1 takes track 0's appearance
    dn[0, 1] = rng.standard_normal(D)
    views = np.ones((M, n), bool)
    a = associate(views, dp, views, dn)
    assert 0 not in a.idx_prev  # view 0 says 0↔0, view 1 says 0↔1: inconsistent
    assert np.all(a.idx_prev == a.idx_next)
    # with the same descriptors in every view (one per track) the match is kept
    b = associate(views, dp[:, 0], views, dn[:, 0])
    assert 0 in b.idx_prev


def test_near_duplicate_correspondences_are_removed_keeping_the_smaller_residual():
    rng = np.random.default_rng(3)
    M = 30
    desc = rng.standard_normal((M, 16)).astype(np.float32)
    X = rng.uniform(-2, 2, (M, 3))
    X[1] = X[0] + 0.01  # track 1 duplicates track 0 at both epochs
    X[3] = X[2] + 0.01  # track 3 is near track 2 at t only
    Xn = X + np.array([0.1, 0.0, 0.0])
    Xn[3] = X[3] + 1.0
    res = np.full(M, 0.3)
    res[0] = 0.9  # track 0 fits worse than its duplicate 1
    views = np.ones((M, 2), bool)
    a = associate(views, desc, views, desc + 0.01, X_prev=X, X_next=Xn, residual_prev=res,
                  residual_next=res, duplicate_distance_m=0.05)
    assert a.n_duplicates_removed == 1
    assert 0 not in a.idx_prev and {1, 2, 3} <= set(a.idx_prev.tolist())


def test_too_few_matches_is_a_reported_failure():
    rng = np.random.default_rng(4)
    views = np.ones((5, 2), bool)
    a = associate(views, rng.standard_normal((5, 8)), views, rng.standard_normal((5, 8)))
    assert not a.ok and a.failure_reason == "fewer than 3 associated points"
    with pytest.raises(ValueError, match="descriptors_next"):
        associate(views, np.zeros((5, 8)), views, np.zeros((5, 9)))
    with pytest.raises(ValueError, match="views_next"):
        associate(views, np.zeros((5, 8)), np.ones((5, 3), bool), np.zeros((5, 8)))


def test_observation_pipeline_associates_and_registers_two_epochs():
    """vision Observation → triangulate → associate → ML registration recovers the increment."""
    from scipy.spatial.transform import Rotation

    from vision.observation import Observation

    rng = np.random.default_rng(5)
    K, T = ring_cameras(3, distance_m=50.0, axis_angle_deg=10.0)
    X_T = fy1_points(200, rng)
    dR = Rotation.from_rotvec(np.radians([0.5, 0.5, 0.5])).as_matrix()
    desc = rng.standard_normal((200, 64)).astype(np.float32)
    obs = []
    for k, R in enumerate((np.eye(3), dR)):
        order = rng.permutation(200) if k else np.arange(200)
        X = (X_T @ R.T)[order]
        obs.append(Observation(
            uv_px=observe(X, K, T, 0.5, rng), K=K, T_CW=T, image_size=(1024, 1024),
            descriptors=desc[order] + 0.05 * rng.standard_normal((200, 64)).astype(np.float32),
            pixel_sigma_px=0.5, feature_id=order, X_T_true=X_T[order]))
    tri = [triangulate(o.uv_px, o.K, o.T_CW, pixel_sigma_px=o.pixel_sigma_px) for o in obs]
    a = associate_from_observations(obs[0], obs[1], tri[0], tri[1])
    assert a.ok
    np.testing.assert_array_equal(obs[0].feature_id[a.idx_prev], obs[1].feature_id[a.idx_next])
    fit = fit_rigid_ml(tri[0].X_W[a.idx_prev], tri[1].X_W[a.idx_next], tri[0].cov_W[a.idx_prev],
                       tri[1].cov_W[a.idx_next], rng=6)
    err = np.linalg.norm(Rotation.from_matrix(dR @ fit.R.T).as_rotvec())
    assert err < 5 * fit.rotation_sigma_rad


def _reference_associate(vp, dp, vn, dn, ratio=0.6):
    """Independent per-track implementation of 003 §1.5 (no de-duplication): ``cv2.BFMatcher``
    knnMatch per view, then the auxiliary-view check and the merge track by track."""
    import cv2

    M, n = vp.shape
    dp3 = dp if dp.ndim == 3 else np.repeat(dp[:, None], n, 1)
    dn3 = dn if dn.ndim == 3 else np.repeat(dn[:, None], n, 1)
    match = np.full((M, n), -1)
    for v in range(n):
        a, b = np.nonzero(vp[:, v])[0], np.nonzero(vn[:, v])[0]
        if len(a) == 0 or len(b) < 2:
            continue
        for m in cv2.BFMatcher(cv2.NORM_L2).knnMatch(dp3[a, v].astype(np.float32),
                                                      dn3[b, v].astype(np.float32), k=2):
            if len(m) == 2 and m[0].distance < ratio * m[1].distance:
                match[a[m[0].queryIdx], v] = b[m[0].trainIdx]
    counts, claims = np.zeros(n, int), {}
    for c in range(n):
        for i in np.nonzero(match[:, c] >= 0)[0]:
            j = match[i, c]
            aux = vp[i] & vn[j]
            aux[c] = False
            if np.all(match[i, aux] == j):
                counts[c] += 1
                claims.setdefault(int(i), set()).add(int(j))
    pairs = [(i, next(iter(js))) for i, js in claims.items() if len(js) == 1]
    partner_count = {}
    for _, j in pairs:
        partner_count[j] = partner_count.get(j, 0) + 1
    kept = [(i, j) for i, j in pairs if partner_count[j] == 1]
    return np.array([i for i, _ in kept], int), np.array([j for _, j in kept], int), counts


@pytest.mark.parametrize("per_view", [False, True])
def test_vectorised_association_equals_a_per_track_knnmatch_reference(per_view):
    """Sparse views, repeated descriptors (ties) and look-alike tracks (conflicts): the matches,
    their order and the per-primary counts equal the per-track loop over ``BFMatcher.knnMatch``."""
    rng = np.random.default_rng(7)
    n_conflicts = 0
    for _ in range(60):
        M, Mn, n, D = int(rng.integers(5, 120)), int(rng.integers(5, 120)), int(rng.integers(2, 5)), 16
        base = rng.standard_normal((max(M, Mn), D)).astype(np.float32)
        dp = base[:M] + 0.1 * rng.standard_normal((M, D)).astype(np.float32)
        dn = base[rng.permutation(max(M, Mn))[:Mn]] + 0.1 * rng.standard_normal((Mn, D)).astype(np.float32)
        dn[1] = dn[2] = dn[0]  # exact ties
        if per_view:
            dp = dp[:, None] + 0.3 * rng.standard_normal((M, n, D)).astype(np.float32)
            dn = dn[:, None] + 0.3 * rng.standard_normal((Mn, n, D)).astype(np.float32)
        vp = rng.random((M, n)) < rng.uniform(0.2, 1.0)
        vn = rng.random((Mn, n)) < rng.uniform(0.2, 1.0)
        ratio = float(rng.uniform(0.6, 1.0))
        a = associate(vp, dp, vn, dn, ratio=ratio)
        ip, jn, counts = _reference_associate(vp, dp, vn, dn, ratio)
        np.testing.assert_array_equal(a.idx_prev, ip)
        np.testing.assert_array_equal(a.idx_next, jn)
        np.testing.assert_array_equal(a.n_per_primary, counts)
        n_conflicts += a.n_conflicts_removed
    assert n_conflicts > 0  # the merge rules were exercised


def test_pairs_of_epochs_associated_together_equal_one_call_per_pair():
    """associate_pairs over epochs with one descriptor per track, per view, or mixed, with points
    and residuals (near duplicates included) and an epoch in two pairs: each result equals
    associate() on its pair alone, field by field."""
    from reconstruction.association import associate_pairs

    rng = np.random.default_rng(8)
    n, D = 3, 16
    views, descs, X, res = [], [], [], []
    base = rng.standard_normal((90, D)).astype(np.float32)
    X_base = rng.uniform(-0.3, 0.3, (90, 3))
    X_base[1::2] = X_base[::2] + 0.01  # pairs of near-duplicate surface points
    for e in range(6):
        M = int(rng.integers(20, 90))
        ids = rng.permutation(90)[:M]
        d = base[ids] + 0.05 * rng.standard_normal((M, D)).astype(np.float32)
        if e in (2, 3):
            d = d[:, None] + 0.1 * rng.standard_normal((M, n, D)).astype(np.float32)
        views.append(rng.random((M, n)) < 0.8)
        descs.append(d)
        x = X_base[ids] + 1e-3 * e
        x[rng.random(M) < 0.1] = np.nan
        X.append(x)
        res.append(rng.uniform(0.1, 1.0, M))
    res[4] = None
    pairs = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (5, 0), (1, 4)]
    many = associate_pairs(views, descs, pairs, X=X, residual=res, duplicate_distance_m=0.05)
    n_dup = 0
    for (a, b), got in zip(pairs, many, strict=True):
        one = associate(views[a], descs[a], views[b], descs[b], X_prev=X[a], X_next=X[b],
                        residual_prev=res[a], residual_next=res[b], duplicate_distance_m=0.05)
        np.testing.assert_array_equal(got.idx_prev, one.idx_prev)
        np.testing.assert_array_equal(got.idx_next, one.idx_next)
        np.testing.assert_array_equal(got.n_per_primary, one.n_per_primary)
        np.testing.assert_array_equal(got.camera_weights, one.camera_weights)
        assert (got.n_conflicts_removed, got.n_duplicates_removed, got.ok, got.failure_reason) == \
               (one.n_conflicts_removed, one.n_duplicates_removed, one.ok, one.failure_reason)
        n_dup += got.n_duplicates_removed
    assert n_dup > 0 and sum(len(a.idx_prev) for a in many) > 100


def test_knn_kernel_equals_an_exact_reference_with_ties_and_crowded_candidates():
    """reconstruction._knn_kernel.knn_l2 against a double-precision brute force: same neighbours in
    (distance, index) order, distances to rounding; exact duplicates (ties) and a crowd of equidistant
    references (the float32 pass cannot separate them: the exact re-search) included."""
    from reconstruction._knn_kernel import knn_l2

    rng = np.random.default_rng(9)
    for case in range(40):
        M, N, D = int(rng.integers(1, 40)), int(rng.integers(1, 70)), int(rng.choice([3, 16, 128]))
        A = rng.standard_normal((M, D)).astype(np.float32)
        B = rng.standard_normal((N, D)).astype(np.float32)
        if N > 20 and case % 2:
            B[:20] = B[0]  # twenty equal references
            A[0] = B[0] + 1e-3
        k = int(rng.integers(1, 12))
        dist, idx = knn_l2(A, B, k)
        d2 = np.sum((A[:, None, :].astype(float) - B[None].astype(float)) ** 2, -1)
        ref = np.lexsort((np.broadcast_to(np.arange(N), d2.shape), np.round(d2, 9)), axis=-1)[:, :k]
        kk = min(k, N)
        np.testing.assert_array_equal(idx[:, :kk], ref[:, :kk])
        np.testing.assert_allclose(dist[:, :kk], np.sqrt(np.take_along_axis(d2, ref[:, :kk], 1)), rtol=1e-12)
        assert np.all(idx[:, kk:] == -1) and np.all(np.isinf(dist[:, kk:]))


def test_duplicate_removal_in_array_operations_equals_the_sequential_pass():
    """_greedy_keep (layer by layer) keeps the points the sequential pass in order of quality keeps."""
    from reconstruction.association import _greedy_keep

    rng = np.random.default_rng(10)
    for _ in range(50):
        N = int(rng.integers(2, 60))
        close = rng.integers(0, N, (int(rng.integers(0, 3 * N)), 2))
        close = close[close[:, 0] != close[:, 1]]
        rank = rng.permutation(N)
        keep = np.ones(N, bool)
        for k in np.argsort(rank):  # the sequential pass
            if keep[k]:
                for a, b in close:
                    other = b if a == k else a if b == k else -1
                    if other >= 0 and rank[other] > rank[k]:
                        keep[other] = False
        np.testing.assert_array_equal(_greedy_keep(rank, close), keep)


def test_pairs_with_empty_epochs_or_mixed_camera_counts():
    """An epoch without tracks gives a failed association for its pairs (as associate does); pairs
    with different camera counts are refused."""
    from reconstruction.association import associate_pairs

    rng = np.random.default_rng(12)
    d = rng.standard_normal((30, 8)).astype(np.float32)
    v = np.ones((30, 2), bool)
    out = associate_pairs([v, v[:0], v], [d, d[:0], d + 0.01], [(0, 1), (1, 2), (0, 2)])
    assert [a.ok for a in out] == [False, False, True] and len(out[2].idx_prev) == 30
    assert out[0].failure_reason == associate(v, d, v[:0], d[:0]).failure_reason
    with pytest.raises(ValueError, match="same number of views"):
        associate_pairs([v, v, np.ones((30, 3), bool), np.ones((30, 3), bool)], [d] * 4, [(0, 1), (2, 3)])
