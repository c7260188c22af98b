"""Cramér–Rao bounds: against a brute-force Fisher matrix, batching, monotonicity, degeneracy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from reconstruction._synthetic import fy1_points, ring_cameras
from reconstruction.accuracy import attitude_increment_crlb, point_covariance

SIGMA = 0.5


def _pixels(X, K, T):
    """Plain pinhole projection, written independently of the package: (M, 3) → (M, n, 2)."""
    out = []
    for Kk, Tk in zip(K, T, strict=True):
        Xc = X @ Tk[:3, :3].T + Tk[:3, 3]
        p = Xc @ Kk.T
        out.append(p[:, :2] / p[:, 2:])
    return np.stack(out, 1)


def _skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


@pytest.mark.parametrize("n_views", [2, 3])
def test_bound_equals_the_inverse_of_the_full_fisher_matrix_with_points_as_nuisance(n_views):
    """Full Fisher matrix of (δθ, δt, X₁..X_M) by central differences of both epochs' pixels;
    the 6×6 block of its inverse is the attitude-increment bound."""
    K, T = ring_cameras(n_views, distance_m=50.0, axis_angle_deg=10.0)
    rng = np.random.default_rng(0)
    M = 6
    X = fy1_points(M, rng)
    dR = Rotation.from_rotvec([0.01, -0.005, 0.008]).as_matrix()
    dt = np.array([0.1, -0.05, 0.02])

    def meas(theta):
        xi, Xs = theta[:6], theta[6:].reshape(M, 3)
        R = Rotation.from_rotvec(xi[:3]).as_matrix() @ dR
        Y = Xs @ R.T + dt + xi[3:]
        return np.concatenate([_pixels(Xs, K, T).ravel(), _pixels(Y, K, T).ravel()])

    theta0 = np.concatenate([np.zeros(6), X.ravel()])
    h = 1e-6
    J = np.stack([(meas(theta0 + h * e) - meas(theta0 - h * e)) / (2 * h)
                  for e in np.eye(theta0.size)], 1)
    F = J.T @ J / SIGMA**2
    full = np.linalg.inv(F)[:6, :6]
    b = attitude_increment_crlb(X, K, T, pixel_sigma_px=SIGMA, R_delta=dR, t_delta=dt)
    assert b.ok and b.n_points == M
    np.testing.assert_allclose(b.cov, full, rtol=2e-5, atol=1e-14)
    np.testing.assert_allclose(b.rms_angle_rad, np.sqrt(np.trace(full[:3, :3])), rtol=1e-5)

    # and the per-point triangulation bound is the inverse of the single-epoch point Fisher block
    Jp = np.stack([(_pixels(X + h * e, K, T) - _pixels(X - h * e, K, T)) / (2 * h)
                   for e in np.eye(3)], -1)  # (M, n, 2, 3)
    Fp = np.einsum("mnij,mnik->mjk", Jp, Jp) / SIGMA**2
    np.testing.assert_allclose(point_covariance(X, K, T, pixel_sigma_px=SIGMA),
                               np.linalg.inv(Fp), rtol=1e-6)


def test_many_observer_subsets_are_scored_in_one_call():
    K5, T5 = ring_cameras(5, distance_m=50.0, axis_angle_deg=10.0)
    X = fy1_points(200, 1)
    subsets = [(0, 1, 2), (0, 2, 4), (1, 3, 4), (0, 1, 3)]
    idx = np.array(subsets)
    batched = attitude_increment_crlb(X, K5[idx], T5[idx], pixel_sigma_px=SIGMA)
    assert batched.cov.shape == (4, 6, 6) and batched.ok.shape == (4,)
    for s, sub in enumerate(subsets):
        one = attitude_increment_crlb(X, K5[list(sub)], T5[list(sub)], pixel_sigma_px=SIGMA)
        np.testing.assert_allclose(batched.cov[s], one.cov, rtol=1e-12)


def test_adding_an_observer_never_loosens_the_bound():
    K, T = ring_cameras(4, distance_m=50.0, axis_angle_deg=10.0)
    rng = np.random.default_rng(2)
    X = fy1_points(100, rng, batch=(20,)) @ Rotation.random(20, random_state=rng).as_matrix()
    three = attitude_increment_crlb(X, K[:3], T[:3], pixel_sigma_px=SIGMA)
    four = attitude_increment_crlb(X, K, T, pixel_sigma_px=SIGMA)
    # cov(4 views) ⪯ cov(3 views): the difference is positive semi-definite
    ev = np.linalg.eigvalsh(three.cov - four.cov)
    assert np.all(ev > -1e-12 * np.max(np.abs(ev)))
    assert np.all(four.rms_angle_rad < three.rms_angle_rad)


def test_bound_scales_linearly_with_pixel_sigma():
    K, T = ring_cameras(3, distance_m=50.0, axis_angle_deg=10.0)
    X = fy1_points(50, 3)
    a = attitude_increment_crlb(X, K, T, pixel_sigma_px=0.5)
    b = attitude_increment_crlb(X, K, T, pixel_sigma_px=1.5)
    np.testing.assert_allclose(b.rms_angle_rad, 3.0 * a.rms_angle_rad, rtol=1e-12)


def test_points_outside_the_image_or_in_one_view_carry_no_information():
    K, T = ring_cameras(2, distance_m=50.0, axis_angle_deg=10.0)
    X = fy1_points(30, 4)
    far = X + np.array([30.0, 0.0, 0.0])  # 30 m off-axis: outside a 20° field of view at 50 m
    both = np.concatenate([X, far])
    a = attitude_increment_crlb(both, K, T, pixel_sigma_px=SIGMA, image_size=(1024, 1024))
    b = attitude_increment_crlb(X, K, T, pixel_sigma_px=SIGMA)
    assert a.n_points == 30
    np.testing.assert_allclose(a.cov, b.cov, rtol=1e-12)
    vis = np.ones((30, 2), bool)
    vis[:10, 1] = False
    c = attitude_increment_crlb(X, K, T, pixel_sigma_px=SIGMA, visible=vis)
    d = attitude_increment_crlb(X[10:], K, T, pixel_sigma_px=SIGMA)
    assert c.n_points == 20
    np.testing.assert_allclose(c.cov, d.cov, rtol=1e-12)
    cov = point_covariance(X, K, T, pixel_sigma_px=SIGMA, visible=vis)
    assert np.all(np.isnan(cov[:10])) and np.all(np.isfinite(cov[10:]))


def test_too_few_or_collinear_points_are_reported_not_inverted():
    K, T = ring_cameras(3, distance_m=50.0, axis_angle_deg=10.0)
    X = np.array([[0.0, 0, 0], [1.0, 0, 0], [0, 1.0, 0], [2.0, 2.0, 0.5]])
    line = np.linspace(-1, 1, 5)[:, None] * np.array([1.0, 0.5, 0.2])
    batch = np.stack([X, X, line[:4]])
    batch[1, 2:] = [30.0, 30.0, 0.0]  # two of the four points outside the field of view
    b = attitude_increment_crlb(batch, K, T, pixel_sigma_px=SIGMA, image_size=(1024, 1024))
    assert list(b.ok) == [True, False, False]
    assert "fewer than 3 points" in b.failure_reason[1]
    assert b.failure_reason[2] == "points are collinear"
    assert np.all(np.isnan(b.cov[1:]))


def test_bad_arguments_raise_value_error_naming_them():
    K, T = ring_cameras(2, distance_m=50.0, axis_angle_deg=10.0)
    X = fy1_points(10, 5)
    with pytest.raises(ValueError, match="pixel_sigma_px"):
        attitude_increment_crlb(X, K, T, pixel_sigma_px=-1.0)
    with pytest.raises(ValueError, match="X_W"):
        attitude_increment_crlb(X[:, :2], K, T, pixel_sigma_px=1.0)
    with pytest.raises(ValueError, match="visible"):
        attitude_increment_crlb(X, K, T, pixel_sigma_px=1.0, visible=np.ones((3, 2), bool))
    with pytest.raises(ValueError, match="T_CW"):
        attitude_increment_crlb(X, K, T[:1], pixel_sigma_px=1.0)
