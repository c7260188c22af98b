"""Rigid registration: closed form vs SVD/scipy/pycolmap, RANSAC, ML with covariance, Open3D."""

from __future__ import annotations

import numpy as np
import pycolmap
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from attitude.batch import rotvecs_from_matrices
from reconstruction._geometry import proper_rotation_from_svd
from reconstruction._synthetic import fy1_points, observe, ring_cameras
from reconstruction.accuracy import attitude_increment_crlb
from reconstruction.registration import (
    fit_rigid,
    fit_rigid_ml,
    fit_rigid_robust,
    register_fpfh_ransac,
    register_icp,
)
from reconstruction.triangulation import triangulate


def _random_motion(rng, batch=()):
    R = Rotation.random(int(np.prod(batch, dtype=int)) or 1, random_state=rng).as_matrix()
    R = R.reshape(batch + (3, 3)) if batch else R[0]
    t = rng.uniform(-10, 10, batch + (3,))
    return R, t


def _apply(R, t, P):
    return P @ np.swapaxes(R, -1, -2) + t[..., None, :]


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(3, 60),
       scale=st.floats(1e-2, 1e3), offset=st.floats(-1e5, 1e5))
def test_exact_motion_is_recovered_for_any_rotation_scale_and_offset(seed, n, scale, offset):
    rng = np.random.default_rng(seed)
    R, t = _random_motion(rng)
    P = offset + scale * rng.standard_normal((n, 3))
    fit = fit_rigid(P, _apply(R, t, P))
    assert fit.ok
    np.testing.assert_allclose(fit.R, R, atol=1e-8)
    np.testing.assert_allclose(fit.t, t, atol=1e-8 * (1 + abs(offset) + scale))
    assert abs(np.linalg.det(fit.R) - 1.0) < 1e-12


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(3, 40), noise=st.floats(0.0, 2.0))
def test_weighted_fit_equals_the_svd_solution_of_000_eq_37(seed, n, noise):
    """Horn's quaternion route gives U diag(1, 1, det UVᵀ) Vᵀ (flag P000-10 (docs/papers.md#p000-10)), reflections too."""
    rng = np.random.default_rng(seed)
    P = rng.standard_normal((n, 3))
    Q = rng.standard_normal((n, 3)) * noise + P @ np.diag([1.0, 1.0, rng.choice([-1.0, 1.0])])
    w = rng.uniform(0.1, 2.0, n)
    fit = fit_rigid(P, Q, w)
    pb, qb = w @ P / w.sum(), w @ Q / w.sum()
    B = ((Q - qb) * w[:, None]).T @ (P - pb)
    R_svd = proper_rotation_from_svd(B)
    _, s, _ = np.linalg.svd(B)
    if s[1] > 1e-6 * s[0] and s[1] - s[2] > 1e-6 * s[0]:  # unique optimum
        np.testing.assert_allclose(fit.R, R_svd, atol=1e-7)
    # the attained objective tr(Rᵀ B) is the optimum in every case
    assert np.trace(fit.R.T @ B) >= np.trace(R_svd.T @ B) - 1e-9 * s[0]
    assert abs(np.linalg.det(fit.R) - 1.0) < 1e-10


def test_weighted_fit_matches_scipy_align_vectors():
    rng = np.random.default_rng(1)
    P = rng.standard_normal((30, 3))
    R, t = _random_motion(rng)
    Q = _apply(R, t, P) + 0.1 * rng.standard_normal((30, 3))
    w = rng.uniform(0.1, 3.0, 30)
    fit = fit_rigid(P, Q, w)
    pb, qb = w @ P / w.sum(), w @ Q / w.sum()
    rot, _ = Rotation.align_vectors(Q - qb, P - pb, weights=w)
    np.testing.assert_allclose(fit.R, rot.as_matrix(), atol=1e-9)
    np.testing.assert_allclose(fit.t, qb - fit.R @ pb, atol=1e-9)


