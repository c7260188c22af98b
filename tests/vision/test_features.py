"""Detection, epipolar geometry (003 eq 2-3, flag P003-2 (docs/papers.md#p003-2)), matching, tracks, and issue 5's figures."""

import numpy as np
import pytest

from tests.vision.conftest import SUN_SIDE_H, facing_attitude, two_camera_poses
from vision.camera import PinholeCamera, invert_pose, look_at, transform_points
from vision.features import (
    Keypoints,
    available_detectors,
    detect,
    epipolar_distance_px,
    fundamental_from_poses,
    match_pair,
    match_views,
    tracks_from_matches,
)
from vision.rendered import foreground_mask, observe_renders, render_views

CAM = PinholeCamera.from_fov(640, 480, fov_x_deg=30.0)


def _views(rng):
    T_A = look_at([40.0, -3.0, 2.0], [0, 0, 0])
    T_B = look_at([39.0, 4.0, -1.0], [0.5, 0, 0])
    X = rng.uniform(-3, 3, (200, 3))
    return T_A, T_B, X, CAM.project_world(X, T_A)[0], CAM.project_world(X, T_B)[0]


def test_fundamental_matrix_from_poses_annihilates_projections_of_the_same_point():
    T_A, T_B, X, uv_A, uv_B = _views(np.random.default_rng(0))
    F = fundamental_from_poses(CAM.K, T_A, CAM.K, T_B)
    xa = np.c_[uv_A, np.ones(len(X))]
    xb = np.c_[uv_B, np.ones(len(X))]
    assert np.max(np.abs(np.sum(xa * (xb @ F.T), axis=1))) < 1e-9      # 003 eq (2)
    assert np.max(epipolar_distance_px(F, uv_A, uv_B)) < 1e-6


def test_epipolar_distance_measures_pixel_offsets_across_the_epipolar_line():
    T_A, T_B, X, uv_A, uv_B = _views(np.random.default_rng(1))
    F = fundamental_from_poses(CAM.K, T_A, CAM.K, T_B)
    line = np.c_[uv_A, np.ones(len(X))] @ F                              # lines in B
    nrm = line[:, :2] / np.linalg.norm(line[:, :2], axis=1, keepdims=True)
    d = epipolar_distance_px(F, uv_A, uv_B + 2.0 * nrm)
    np.testing.assert_allclose(np.sqrt(np.abs(d)) ** 2, 2.0, rtol=0.02)  # max(d_A, d_B) ~ 2 px
    assert np.all(epipolar_distance_px(F, uv_A, uv_B + 1.0 * nrm) > 0.9)


def test_fundamental_matrix_rejects_coincident_camera_centres():
    T = look_at([40.0, 0, 0], [0, 0, 0])
    with pytest.raises(ValueError, match="camera centre"):
        fundamental_from_poses(CAM.K, T, CAM.K, T)


def test_sift_keypoints_are_unbiased_on_gaussian_blobs_at_known_subpixel_positions():
    yy, xx = np.mgrid[0:240, 0:240]
    centres = np.array([[60.3, 80.7], [150.0, 120.0], [100.5, 190.25], [190.8, 40.4]])
    img = sum(np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * 4.0 ** 2)) for cx, cy in centres)
    kp = detect((img / img.max() * 200).astype(np.uint8))
    for c in centres:
        d = np.linalg.norm(kp.uv_px - c, axis=1)
        assert d.min() < 0.1
    assert kp.descriptors.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(kp.descriptors, axis=1), 1.0, rtol=1e-5)


def _synthetic_keypoints(rng, uv, desc):
    n = len(uv)
    return Keypoints(uv, desc, np.full(n, 3.0), np.zeros(n), np.ones(n), "sift")


def test_match_pair_finds_true_pairs_and_the_epipolar_gate_removes_a_wrong_one():
    rng = np.random.default_rng(2)
    T_A, T_B, X, uv_A, uv_B = _views(rng)
    d = rng.standard_normal((200, 128)).astype(np.float32)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    noisy = d + 0.02 * rng.standard_normal(d.shape).astype(np.float32)
    perm = rng.permutation(200)
    kA = _synthetic_keypoints(rng, uv_A, d)
    kB = _synthetic_keypoints(rng, uv_B[perm], noisy[perm])
    # swap the positions of two B keypoints: their descriptors still match, their geometry no longer
    uvB = kB.uv_px.copy()
    uvB[[0, 1]] = uvB[[1, 0]]
    kB_bad = _synthetic_keypoints(rng, uvB, kB.descriptors)
    F = fundamental_from_poses(CAM.K, T_A, CAM.K, T_B)
    pairs = match_pair(kA, kB_bad, ratio=0.6, F_AB=F)
    np.testing.assert_array_equal(perm[pairs[:, 1]], pairs[:, 0])        # every kept pair is true
    assert len(pairs) == 198 and not np.isin(pairs[:, 1], [0, 1]).any()
    assert len(match_pair(kA, kB_bad, ratio=0.6)) == 200                  # without the gate


