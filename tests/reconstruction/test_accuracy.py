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


def _view_sets_that_change(M, rng):
    """Visibility (M, 3) at t and at t + Δt: every point in >= 2 of 3 views at both epochs, and
    every other point with a different view set at t + Δt (a view lost, gained or swapped)."""
    sets = np.array([[1, 1, 1], [1, 1, 0], [0, 1, 1], [1, 0, 1]], bool)
    a = rng.integers(0, 4, M)
    b = np.where(np.arange(M) % 2 == 0, (a + rng.integers(1, 4, M)) % 4, a)
    return sets[a], sets[b]


def test_per_epoch_visibility_equals_the_full_fisher_matrix_with_each_epochs_own_views():
    """003 eq (11)-(12) registers two clouds triangulated from each epoch's own views: the bound with
    ``visible`` at t and ``visible_next`` at t + Δt is the 6x6 block of the inverse of the full
    Fisher matrix of (δθ, δt, X₁..X_M) built by central differences from exactly the pixels that
    exist at each epoch; the one-mask bound (epoch t's views at both) is not."""
    K, T = ring_cameras(3, distance_m=50.0, axis_angle_deg=10.0)
    rng = np.random.default_rng(11)
    M = 8
    X = fy1_points(M, rng)
    vis0, vis1 = _view_sets_that_change(M, rng)
    assert np.any(vis0 != vis1)
    dR = Rotation.from_rotvec([0.01, -0.005, 0.008]).as_matrix()

    def meas(theta):
        xi, Xs = theta[:6], theta[6:].reshape(M, 3)
        Y = Xs @ (Rotation.from_rotvec(xi[:3]).as_matrix() @ dR).T + xi[3:]
        return np.concatenate([_pixels(Xs, K, T)[vis0].ravel(), _pixels(Y, K, T)[vis1].ravel()])

    theta0 = np.concatenate([np.zeros(6), X.ravel()])
    h = 1e-6
    J = np.stack([(meas(theta0 + h * e) - meas(theta0 - h * e)) / (2 * h) for e in np.eye(theta0.size)], 1)
    full = np.linalg.inv(J.T @ J / SIGMA**2)[:6, :6]
    b = attitude_increment_crlb(X, K, T, pixel_sigma_px=SIGMA, visible=vis0, visible_next=vis1, R_delta=dR)
    assert b.ok and b.n_points == M
    np.testing.assert_allclose(b.cov, full, rtol=2e-5, atol=1e-14)
    one_mask = attitude_increment_crlb(X, K, T, pixel_sigma_px=SIGMA, visible=vis0, visible_next=vis0,
                                       R_delta=dR)
    assert np.linalg.norm(one_mask.cov - full) > 0.05 * np.linalg.norm(full)
    # σ per epoch: the same Fisher matrix with the pixels of t + Δt weighted by 1/σ'²
    s1 = 1.7
    n0 = 2 * int(vis0.sum())
    w = np.concatenate([np.full(n0, 1 / SIGMA**2), np.full(J.shape[0] - n0, 1 / s1**2)])
    full_s = np.linalg.inv(J.T @ (w[:, None] * J))[:6, :6]
    bs = attitude_increment_crlb(X, K, T, pixel_sigma_px=SIGMA, pixel_sigma_px_next=s1, visible=vis0,
                                 visible_next=vis1, R_delta=dR)
    np.testing.assert_allclose(bs.cov, full_s, rtol=2e-5, atol=1e-14)


def test_per_epoch_bound_is_what_the_ml_fit_of_each_epochs_own_triangulation_reaches():
    """Monte Carlo, independent of the bound's algebra: 800 trials of 40 points on the FY-1-like body,
    3 views at 50 m, every point seen by all three at t and by two at t + Δt; each epoch's tracks
    triangulated from the views that see them then and registered by ``fit_rigid_ml``.  The RMS of
    ‖δθ‖ over 800 trials (3 dof each) has a relative σ of about 1/√(2·2400) ≈ 1.5 % (over seeds
    12–15 the ratio was 0.97–1.02), so 0.93–1.07 is a band of more than 3σ.  The one-mask bound
    (epoch t's three views at both epochs) is 10–16 % optimistic here and falls outside the band:
    the test tells the two apart."""
    from reconstruction._synthetic import observe
    from reconstruction.registration import fit_rigid_ml
    from reconstruction.triangulation import triangulate

    K, T = ring_cameras(3, distance_m=50.0, axis_angle_deg=10.0)
    rng = np.random.default_rng(12)
    n_trials, M = 800, 40
    X = fy1_points(M, rng, batch=(n_trials,)) @ np.swapaxes(Rotation.random(n_trials, random_state=rng).as_matrix(),
                                                            -1, -2)
    dR = Rotation.from_rotvec(np.radians(0.866) * Rotation.random(n_trials, random_state=rng).as_rotvec()
                              / np.pi).as_matrix()
    # all three views see every point at t; at t + Δt each point has lost one view
    vis0 = np.ones((n_trials, M, 3), bool)
    vis1 = vis0.copy()
    vis1[np.arange(n_trials)[:, None], np.arange(M), rng.integers(0, 3, (n_trials, M))] = False
    Y = X @ np.swapaxes(dR, -1, -2)
    uv0 = np.where(vis0[..., None], observe(X, K, T, SIGMA, rng), np.nan)
    uv1 = np.where(vis1[..., None], observe(Y, K, T, SIGMA, rng), np.nan)
    tri0 = triangulate(uv0, K, T, pixel_sigma_px=SIGMA, drop_worst_view=False, gate_probability=1 - 1e-12)
    tri1 = triangulate(uv1, K, T, pixel_sigma_px=SIGMA, drop_worst_view=False, gate_probability=1 - 1e-12)
    assert tri0.valid.all() and tri1.valid.all()
    ml = fit_rigid_ml(tri0.X_W, tri1.X_W, tri0.cov_W, tri1.cov_W, robust=False)
    e = Rotation.from_matrix(dR @ np.swapaxes(ml.R, -1, -2)).as_rotvec()
    ml_rms = np.sqrt(np.mean(np.sum(e * e, -1)))

    def bound_rms(v1):
        b = attitude_increment_crlb(X, K, T, pixel_sigma_px=SIGMA, visible=vis0, visible_next=v1, R_delta=dR)
        assert np.all(b.ok)
        return np.sqrt(np.mean(b.rms_angle_rad**2))

    per_epoch, one_mask = bound_rms(vis1), bound_rms(vis0)
    assert 0.93 < ml_rms / per_epoch < 1.07
    assert not 0.93 < ml_rms / one_mask < 1.07


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
    c = attitude_increment_crlb(X, K, T, pixel_sigma_px=SIGMA, visible=vis, visible_next=vis)
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
        attitude_increment_crlb(X, K, T, pixel_sigma_px=1.0, visible=np.ones((3, 2), bool),
                                visible_next=np.ones((3, 2), bool))
    with pytest.raises(ValueError, match="visible_next"):
        attitude_increment_crlb(X, K, T, pixel_sigma_px=1.0, visible=np.ones((10, 2), bool))
    with pytest.raises(ValueError, match="pixel_sigma_px_next"):
        attitude_increment_crlb(X, K, T, pixel_sigma_px=1.0, pixel_sigma_px_next=0.0)
    with pytest.raises(ValueError, match="T_CW"):
        attitude_increment_crlb(X, K, T[:1], pixel_sigma_px=1.0)
