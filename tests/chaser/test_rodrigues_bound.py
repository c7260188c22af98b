"""Cramér–Rao bound of the 001 pose: against an independent numerical Fisher matrix, a Monte Carlo of
the solver, exact similarity scalings, and its failure flags."""

import numpy as np
import pytest

from attitude.quaternion import (
    matrix_from_quat,
    quat_from_matrix,
    quat_from_rotvec,
    rotvec_from_quat,
)
from chaser.rodrigues_pose import GibbsPose, pose_crlb, project_focal_plane, solve_pose_rodrigues

F_M = 0.2  # 001 §2.4: f = 200 mm
PIXEL_M = 7e-6  # 7 µm pixels, σ = 1 px
CUBE_T = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])  # 2 m cube
Q_CT = quat_from_rotvec([0.5, -0.7, 0.3])  # shows three faces: 7 vertices
R_CT = matrix_from_quat(Q_CT)
R_TC_C = np.array([0.3, -0.2, 100.0])


def _visible(R, r, edge=2.0):
    """Vertices with an adjacent face turned to the camera (back-face culling), as the scenario's truth."""
    c_T = -R.T @ r
    V = CUBE_T * edge / 2.0
    vis = np.zeros(8, bool)
    for k in range(3):
        for s in (-1.0, 1.0):
            vis |= (s * c_T[k] - edge / 2.0 > 0) & (s * V[:, k] > 0)
    return vis


VISIBLE = _visible(R_CT, R_TC_C)


def test_bound_is_the_inverse_fisher_matrix_of_a_central_difference_jacobian():
    assert VISIBLE.sum() == 7
    P = CUBE_T[VISIBLE]

    def image(x):
        R = matrix_from_quat(quat_from_rotvec(x[:3])) @ R_CT  # φ on the left, camera axes
        return project_focal_plane(P, R, R_TC_C + x[3:], focal_length_m=F_M)[0].ravel()

    h = 1e-7
    H = np.stack([(image(h * e) - image(-h * e)) / (2 * h) for e in np.eye(6)], -1)
    C_numeric = np.linalg.inv(H.T @ H / PIXEL_M**2)
    b = pose_crlb(CUBE_T, R_CT, R_TC_C, focal_length_m=F_M, pixel_sigma_m=PIXEL_M, visible=VISIBLE)
    assert b.ok and b.failure_reason == "" and b.n_points == 7
    scale = np.sqrt(np.outer(np.diag(C_numeric), np.diag(C_numeric)))
    np.testing.assert_allclose(b.covariance / scale, C_numeric / scale, atol=1e-5)
    u = R_TC_C / np.linalg.norm(R_TC_C)
    Cr = C_numeric[3:, 3:]
    np.testing.assert_allclose(b.sigma_along_los_m, np.sqrt(u @ Cr @ u), rtol=1e-5)
    np.testing.assert_allclose(b.sigma_across_los_m, np.sqrt(np.trace(Cr) - u @ Cr @ u), rtol=1e-5)
    np.testing.assert_allclose(b.sigma_attitude_rad, np.sqrt(np.trace(C_numeric[:3, :3])), rtol=1e-5)


def test_solver_monte_carlo_meets_the_bound_at_the_paper_operating_point():
    """2000 noisy frames of the 2 m cube at 100 m, 1 px: RMS errors / bound within 0.8–1.25."""
    n = 2000
    rng = np.random.default_rng(20100)
    xy, _ = project_focal_plane(CUBE_T, R_CT, R_TC_C, focal_length_m=F_M)
    xy = np.where(VISIBLE[:, None], xy, np.nan) + PIXEL_M * rng.standard_normal((n, 8, 2))
    guess = GibbsPose.from_quat(np.broadcast_to(Q_CT, (n, 4)), np.broadcast_to(R_TC_C, (n, 3)))
    res = solve_pose_rodrigues(CUBE_T, xy, guess, focal_length_m=F_M)
    assert res.ok.all()
    phi = rotvec_from_quat(quat_from_matrix(res.R_CT @ R_CT.T))
    dr = res.r_TC_C - R_TC_C
    u = R_TC_C / np.linalg.norm(R_TC_C)
    along = dr @ u
    across = np.linalg.norm(dr - along[:, None] * u, axis=1)
    b = pose_crlb(CUBE_T, R_CT, R_TC_C, focal_length_m=F_M, pixel_sigma_m=PIXEL_M, visible=VISIBLE)
    ratios = [np.sqrt(np.mean(along**2)) / b.sigma_along_los_m, np.sqrt(np.mean(across**2)) / b.sigma_across_los_m,
              np.sqrt(np.mean(np.sum(phi**2, 1))) / b.sigma_attitude_rad]
    assert all(0.8 < r < 1.25 for r in ratios), ratios
    # every pose component, not only the three summaries
    per_axis = np.std(np.c_[phi, dr], axis=0) / np.sqrt(np.diag(b.covariance))
    assert np.all((per_axis > 0.8) & (per_axis < 1.25)), per_axis