def test_batched_fit_matches_a_loop_of_pycolmap_estimate_rigid3d():
    rng = np.random.default_rng(2)
    R, t = _random_motion(rng, (50,))
    P = rng.uniform(-3, 3, (50, 200, 3))
    Q = _apply(R, t, P) + 0.01 * rng.standard_normal(P.shape)
    fit = fit_rigid(P, Q)
    assert fit.R.shape == (50, 3, 3) and np.all(fit.ok)
    for b in range(50):
        ref = pycolmap.estimate_rigid3d(P[b], Q[b])
        np.testing.assert_allclose(fit.R[b], ref.rotation.matrix(), atol=1e-10)
        np.testing.assert_allclose(fit.t[b], ref.translation, atol=1e-9)
    res = Q - _apply(fit.R, fit.t, P)
    # rms_m comes from the second moments (no residual pass): exact to rounding of Σ|p̃|²
    np.testing.assert_allclose(fit.rms_m, np.sqrt(np.mean(np.sum(res**2, -1), -1)), rtol=1e-8)


def test_nan_rows_are_ignored_like_absent_points():
    rng = np.random.default_rng(3)
    R, t = _random_motion(rng)
    P = rng.standard_normal((20, 3))
    Q = _apply(R, t, P)
    P2 = P.copy()
    P2[[2, 5]] = np.nan
    Q2 = Q.copy()
    Q2[7] = np.nan
    fit = fit_rigid(P2, Q2)
    assert fit.ok and fit.n_inliers == 17
    np.testing.assert_allclose(fit.R, R, atol=1e-10)
    assert not fit.inliers[2] and not fit.inliers[7]


def test_degenerate_inputs_report_failure_inside_a_batch():
    rng = np.random.default_rng(4)
    P = rng.standard_normal((3, 10, 3))
    P[1, 2:] = np.nan  # two usable points
    P[2] = np.linspace(0, 1, 10)[:, None] * np.array([1.0, 2.0, 3.0])  # collinear
    Q = P + 1.0
    fit = fit_rigid(P, Q)
    assert list(fit.ok) == [True, False, False]
    assert fit.failure_reason[1] == "fewer than 3 usable points"
    assert fit.failure_reason[2] == "points are collinear"
    assert np.all(np.isnan(fit.R[1:])) and np.all(np.isnan(fit.t[1:]))
    rob = fit_rigid_robust(P, Q, threshold_m=0.1, rng=0)
    assert list(rob.ok) == [True, False, False]
    cov = np.broadcast_to(1e-4 * np.eye(3), P.shape + (3,))
    ml = fit_rigid_ml(P, Q, cov, cov, rng=0)
    assert list(ml.ok) == [True, False, False]
    assert np.all(np.isnan(ml.cov[1:]))


def test_bad_arguments_raise_value_error_naming_them():
    P = np.zeros((5, 3))
    with pytest.raises(ValueError, match="P"):
        fit_rigid(np.zeros((5, 2)), P)
    with pytest.raises(ValueError, match="weights"):
        fit_rigid(P, P, -np.ones(5))
    with pytest.raises(ValueError, match="threshold_m"):
        fit_rigid_robust(P, P)
    with pytest.raises(ValueError, match="cov_P, cov_Q"):
        fit_rigid_robust(P, P, cov_P=np.zeros((5, 3, 3)))
    with pytest.raises(ValueError, match="gate_probability"):
        fit_rigid_ml(P, P, np.zeros((5, 3, 3)), np.zeros((5, 3, 3)), gate_probability=1.5)


def test_ransac_recovers_motion_with_40_percent_gross_outliers_and_flags_them():
    rng = np.random.default_rng(5)
    R, t = _random_motion(rng, (20,))
    P = rng.uniform(-2, 2, (20, 100, 3))
    Q = _apply(R, t, P) + 0.005 * rng.standard_normal(P.shape)
    out = rng.random((20, 100)) < 0.4
    Q[out] = rng.uniform(-12, 12, (out.sum(), 3))
    fit = fit_rigid_robust(P, Q, threshold_m=0.03, rng=6)
    assert np.all(fit.ok)
    ang = np.linalg.norm(rotvecs_from_matrices(R @ np.swapaxes(fit.R, -1, -2)), axis=-1)
    assert np.max(ang) < 2e-3
    assert np.mean(fit.inliers[out]) < 0.01 and np.mean(fit.inliers[~out]) > 0.99
    again = fit_rigid_robust(P, Q, threshold_m=0.03, rng=6)
    np.testing.assert_array_equal(again.inliers, fit.inliers)