def test_ratio_test_rejects_a_keypoint_with_two_equally_good_candidates():
    rng = np.random.default_rng(3)
    d = rng.standard_normal((3, 128)).astype(np.float32)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    kA = _synthetic_keypoints(rng, np.zeros((1, 2)), d[:1])
    twins = d[0] + 0.05 * rng.standard_normal((2, 128)).astype(np.float32)
    kB = _synthetic_keypoints(rng, np.zeros((3, 2)), np.vstack([twins, d[2:]]))
    assert len(match_pair(kA, kB, ratio=0.6)) == 0
    assert len(match_pair(kA, kB.subset([0, 2]), ratio=0.6)) == 1      # one twin alone matches


def test_tracks_chain_pairwise_matches_and_drop_inconsistent_components():
    pm = {(0, 1): np.array([[0, 0], [1, 1], [2, 2]]),
          (1, 2): np.array([[0, 5], [1, 6]]),
          (0, 2): np.array([[2, 7], [3, 6]])}      # keypoint 6 of view 2 joins tracks 1 and 3
    t = tracks_from_matches([4, 3, 8], pm)
    rows = {tuple(r) for r in t.tolist()}
    assert (0, 0, 5) in rows and (2, 2, 7) in rows
    assert not any(r[0] in (1, 3) for r in rows)                           # conflict dropped
    assert t.shape[1] == 3


def test_surf_is_available_only_with_the_nonfree_build_and_says_so():
    if "surf" in available_detectors():
        kp = detect(np.random.default_rng(0).integers(0, 255, (128, 128)).astype(np.uint8),
                    detector="surf")
        assert kp.descriptors.shape[1] in (64, 128)
    else:
        with pytest.raises(ValueError, match="non-free"):
            detect(np.zeros((64, 64), np.uint8), detector="surf")