def test_bound_scales_with_pixel_noise_and_with_range_and_size_together():
    """Exact: σ ∝ pixel σ; scaling range and target by k leaves the attitude bound and scales positions by k."""
    b1 = pose_crlb(CUBE_T, R_CT, R_TC_C, focal_length_m=F_M, pixel_sigma_m=PIXEL_M, visible=VISIBLE)
    b2 = pose_crlb(CUBE_T, R_CT, R_TC_C, focal_length_m=F_M, pixel_sigma_m=2.5 * PIXEL_M, visible=VISIBLE)
    np.testing.assert_allclose(b2.covariance, 2.5**2 * b1.covariance, rtol=1e-9)
    k = 3.0
    b3 = pose_crlb(k * CUBE_T, R_CT, k * R_TC_C, focal_length_m=F_M, pixel_sigma_m=PIXEL_M, visible=VISIBLE)
    np.testing.assert_allclose(b3.sigma_attitude_rad, b1.sigma_attitude_rad, rtol=1e-9)
    np.testing.assert_allclose([b3.sigma_along_los_m, b3.sigma_across_los_m],
                               [k * b1.sigma_along_los_m, k * b1.sigma_across_los_m], rtol=1e-9)
    # weak perspective: range × 2 at fixed size → along-LOS σ × ≈4, across and attitude × ≈2
    b4 = pose_crlb(CUBE_T, R_CT, 2 * R_TC_C, focal_length_m=F_M, pixel_sigma_m=PIXEL_M, visible=VISIBLE)
    np.testing.assert_allclose(b4.sigma_along_los_m / b1.sigma_along_los_m, 4.0, rtol=0.02)
    np.testing.assert_allclose(b4.sigma_across_los_m / b1.sigma_across_los_m, 2.0, rtol=0.05)


def test_batches_flag_too_few_points_behind_camera_and_collinear_points_without_raising():
    R = np.broadcast_to(R_CT, (4, 3, 3))
    r = np.array([R_TC_C, R_TC_C, [0.0, 0.0, 0.5], R_TC_C])
    vis = np.array([VISIBLE, np.arange(8) < 2, np.ones(8, bool), np.ones(8, bool)])
    line = np.zeros((8, 3))
    line[:, 0] = np.arange(8.0)
    P = np.array([CUBE_T, CUBE_T, CUBE_T, line])
    b = pose_crlb(P, R, r, focal_length_m=F_M, pixel_sigma_m=PIXEL_M, visible=vis)
    assert b.failure_reason.tolist() == ["", "too_few_points", "behind_camera", "rank_deficient"]
    assert b.ok.tolist() == [True, False, False, False]
    assert np.all(np.isfinite(b.covariance[0])) and np.all(np.isnan(b.sigma_attitude_rad[1:]))


@pytest.mark.parametrize(("kwargs", "name"), [
    ({"focal_length_m": 0.0}, "focal_length_m"),
    ({"pixel_sigma_m": -1.0}, "pixel_sigma_m"),
    ({"points_T": np.zeros((8, 2))}, "points_T"),
    ({"R_CT": np.eye(2)}, "R_CT"),
    ({"r_TC_C": [0.0, np.nan, 1.0]}, "r_TC_C"),
    ({"visible": np.ones(7, bool)}, "visible"),
])
def test_bad_arguments_raise_value_error_naming_the_parameter(kwargs, name):
    args = {"points_T": CUBE_T, "R_CT": R_CT, "r_TC_C": R_TC_C, "focal_length_m": F_M, "pixel_sigma_m": PIXEL_M,
            **kwargs}
    with pytest.raises(ValueError, match=f"^{name}: "):
        pose_crlb(args.pop("points_T"), args.pop("R_CT"), args.pop("r_TC_C"), **args)
