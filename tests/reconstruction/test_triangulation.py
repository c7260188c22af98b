"""Triangulation: exactness, agreement with OpenCV/pycolmap, covariance consistency, rejection."""

from __future__ import annotations

import cv2
import numpy as np
import pycolmap
import pytest
from scipy.stats import chi2

from reconstruction._synthetic import fy1_points, observe, ring_cameras
from reconstruction.accuracy import point_covariance
from reconstruction.triangulation import (
    FAILURE_BEHIND_CAMERA,
    FAILURE_DEGENERATE,
    FAILURE_REPROJECTION,
    FAILURE_TOO_FEW_VIEWS,
    triangulate,
    triangulate_from_observation,
)

SIGMA = 0.5


@pytest.fixture(scope="module")
def cams3():
    return ring_cameras(3, distance_m=50.0, axis_angle_deg=10.0)


@pytest.mark.parametrize("n_views", [2, 3, 5])
def test_noise_free_tracks_are_recovered_exactly_for_2_to_5_views(n_views):
    K, T = ring_cameras(n_views, distance_m=50.0, axis_angle_deg=10.0)
    X = fy1_points(300, 0)
    tri = triangulate(observe(X, K, T, 0.0, 1), K, T, pixel_sigma_px=SIGMA)
    assert tri.ok and tri.failure_reason == ""
    assert np.all(tri.valid)
    np.testing.assert_allclose(tri.X_W, X, atol=1e-9)
    assert np.nanmax(tri.rms_reprojection_px) < 1e-8


def test_batched_call_equals_per_trial_calls(cams3):
    K, T = cams3
    rng = np.random.default_rng(2)
    X = fy1_points(50, rng, batch=(4, 2))
    uv = observe(X, K, T, SIGMA, rng)
    tri = triangulate(uv, K, T, pixel_sigma_px=SIGMA)
    assert tri.X_W.shape == (4, 2, 50, 3) and tri.cov_W.shape == (4, 2, 50, 3, 3)
    assert tri.ok.shape == (4, 2)
    for a in range(4):
        for b in range(2):
            one = triangulate(uv[a, b], K, T, pixel_sigma_px=SIGMA)
            np.testing.assert_allclose(tri.X_W[a, b], one.X_W, rtol=0, atol=1e-10)
            np.testing.assert_allclose(tri.cov_W[a, b], one.cov_W, rtol=1e-9, atol=0)


def test_each_point_gives_the_same_bits_in_any_batch(cams3):
    """Gauss–Newton stops point by point: five mismatched tracks (slow, large steps) in the batch do
    not change the other points' estimates, bit for bit against each track triangulated alone."""
    K, T = cams3
    X = fy1_points(120, 0)
    uv = observe(X, K, T, SIGMA, 1)
    uv[:5, 2] += 40.0
    tri = triangulate(uv, K, T, pixel_sigma_px=SIGMA)
    for i in range(120):
        one = triangulate(uv[i:i + 1], K, T, pixel_sigma_px=SIGMA)
        np.testing.assert_array_equal(one.X_W[0], tri.X_W[i])
        np.testing.assert_array_equal(one.cov_W[0], tri.cov_W[i])
        assert one.failure_code[0] == tri.failure_code[i]


def test_two_view_estimate_agrees_with_opencv_and_has_no_larger_reprojection_error(cams3):
    K, T = ring_cameras(2, distance_m=50.0, axis_angle_deg=10.0)
    rng = np.random.default_rng(3)
    X = fy1_points(200, rng)
    uv = observe(X, K, T, SIGMA, rng)
    tri = triangulate(uv, K, T, pixel_sigma_px=SIGMA)
    P1, P2 = K[0] @ T[0, :3], K[1] @ T[1, :3]
    Xh = cv2.triangulatePoints(P1, P2, uv[:, 0].T.copy(), uv[:, 1].T.copy())
    X_cv = (Xh[:3] / Xh[3]).T
    # both are consistent estimators: they differ by much less than the depth σ (≈ 7 cm)
    assert np.max(np.linalg.norm(X_cv - tri.X_W, axis=-1)) < 0.02

    def reproj(Xe):
        out = 0.0
        for k in range(2):
            p = (K[k] @ (T[k, :3, :3] @ Xe.T + T[k, :3, 3:])).T
            out = out + np.sum((p[:, :2] / p[:, 2:] - uv[:, k]) ** 2, -1)
        return out

    # ours minimises the reprojection error (maximum likelihood), OpenCV's DLT does not
    assert np.all(reproj(tri.X_W) <= reproj(X_cv) + 1e-9)