@pytest.mark.parametrize("detector", ["orb", "akaze"])
def test_binary_detectors_match_a_shifted_image_to_its_shift(detector):
    rng = np.random.default_rng(4)
    import cv2

    base = cv2.GaussianBlur(rng.random((300, 300)).astype(np.float32), (0, 0), 3)
    img = cv2.normalize(base, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    a, b = img[20:260, 20:260], img[27:267, 15:255]                         # shift (-5, +7)
    ka, kb = detect(a, detector=detector), detect(b, detector=detector)
    p = match_pair(ka, kb, ratio=0.8)
    assert len(p) > 20
    shift = ka.uv_px[p[:, 0]] - kb.uv_px[p[:, 1]]
    assert np.mean(np.linalg.norm(shift - [-5, 7], axis=1) < 1.5) > 0.9


# --- issue 5 "done when": FY-1-like and TOPEX at 50 m, 1024 px, 20 deg, axes 10 deg apart ----------


def _issue5_figures(renders, target, q):
    n_features = [len(detect(r.image, roi=r.roi, mask=foreground_mask(r.image))) for r in renders]
    obs = observe_renders(renders, target, q)
    return n_features, obs


def test_fy1_at_50m_gives_300_features_per_view_and_100_matches_95_percent_correct(fy1_pair, fy1):
    T, q, renders = fy1_pair
    n_features, obs = _issue5_figures(renders, fy1, q)
    assert min(n_features) >= 300
    assert obs.n_tracks >= 100
    assert np.mean(obs.feature_id >= 0) >= 0.95


def test_topex_at_50m_with_procedural_texture_meets_the_same_figures(camera, topex):
    T = two_camera_poses(50.0)
    q = facing_attitude([0.0, 0.53, 0.85])                   # solar-array normal (README)
    renders = render_views(camera, T, topex, q, SUN_SIDE_H, rng=0)
    n_features, obs = _issue5_figures(renders, topex, q)
    assert min(n_features) >= 300
    assert obs.n_tracks >= 100
    assert np.mean(obs.feature_id >= 0) >= 0.95


def test_rendered_tracks_have_truth_consistent_with_their_pixels(fy1_pair, fy1, camera):
    from attitude.quaternion import matrix_from_quat

    T, q, renders = fy1_pair
    obs = observe_renders(renders, fy1, q)
    good = obs.feature_id >= 0
    X_H = obs.X_T_true[good] @ matrix_from_quat(q).T
    for i in range(2):
        uv, _ = camera.project_world(X_H, T[i])
        seen = obs.seen[good, i]
        err = np.linalg.norm(uv[seen] - obs.uv_px[good][seen, i], axis=1)
        assert np.median(err) < 0.6 and err.max() <= 2.0
    assert obs.descriptors.shape == (obs.n_tracks, 128)
    assert obs.K.shape == (2, 3, 3) and obs.image_size == (1024, 1024)


def test_rendered_observation_is_reproducible_with_the_same_seed(fy1):
    from vision.rendered import observe

    cam = PinholeCamera.from_fov(400, 400, fov_x_deg=20.0)
    T = two_camera_poses(30.0)
    q = facing_attitude([1.0, 0.0, 0.0], 45.0)
    a = observe(cam, T, fy1, q, SUN_SIDE_H, rng=11)
    b = observe(cam, T, fy1, q, SUN_SIDE_H, rng=11)
    assert a.n_tracks > 10
    np.testing.assert_array_equal(a.uv_px, b.uv_px)
    np.testing.assert_array_equal(a.descriptors, b.descriptors)


def test_match_views_rejects_inconsistent_inputs():
    kp = detect(np.zeros((32, 32), np.uint8))
    T = np.stack([look_at([10.0, 0, 0], [0, 0, 0]), look_at([10.0, 1, 0], [0, 0, 0])])
    with pytest.raises(ValueError, match="T_CW"):
        match_views([kp, kp], CAM, T[:1])
    with pytest.raises(ValueError, match="min_views"):
        match_views([kp, kp], CAM, T, min_views=3)
    obs = match_views([kp, kp], CAM, T)
    assert obs.failure_reason == "too few matches" and obs.n_tracks == 0


def test_transform_helpers_used_by_the_tests_are_consistent():
    T = look_at([10.0, 2, 3], [0, 0, 0])
    X = np.array([1.0, 2, 3])
    np.testing.assert_allclose(transform_points(invert_pose(T), transform_points(T, X)), X)


@pytest.mark.parametrize("binary", [False, True])
def test_flann_neighbours_as_arrays_equal_opencvs_flann_matcher(binary):
    """``vision.features._knn`` (a ``cv2.flann_Index`` searched to arrays) returns the very neighbours and
    distances of ``cv2.FlannBasedMatcher.knnMatch`` with the same index and search parameters (the
    matcher it replaced), for SIFT-like float descriptors (kd-trees) and binary ones (LSH)."""
    import cv2

    from vision.features import _knn

    rng = np.random.default_rng(3)
    if binary:
        a = rng.integers(0, 256, size=(300, 32), dtype=np.uint8)
        b = np.concatenate([a[:150] ^ (rng.random((150, 32)) < 0.03).astype(np.uint8),
                            rng.integers(0, 256, size=(250, 32), dtype=np.uint8)])
        index = {"algorithm": 6, "table_number": 6, "key_size": 12, "multi_probe_level": 1}
    else:
        b = rng.random((400, 128)).astype(np.float32)
        a = np.concatenate([b[:200] + rng.normal(0.0, 0.05, (200, 128)), rng.random((100, 128))]).astype(np.float32)
        index = {"algorithm": 1, "trees": 4}
    idx, dist = _knn(a, b, 2, flann_trees=4, flann_checks=32)
    cv2.setRNGSeed(0)
    matcher = cv2.FlannBasedMatcher(index, {"checks": 32})
    matcher.add([b])
    matcher.train()
    ref_idx, ref_dist = np.full((len(a), 2), -1), np.full((len(a), 2), np.inf)
    for i, ms in enumerate(matcher.knnMatch(a, k=2)):
        for j, m in enumerate(ms[:2]):
            ref_idx[i, j], ref_dist[i, j] = m.trainIdx, m.distance
    assert (ref_idx >= 0).sum() >= 0.9 * ref_idx.size          # the comparison is over found neighbours
    np.testing.assert_array_equal(idx, ref_idx)
    np.testing.assert_array_equal(dist, ref_dist)