def _scene(n_views, n_trials, rng, n_points=200):
    K, T = ring_cameras(n_views, distance_m=50.0, axis_angle_deg=10.0)
    X = fy1_points(n_points, rng, batch=(n_trials,)) @ np.swapaxes(
        Rotation.random(n_trials, random_state=rng).as_matrix(), -1, -2)
    dR = Rotation.from_rotvec(np.radians(0.866) * Rotation.random(
        n_trials, random_state=rng).apply([1.0, 0, 0])).as_matrix()
    X1 = X @ np.swapaxes(dR, -1, -2)
    tri0 = triangulate(observe(X, K, T, 0.5, rng), K, T, pixel_sigma_px=0.5)
    tri1 = triangulate(observe(X1, K, T, 0.5, rng), K, T, pixel_sigma_px=0.5)
    return K, T, X, dR, tri0, tri1


@pytest.fixture(scope="module")
def scene3():
    return _scene(3, 150, np.random.default_rng(7))


def _rms_deg(dR, R):
    e = rotvecs_from_matrices(dR @ np.swapaxes(R, -1, -2))
    return np.degrees(np.sqrt(np.mean(np.sum(e * e, -1)))), e


def test_ml_fit_reaches_the_cramer_rao_bound_and_scalar_weights_do_not(scene3):
    """150 trials: the RMS of ‖δθ‖ (3 dof each) has a relative σ of about 1/√(2·450) ≈ 3.3 %."""
    K, T, X, dR, tri0, tri1 = scene3
    ml = fit_rigid_ml(tri0.X_W, tri1.X_W, tri0.cov_W, tri1.cov_W, robust=False)
    ml_rms, _ = _rms_deg(dR, ml.R)
    bound = attitude_increment_crlb(X, K, T, pixel_sigma_px=0.5, R_delta=dR)
    crlb_rms = np.degrees(np.sqrt(np.mean(bound.rms_angle_rad**2)))
    assert 0.90 < ml_rms / crlb_rms < 1.10
    sc = fit_rigid(tri0.X_W, tri1.X_W, tri0.weight * tri1.weight)
    sc_rms, _ = _rms_deg(dR, sc.R)
    assert sc_rms > 3.0 * ml_rms


def test_ml_covariance_is_consistent_with_its_errors(scene3):
    """Mean 6-dof NEES of 150 trials inside the 99 % band of χ²(900)/150."""
    K, T, X, dR, tri0, tri1 = scene3
    ml = fit_rigid_ml(tri0.X_W, tri1.X_W, tri0.cov_W, tri1.cov_W, robust=False)
    _, e = _rms_deg(dR, ml.R)
    d = np.concatenate([e, -ml.t], -1)
    nees = np.einsum("...i,...ij,...j->...", d, np.linalg.inv(ml.cov), d)
    lo, hi = chi2.ppf([0.005, 0.995], 6 * 150) / 150
    assert lo < np.mean(nees) < hi
    # the bound evaluated at the estimate is the returned covariance
    np.testing.assert_allclose(ml.rotation_sigma_rad,
                               attitude_increment_crlb(X, K, T, pixel_sigma_px=0.5,
                                                       R_delta=dR).rms_angle_rad, rtol=0.05)


def test_robust_ml_with_30_percent_added_false_matches_stays_within_20_percent(scene3):
    K, T, X, dR, tri0, tri1 = scene3
    rng = np.random.default_rng(8)
    n_out = 86  # 30 % of 286 correspondences
    i = rng.integers(0, 200, (150, n_out))
    j = (i + rng.integers(1, 200, (150, n_out))) % 200
    tk = np.take_along_axis
    P = np.concatenate([tri0.X_W, tk(tri0.X_W, i[..., None], 1)], 1)
    Q = np.concatenate([tri1.X_W, tk(tri1.X_W, j[..., None], 1)], 1)
    cP = np.concatenate([tri0.cov_W, tk(tri0.cov_W, i[..., None, None], 1)], 1)
    cQ = np.concatenate([tri1.cov_W, tk(tri1.cov_W, j[..., None, None], 1)], 1)
    clean = fit_rigid_ml(tri0.X_W, tri1.X_W, tri0.cov_W, tri1.cov_W, robust=False)
    rob = fit_rigid_ml(P, Q, cP, cQ, robust=True, rng=9)
    assert np.all(rob.ok)
    r_clean, _ = _rms_deg(dR, clean.R)
    r_rob, _ = _rms_deg(dR, rob.R)
    assert r_rob < 1.2 * r_clean
    assert np.mean(rob.inliers[:, 200:]) < 0.01  # false matches rejected
    assert np.mean(rob.inliers[:, :200]) > 0.98  # true ones kept (gate at 99.73 %)