def test_three_view_estimate_agrees_with_pycolmap_estimate_triangulation(cams3):
    K, T = cams3
    rng = np.random.default_rng(4)
    X = fy1_points(40, rng)
    uv = observe(X, K, T, SIGMA, rng)
    tri = triangulate(uv, K, T, pixel_sigma_px=SIGMA)
    cam = pycolmap.Camera(model="PINHOLE", width=1024, height=1024,
                          params=[K[0, 0, 0], K[0, 1, 1], K[0, 0, 2], K[0, 1, 2]])
    poses = [pycolmap.Rigid3d(T[k, :3, :]) for k in range(3)]
    opts = pycolmap.EstimateTriangulationOptions()
    opts.ransac.max_error = 5.0 / K[0, 0, 0]
    for m in range(len(X)):
        res = pycolmap.estimate_triangulation(uv[m], poses, [cam] * 3, opts)
        assert res is not None
        sd = np.sqrt(np.linalg.eigvalsh(tri.cov_W[m])[-1])
        # the same point to a fraction of the depth σ, and ours has the smaller pixel residual
        assert np.linalg.norm(res["xyz"] - tri.X_W[m]) < 0.3 * sd
        assert _reprojection(tri.X_W[m], uv[m], K, T) <= _reprojection(res["xyz"], uv[m], K, T)


def _reprojection(X, uv, K, T):
    from reconstruction._geometry import project

    uvp, _, _ = project(X[None, :], K, T)
    return float(np.sum((uvp - uv) ** 2))


def test_covariance_equals_cramer_rao_bound_at_the_truth(cams3):
    K, T = cams3
    rng = np.random.default_rng(5)
    X = fy1_points(100, rng)
    tri = triangulate(observe(X, K, T, SIGMA, rng), K, T, pixel_sigma_px=SIGMA)
    bound = point_covariance(X, K, T, pixel_sigma_px=SIGMA)
    # the depth variance scales like z⁴, so evaluating at the estimate instead of the truth
    # changes it by ~4 δz / z ≤ 4 · 3 σ_depth / 50 m ≈ 1.2 %: whitened by the bound, the
    # estimated covariance is the identity within 3 %
    L = np.linalg.cholesky(np.linalg.inv(bound))
    white = np.swapaxes(L, -1, -2) @ tri.cov_W @ L
    np.testing.assert_allclose(white, np.broadcast_to(np.eye(3), white.shape), atol=3e-2)
    lat, depth = np.sqrt(np.linalg.eigvalsh(bound[0]))[[0, 2]]
    assert 8.0 < depth / lat < 12.0  # the "ten times less certain in depth" of issue 6


def test_average_nees_lies_in_the_99_percent_band_over_100_trials(cams3):
    """100 trials × 200 points: mean NEES of 2·10⁴ points ~ χ²(6·10⁴)/2·10⁴ under consistency."""
    K, T = cams3
    rng = np.random.default_rng(6)
    X = fy1_points(200, rng, batch=(100,))
    tri = triangulate(observe(X, K, T, SIGMA, rng), K, T, pixel_sigma_px=SIGMA)
    e = tri.X_W - X
    nees = np.einsum("...i,...ij,...j->...", e, np.linalg.inv(tri.cov_W), e)[tri.valid]
    m = nees.size
    assert m > 0.99 * 2e4  # the 0.999 gate rejects ~0.1 % of good points
    lo, hi = chi2.ppf([0.005, 0.995], 3 * m) / m
    assert lo < np.mean(nees) < hi


def test_mismatched_view_is_dropped_and_the_point_kept_with_three_views(cams3):
    K, T = cams3
    rng = np.random.default_rng(7)
    X = fy1_points(100, rng)
    uv = observe(X, K, T, SIGMA, rng)
    bad = np.arange(0, 100, 5)
    uv[bad, 1] += 25.0  # a 25 px mismatch in view 1 for 20 % of the tracks
    tri = triangulate(uv, K, T, pixel_sigma_px=SIGMA)
    assert np.all(tri.valid[bad])
    assert np.all(~tri.views_used[bad, 1]) and np.all(tri.n_views[bad] == 2)
    good = np.setdiff1d(np.arange(100), bad)
    assert np.mean(tri.n_views[good] == 3) > 0.97
    err = np.linalg.norm(tri.X_W[bad] - X[bad], axis=-1)
    assert np.max(err) < 5 * np.sqrt(np.max(np.linalg.eigvalsh(tri.cov_W[bad])))


def test_two_view_mismatch_is_rejected_by_the_chi_square_gate():
    K, T = ring_cameras(2, distance_m=50.0, axis_angle_deg=10.0)
    rng = np.random.default_rng(8)
    X = fy1_points(50, rng)
    uv = observe(X, K, T, SIGMA, rng)
    uv[:10, 1, 0] += 20.0  # across the epipolar lines (which run along v here) by 20 px
    tri = triangulate(uv, K, T, pixel_sigma_px=SIGMA)
    assert np.all(tri.failure_code[:10] == FAILURE_REPROJECTION)
    assert np.all(np.isnan(tri.X_W[:10]))
    assert np.mean(tri.valid[10:]) > 0.95


def test_paper_threshold_on_rms_reprojection_rejects_points_above_it(cams3):
    K, T = cams3
    rng = np.random.default_rng(9)
    X = fy1_points(200, rng)
    tri = triangulate(observe(X, K, T, 2.0, rng), K, T, pixel_sigma_px=2.0,
                      max_rms_reprojection_px=1.0, drop_worst_view=False)
    assert np.all(tri.rms_reprojection_px[tri.valid] <= 1.0)
    assert np.all(tri.rms_reprojection_px[tri.failure_code == FAILURE_REPROJECTION] > 1.0 - 1e-12)


