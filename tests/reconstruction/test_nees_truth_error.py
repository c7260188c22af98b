"""Triangulation NEES against a truth point that carries its first view's keypoint error (issue 16).

The rendered mode's truth point is the surface point under the first view's keypoint.  On a plane
seen by ring cameras, with Gaussian keypoint noise of known σ, the NEES that accounts for the truth's
own error (:func:`experiments.studies.triangulation_consistency.nees_with_truth_error`) has mean 3
for tracks of two and of three views, while the plain statistic against the same truth is ≈ 5 for
three views (the first view's error counted twice); it matches its predicted expectation.
"""

import numpy as np
import pytest

from experiments.studies.triangulation_consistency import nees_with_truth_error, projection_jacobian
from reconstruction._synthetic import ring_cameras
from reconstruction.triangulation import triangulate


def _ray_plane(uv, K, T, n_W, c_W):
    """Points of the plane (normal n_W through c_W) seen through pixels uv (m, 2) of one camera."""
    R, t = T[:3, :3], T[:3, 3]
    centre = -R.T @ t
    d = (np.c_[uv, np.ones(len(uv))] @ np.linalg.inv(K).T) @ R        # ray directions in W
    s = ((c_W - centre) @ n_W) / (d @ n_W)
    return centre + s[:, None] * d


@pytest.mark.parametrize("n_views", [2, 3])
def test_nees_with_the_truth_points_error_is_three_where_the_plain_one_is_not(n_views):
    K, T = ring_cameras(n_views, distance_m=40.0, axis_angle_deg=10.0)
    rng = np.random.default_rng(5 + n_views)
    m = 4000
    n_W = np.array([0.3, -0.2, 1.0])
    n_W /= np.linalg.norm(n_W)
    a = np.cross(n_W, [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n_W, a)
    X = rng.uniform(-1.5, 1.5, (m, 1)) * a + rng.uniform(-1.5, 1.5, (m, 1)) * b
    sigma = rng.choice([0.12, 0.3], size=(m, n_views))
    uv = np.empty((m, n_views, 2))
    for k in range(n_views):
        X_C = X @ T[k, :3, :3].T + T[k, :3, 3]
        p = X_C @ K[k].T
        uv[:, k] = p[:, :2] / p[:, 2:] + sigma[:, k, None] * rng.normal(size=(m, 2))
    tri = triangulate(uv, K, T, pixel_sigma_px=sigma, gate_probability=1 - 1e-12)
    ok = tri.valid
    X_f = _ray_plane(uv[:, 0], K[0], T[0], n_W, np.zeros(3))             # the truth point: under view 0's keypoint
    h = 0.5
    lift = np.stack([(_ray_plane(uv[:, 0] + [h, 0], K[0], T[0], n_W, np.zeros(3))
                      - _ray_plane(uv[:, 0] - [h, 0], K[0], T[0], n_W, np.zeros(3))) / (2 * h),
                     (_ray_plane(uv[:, 0] + [0, h], K[0], T[0], n_W, np.zeros(3))
                      - _ray_plane(uv[:, 0] - [0, h], K[0], T[0], n_W, np.zeros(3))) / (2 * h)], axis=2)
    J = projection_jacobian(tri.X_W[ok], K, T)
    nees, plain, expected = nees_with_truth_error(tri.X_W[ok] - X_f[ok], J, sigma[ok], tri.views_used[ok],
                                                  np.zeros(ok.sum(), int), lift[ok])
    assert abs(nees.mean() - 3.0) < 0.2                         # ± 5 standard errors of the mean
    assert abs(plain.mean() / expected.mean() - 1.0) < 0.07
    if n_views == 3:
        assert plain.mean() > 4.0                               # the first view's error counted twice


@pytest.mark.parametrize("shared_fraction", [0.0, 0.5])
def test_increment_nees_is_three_for_independent_errors_and_drops_with_the_error_both_epochs_share(shared_fraction):
    """A feature's body-point error split into a part both epochs share (it moves with the body) and
    an independent part: the increment NEES with the full covariance is 3 × the independent fraction."""
    from types import SimpleNamespace

    from attitude.quaternion import matrix_from_quat, quat_from_rotvec
    from experiments.studies.nees_calibration import increment_nees

    rng = np.random.default_rng(3)
    m = 6000
    X_T = rng.uniform(-2.0, 2.0, (m, 3))
    q_a, q_b = quat_from_rotvec([0.3, -0.2, 0.5]), quat_from_rotvec([0.31, -0.19, 0.51])
    var = 1e-4                                                         # m² per axis, total
    shared = np.sqrt(shared_fraction * var) * rng.normal(size=(m, 3))
    frames = []
    for q in (q_a, q_b):
        R = matrix_from_quat(q)
        err_T = shared + np.sqrt((1 - shared_fraction) * var) * rng.normal(size=(m, 3))
        obs = SimpleNamespace(feature_id=np.arange(m), X_T_true=X_T)
        tri = SimpleNamespace(valid=np.ones(m, bool), X_W=(X_T + err_T) @ R.T,
                              cov_W=np.broadcast_to(var * np.eye(3), (m, 3, 3)))
        frames.append((obs, tri))
    v, ia = increment_nees(frames[0], frames[1], q_a, q_b, tol_m=1e-6)
    assert ia.size == m
    assert abs(v.mean() - 3.0 * (1 - shared_fraction)) < 0.15