def test_ml_with_isotropic_equal_covariances_equals_kabsch():
    rng = np.random.default_rng(10)
    R, t = _random_motion(rng)
    P = rng.standard_normal((40, 3))
    Q = _apply(R, t, P) + 0.01 * rng.standard_normal((40, 3))
    cov = np.broadcast_to(1e-4 * np.eye(3), (40, 3, 3))
    ml = fit_rigid_ml(P, Q, cov, cov, robust=False)
    kb = fit_rigid(P, Q)
    np.testing.assert_allclose(ml.R, kb.R, atol=1e-10)
    np.testing.assert_allclose(ml.t, kb.t, atol=1e-10)
    # isotropic covariance σ²(1+1): rotation covariance (Σ [R x̃×]ᵀ[R x̃×] / 2σ²)⁻¹ about the best
    # estimate of the true points, x̂ = (P + Rᵀ(Q − t)) / 2, centred
    X = 0.5 * (P + (Q - ml.t) @ ml.R)
    Pc = (X - X.mean(0)) @ ml.R.T
    Hrot = sum((np.cross(np.eye(3), p).T @ np.cross(np.eye(3), p)) for p in Pc) / 2e-4
    np.testing.assert_allclose(ml.cov[:3, :3], np.linalg.inv(Hrot), rtol=1e-6)


def test_ml_consistent_with_clouds_elongated_along_the_line_of_sight():
    """Both clouds' covariances elongated 10:1 along one fixed direction of H (the line of sight of a
    small-baseline formation) while the target turns 20° between the epochs: over 400 noise draws the
    fit's rotation error has NEES within 10 % of 3 against its own covariance.  (With the noisy lever
    arms R P, iteratively reweighted least squares, the mean NEES here was 4.9.)"""
    rng = np.random.default_rng(3)
    N, draws = 30, 400
    X_T = rng.uniform(-0.5, 0.5, (N, 3))
    R = Rotation.from_rotvec(np.radians(20.0) * np.array([0.6, 0.8, 0.0])).as_matrix()
    t = np.array([0.1, -0.2, 0.05])
    cov = np.broadcast_to(np.diag([0.01, 0.01, 0.1]) ** 2, (N, 3, 3))
    L = np.linalg.cholesky(cov[0])
    P = X_T + rng.standard_normal((draws, N, 3)) @ L.T
    Q = _apply(R, t, X_T) + rng.standard_normal((draws, N, 3)) @ L.T
    fit = fit_rigid_ml(P, Q, np.broadcast_to(cov, (draws, N, 3, 3)), np.broadcast_to(cov, (draws, N, 3, 3)),
                       robust=False)
    e = rotvecs_from_matrices(fit.R @ R.T)
    nees = np.einsum("ri,rij,rj->r", e, np.linalg.inv(fit.cov[:, :3, :3]), e)
    assert abs(nees.mean() / 3.0 - 1.0) < 0.10, nees.mean()


def _box_cloud(rng, n=3000):
    """Dense samples on the surface of an asymmetric box (3 × 2 × 1 m)."""
    half = np.array([1.5, 1.0, 0.5])
    face = rng.integers(0, 6, n)
    pts = rng.uniform(-1, 1, (n, 3)) * half
    ax = face // 2
    pts[np.arange(n), ax] = np.where(face % 2 == 0, 1.0, -1.0) * half[ax]
    return pts


def test_open3d_icp_refines_a_small_unknown_correspondence_motion():
    rng = np.random.default_rng(11)
    P = _box_cloud(rng)
    R = Rotation.from_rotvec([0.02, -0.03, 0.05]).as_matrix()
    t = np.array([0.05, -0.02, 0.03])
    Q = _apply(R, t, _box_cloud(np.random.default_rng(12)))  # different samples of the surface
    fit = register_icp(P, Q, max_correspondence_m=0.3)
    assert fit.ok and fit.method == "icp"
    ang = np.linalg.norm(rotvecs_from_matrices(R @ fit.R.T))
    assert ang < np.radians(0.5)
    assert np.linalg.norm(fit.t - t) < 0.03