def test_points_behind_the_cameras_are_reported_not_triangulated():
    K, T = ring_cameras(3, distance_m=50.0, axis_angle_deg=10.0)
    X = fy1_points(20, 0)
    C = np.array([-(Tk[:3, :3].T @ Tk[:3, 3]) for Tk in T])  # camera centres
    X_behind = 2.0 * C.mean(0) + 0.05 * X  # the mirror image of the target behind the cameras
    uv, _, _ = _project_signed(X_behind, K, T)
    tri = triangulate(uv, K, T, pixel_sigma_px=SIGMA)
    assert not tri.ok
    assert tri.failure_reason == "all points behind a camera"
    assert np.all(tri.failure_code == FAILURE_BEHIND_CAMERA)
    assert np.all(np.isnan(tri.X_W))


def _project_signed(X, K, T):
    from reconstruction._geometry import project

    return project(X[:, None, :], K[None], T[None])


def test_track_in_one_view_and_coincident_cameras_are_flagged():
    K, T = ring_cameras(3, distance_m=50.0, axis_angle_deg=10.0)
    X = fy1_points(6, 0)
    uv = observe(X, K, T, 0.0, 1)
    uv[0, 1:] = np.nan
    tri = triangulate(uv, K, T, pixel_sigma_px=SIGMA)
    assert tri.failure_code[0] == FAILURE_TOO_FEW_VIEWS and np.all(tri.valid[1:])
    Tsame = np.stack([T[0], T[0]])
    Ksame = np.stack([K[0], K[0]])
    uv2 = observe(X, Ksame, Tsame, 0.0, 1)
    tri2 = triangulate(uv2, Ksame, Tsame, pixel_sigma_px=SIGMA)
    assert np.all(tri2.failure_code == FAILURE_DEGENERATE)
    assert not tri2.ok and "degenerate" in tri2.failure_reason


def test_camera_weights_scale_each_views_sigma(cams3):
    K, T = cams3
    X = fy1_points(10, 0)
    uv = observe(X, K, T, 0.0, 1)
    a = triangulate(uv, K, T, pixel_sigma_px=SIGMA, camera_weights=[1.0, 1.0, 4.0])
    sig = np.array([SIGMA, SIGMA, SIGMA / 2.0]) * np.sqrt(np.mean([1.0, 1.0, 4.0]))
    b = triangulate(uv, K, T, pixel_sigma_px=np.broadcast_to(sig, (10, 3)))
    np.testing.assert_allclose(a.cov_W, b.cov_W, rtol=1e-10)


def test_bad_input_raises_value_error_naming_the_parameter(cams3):
    K, T = cams3
    uv = np.zeros((5, 3, 2))
    with pytest.raises(ValueError, match="uv_px"):
        triangulate(np.zeros((5, 3)), K, T, pixel_sigma_px=1.0)
    with pytest.raises(ValueError, match="pixel_sigma_px"):
        triangulate(uv, K, T, pixel_sigma_px=0.0)
    with pytest.raises(ValueError, match="K, T_CW"):
        triangulate(np.zeros((5, 2, 2)), K, T, pixel_sigma_px=1.0)
    Tb = T.copy()
    Tb[0, :3, :3] *= 2.0
    with pytest.raises(ValueError, match="T_CW"):
        triangulate(uv, K, Tb, pixel_sigma_px=1.0)
    with pytest.raises(ValueError, match="camera_weights"):
        triangulate(uv, K, T, pixel_sigma_px=1.0, camera_weights=[1.0, -1.0, 1.0])


def test_observation_wrapper_uses_its_fields_and_reports_its_failure_reason(cams3):
    from vision.observation import Observation

    K, T = cams3
    X = fy1_points(30, 0)
    uv = observe(X, K, T, SIGMA, 1)
    obs = Observation(uv_px=uv, descriptors=np.zeros((30, 8), np.float32), K=K, T_CW=T,
                      image_size=(1024, 1024), pixel_sigma_px=SIGMA,
                      feature_id=np.arange(30), X_T_true=X)
    tri = triangulate_from_observation(obs)
    np.testing.assert_allclose(tri.X_W, triangulate(uv, K, T, pixel_sigma_px=SIGMA).X_W)
    empty = Observation.empty(K, T, (1024, 1024), SIGMA, "target in Earth shadow")
    out = triangulate_from_observation(empty)
    assert not out.ok and "target in Earth shadow" in out.failure_reason
    with pytest.raises(ValueError, match="pixel_sigma_px"):
        triangulate_from_observation(Observation(
            uv_px=uv, descriptors=np.zeros((30, 8), np.float32), K=K, T_CW=T,
            image_size=(1024, 1024), pixel_sigma_px=0.0, feature_id=np.arange(30), X_T_true=X))