def test_open3d_fpfh_ransac_recovers_a_large_rotation_without_correspondences():
    rng = np.random.default_rng(13)
    P = _box_cloud(rng, 6000)
    R = Rotation.from_rotvec([0.6, -1.1, 0.8]).as_matrix()
    t = np.array([2.0, -1.0, 0.5])
    Q = _apply(R, t, P[rng.permutation(len(P))]) + 0.002 * rng.standard_normal(P.shape)
    fit = register_fpfh_ransac(P, Q, voxel_size_m=0.1, rng=14)
    assert fit.ok and fit.method == "fpfh_ransac"
    ang = np.linalg.norm(rotvecs_from_matrices(R @ fit.R.T))
    assert ang < np.radians(1.0)
    assert np.linalg.norm(fit.t - t) < 0.05
    few = register_icp(P[:2], Q, max_correspondence_m=0.3)
    assert not few.ok and "fewer than 3" in few.failure_reason


def test_coincident_points_are_reported_not_fitted():
    """All points of P at one place (far from the origin): the rotation is undetermined."""
    rng = np.random.default_rng(5)
    P = np.tile(np.array([1000.0, -250.0, 40.0]), (50, 1)) + 1e-13 * rng.normal(size=(50, 3))
    Q = rng.normal(size=(50, 3))
    res = fit_rigid(P, Q)
    assert not res.ok
    assert "coincident" in str(res.failure_reason)
    assert np.all(np.isnan(res.R))


def _reference_batch(rng, B, N):
    """Noisy motions with weights (20% zero), NaN rows in either cloud, and at the front the
    special problems: 2 usable points, collinear, coincident, all weights zero, a cloud 10⁴ m
    from the origin for 1 m of spread (the compiled kernel's second, centred pass)."""
    R, t = _random_motion(rng, (B,))
    P = rng.uniform(-2.0, 2.0, (B, N, 3))
    Q = _apply(R, t, P) + 0.05 * rng.standard_normal(P.shape)
    w = rng.uniform(0.1, 2.0, (B, N))
    w[rng.random((B, N)) < 0.2] = 0.0
    P[rng.random((B, N)) < 0.05] = np.nan
    Q[rng.random((B, N)) < 0.05, 1] = np.nan
    P[0, 2:] = np.nan
    P[1] = np.linspace(-1.0, 1.0, N)[:, None] * np.array([1.0, -2.0, 0.5])
    Q[1] = P[1] + 1.0
    P[2] = np.array([3.0, -1.0, 2.0]) + 1e-14 * rng.standard_normal((N, 3))
    w[3] = 0.0
    P[4] += 1e4
    Q[4] = _apply(R[4], t[4], P[4]) + 0.05 * rng.standard_normal((N, 3))
    return P, Q, w


@pytest.mark.parametrize("weighted", [True, False])
def test_compiled_kabsch_matches_the_numpy_reference_with_weights_nan_rows_and_degeneracies(
        weighted):
    """The Numba kernel behind ``fit_rigid`` against the NumPy path it replaced, problem by
    problem: same failure codes, usable-point counts and row masks; R, t, RMS to rounding."""
    from reconstruction.registration.kabsch import kabsch_flat, kabsch_flat_numpy

    P, Q, w = _reference_batch(np.random.default_rng(11), 600, 40)
    w = w if weighted else None
    R, t, code, npts, rms, rows = kabsch_flat(P, Q, w)
    R0, t0, code0, npts0, rms0, rows0 = kabsch_flat_numpy(P, Q, w)
    np.testing.assert_array_equal(code, code0)
    assert list(code[:4]) == [1, 2, 3, 1 if weighted else 0] and np.all(code[4:] == 0)
    np.testing.assert_array_equal(npts, npts0)
    np.testing.assert_array_equal(rows, rows0)
    ok = code == 0
    assert np.all(np.isnan(R[~ok])) and np.all(np.isnan(t[~ok])) and np.all(np.isnan(rms[~ok]))
    np.testing.assert_allclose(R[ok], R0[ok], rtol=0, atol=1e-9)
    scale = 1.0 + np.abs(t0[ok]).max(axis=-1, keepdims=True)  # problem 4: t ~ 10⁴ m
    assert np.all(np.abs(t[ok] - t0[ok]) < 1e-9 * scale)
    # rms comes from G − 2 tr(R S), which cancels ~3 digits at this noise: 1e-9 of G/Σw
    np.testing.assert_allclose(rms[ok], rms0[ok], rtol=1e-8)


def test_compiled_kabsch_recovers_motion_far_from_the_origin():
    """Clouds 10⁶ m away with 1 m of spread: raw moments alone would lose 12 digits; the
    kernel's centred second pass keeps the exact motion (analytic truth)."""
    rng = np.random.default_rng(12)
    R, t = _random_motion(rng, (20,))
    P = 1e6 * np.array([1.0, -0.5, 0.3]) + rng.standard_normal((20, 30, 3))
    fit = fit_rigid(P, _apply(R, t, P))
    assert np.all(fit.ok)
    np.testing.assert_allclose(fit.R, R, atol=1e-9)
    np.testing.assert_allclose(fit.rms_m, 0.0, atol=1e-6)


def test_ill_determined_quaternions_fall_back_to_the_svd_with_an_optimal_fit():
    """Q = −P for a cloud with two equal principal moments: two 180° rotations fit equally well,
    the quaternion eigenvector is ill-determined for some orientations and those problems go
    to the SVD reference; every fit is a proper rotation with the optimal (equal) residual."""
    from reconstruction.registration import _kabsch_kernel
    from reconstruction.registration.kabsch import kabsch_flat_numpy, readonly_c

    base = np.array([[2.0, 0, 0], [-2, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
    Rr = Rotation.random(2000, random_state=13).as_matrix()
    P = base @ np.swapaxes(Rr, -1, -2)
    Q = -P
    flags = np.empty(2000, np.uint8)
    out = (np.empty((2000, 3, 3)), np.empty((2000, 3)), np.empty(2000), np.empty(2000, np.int8),
           np.empty(2000, np.int64), flags)
    _kabsch_kernel.kabsch_batch(readonly_c(P.reshape(2000, -1)), readonly_c(Q.reshape(2000, -1)),
                                readonly_c(np.zeros((1, 6))), False, *out)
    assert np.count_nonzero(flags & _kabsch_kernel.FLAG_SVD) > 0
    fit = fit_rigid(P, Q)
    assert np.all(fit.ok)
    np.testing.assert_allclose(np.linalg.det(fit.R), 1.0, atol=1e-12)
    _, _, _, _, rms0, _ = kabsch_flat_numpy(P, Q, None)
    np.testing.assert_allclose(fit.rms_m, rms0, rtol=1e-9)
    # the optimum, a 180° turn about a minor axis: R p + p = 2 p_minor, Σ = 2 · 2² over 6 points
    np.testing.assert_allclose(fit.rms_m, np.sqrt(8 / 6), rtol=1e-9)


def test_infinite_coordinates_raise_value_error():
    P = np.random.default_rng(14).standard_normal((4, 10, 3))
    P[2, 3, 1] = np.inf
    with pytest.raises(ValueError, match="infinite"):
        fit_rigid(P, P)
    with pytest.raises(ValueError, match="infinite"):
        fit_rigid(P, P, np.ones(10))


def test_qcp_kernel_matches_the_svd_rotation_for_random_and_reflected_correlations():
    """The one Horn/QCP kernel against an independent oracle, the SVD solution
    ``U diag(1, 1, det UVᵀ) Vᵀ`` of 000 eq (37): random correlations, reflected ones (det S < 0),
    rank 2; rank ≤ 1 is flagged collinear and a non-finite S gives NaN."""
    from reconstruction.registration.qcp import rotations_from_correlations

    rng = np.random.default_rng(21)
    S = rng.standard_normal((500, 3, 3))
    S[100:200] *= np.array([1.0, 1.0, -1.0])  # a column flipped: det S changes sign
    S[200:250, :, 2] = S[200:250, :, :2] @ np.array([0.3, -0.7])  # rank 2
    S[250] = np.outer([1.0, 2.0, -1.0], [0.5, 0.0, 1.0])  # rank 1
    S[251, 1, 2] = np.nan
    G = np.sqrt(np.einsum("bij,bij->b", S, S)) * 3.0  # any upper bound of λ_max is valid
    R, collinear = rotations_from_correlations(S, G)
    oracle = proper_rotation_from_svd(np.swapaxes(S, -1, -2))
    full = np.r_[0:250, 252:500]
    np.testing.assert_allclose(R[full], oracle[full], rtol=0, atol=1e-10)
    np.testing.assert_allclose(np.linalg.det(R[full]), 1.0, atol=1e-12)
    assert not np.any(collinear[full]) and collinear[250] and collinear[251]
    assert np.all(np.isnan(R[251]))


# ---------------------------------------------------------------- garbage in (issue 17)
def _cloud(n=12, seed=3):
    rng = np.random.default_rng(seed)
    P = rng.normal(size=(n, 3))
    R = Rotation.from_rotvec([0.2, -0.4, 0.3]).as_matrix()
    return P, P @ R.T + [1.0, 2.0, 3.0], R


@pytest.mark.parametrize("shape", [(0, 3), (4, 0, 3)])
def test_empty_clouds_give_ok_false_with_too_few_points_in_every_fit(shape):
    P = np.zeros(shape)
    cov = np.zeros(shape + (3,))
    fits = [fit_rigid(P, P), fit_rigid_robust(P, P, threshold_m=0.1, rng=0),
            fit_rigid_ml(P, P, cov, cov, rng=0)]
    for fit in fits:
        assert np.all(~np.asarray(fit.ok))
        assert np.all(np.asarray(fit.failure_reason) == "fewer than 3 usable points")
        assert np.shape(fit.ok) == shape[:-2]


@pytest.mark.parametrize("scale", [1e155, 1e200])
def test_coordinates_whose_squares_overflow_are_refused_as_too_large_not_collinear(scale):
    P, Q, _ = _cloud()
    cov = np.broadcast_to(1e-4 * np.eye(3), P.shape + (3,))
    for fit in (lambda: fit_rigid(P * scale, Q * scale),
                lambda: fit_rigid_robust(P * scale, Q * scale, threshold_m=0.1, rng=0),
                lambda: fit_rigid_ml(P * scale, Q * scale, cov, cov, rng=0)):
        with pytest.raises(ValueError, match=r"^P, Q: coordinates too large"):
            fit()


@pytest.mark.parametrize("scale", [1e-30, 1e25, 1e28])
def test_clouds_at_extreme_but_accepted_scales_give_the_right_rotation(scale):
    """Up to 1e28 the QCP quartic overflowed (R = I reported with ok=True at 1e25): the SVD takes over."""
    P, Q, R = _cloud()
    for fit in (fit_rigid(P * scale, Q * scale), fit_rigid(P * scale, Q * scale, np.full(12, 2.0))):
        assert fit.ok
        np.testing.assert_allclose(fit.R, R, atol=1e-12)


@pytest.mark.parametrize(("cov_P", "cov_Q", "name"), [
    (-1e-4 * np.eye(3), 1e-4 * np.eye(3), "cov_P: not symmetric positive semi-definite"),
    (1e-4 * np.eye(3), np.diag([1e-4, -1e-6, 1e-4]), "cov_Q: not symmetric positive semi-definite"),
    (1e-4 * np.eye(3), [[1e-4, 1e-5, 0], [0, 1e-4, 0], [0, 0, 1e-4]], "cov_Q: not symmetric"),
    (np.zeros((3, 3)), np.diag([1e-4, 1e-4, 0.0]), r"cov_P, cov_Q: both singular"),
])
def test_covariances_that_are_not_positive_semi_definite_are_refused_naming_them(cov_P, cov_Q, name):
    P, Q, _ = _cloud()
    cP = np.broadcast_to(np.asarray(cov_P, float), P.shape + (3,))
    cQ = np.broadcast_to(np.asarray(cov_Q, float), P.shape + (3,))
    with pytest.raises(ValueError, match=rf"^{name}"):
        fit_rigid_ml(P, Q, cP, cQ, robust=False)
    with pytest.raises(ValueError, match=rf"^{name}"):
        fit_rigid_robust(P, Q, cov_P=cP, cov_Q=cQ, rng=0)


def test_a_nan_covariance_marks_an_absent_point_and_one_exact_cloud_is_accepted():
    P, Q, R = _cloud()
    cP = np.zeros(P.shape + (3,))  # exact source points, noisy targets: still invertible
    cQ = np.tile(1e-4 * np.eye(3), (12, 1, 1))
    cQ[5] = np.nan
    fit = fit_rigid_ml(P, Q, cP, cQ, robust=False)
    assert fit.ok and not fit.inliers[5] and fit.n_inliers == 11
    np.testing.assert_allclose(fit.R, R, atol=1e-9)
