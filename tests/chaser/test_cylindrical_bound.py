"""Cramér–Rao bounds of the 004 cylindrical system, checked against Monte Carlo of its own estimators."""

import numpy as np
import pytest

from attitude.euler import matrix_from_euler
from chaser.cylindrical import (
    angle_jacobian,
    attitude_crlb,
    attitude_from_three_points,
    intersect_planes,
    paper_rig,
    point_crlb,
    rotation_error_vector,
    yaw_roll_pitch_from_matrix,
)

SIGMA_RAD = 1e-5  # per channel; small enough for the linearisation, far above rounding
N_MC = 4000


def _leds(pose_deg, centre=(1.0, 3.5, 0.0)):
    """Three LEDs (|ab| = |bc| = 0.5 m, 80°) at a 3-1-2 pose (corrected eq 9–11), and R_OS."""
    R_OS = matrix_from_euler(np.deg2rad(pose_deg), "312").T
    th = np.deg2rad(80.0)
    body = np.array([[0.5, 0, 0], [0, 0, 0], [-0.5 * np.cos(th), 0.5 * np.sin(th), 0]])
    return np.asarray(centre) + (body - body.mean(0)) @ R_OS.T, R_OS


def test_angle_jacobian_matches_central_differences_of_the_true_angles():
    rig = paper_rig()
    X = np.array([[1.3, 3.7, 0.2], [0.4, 2.5, -0.6], [2.2, 6.0, 0.9]])
    h = 1e-6
    num = np.stack([(rig.true_angles(X + h * e) - rig.true_angles(X - h * e)) / (2 * h) for e in np.eye(3)], -1)
    np.testing.assert_allclose(angle_jacobian(rig.R_CW, rig.t_CW, X), num, atol=1e-8)


def test_point_bound_equals_the_scatter_of_plane_intersection_monte_carlo():
    rig = paper_rig()
    X = np.array([1.3, 3.7, 0.2])
    bound = point_crlb(rig.R_CW, rig.t_CW, X, SIGMA_RAD)
    rng = np.random.default_rng(7)
    ab = rig.true_angles(X) + rng.normal(0.0, SIGMA_RAD, (N_MC, 2, 2))
    err = intersect_planes(rig.R_CW, rig.t_CW, ab).X_W - X
    ratio = np.trace(np.cov(err.T)) / np.trace(bound.covariance_m2)
    assert 0.9 < ratio < 1.1  # trace of a 4000-sample covariance: ≈ 3 % standard error
    # per axis too: depth (y) is the weak direction, as 004 says
    np.testing.assert_allclose(np.std(err, 0), np.sqrt(np.diag(bound.covariance_m2)), rtol=0.1)
    assert np.argmax(np.diag(bound.covariance_m2)) == 1


def test_point_bound_fails_with_fewer_than_three_channels():
    rig = paper_rig()
    used = np.array([[True, False], [True, False]])
    b = point_crlb(rig.R_CW, rig.t_CW, np.array([1.0, 3.5, 0.0]), SIGMA_RAD, used=used)
    assert not b.ok and np.isnan(b.rms_m)


@pytest.mark.parametrize("pose_deg", [[-22.0581, 59.1990, 6.0103], [19.3189, 88.6700, -22.1653],
                                      [-87.4626, -77.8150, 87.2480]])
def test_attitude_bound_equals_the_scatter_of_the_attitude_solution_monte_carlo(pose_deg):
    P, R_OS = _leds(pose_deg)
    rig = paper_rig()
    pb = point_crlb(rig.R_CW, rig.t_CW, P, SIGMA_RAD)
    bound = attitude_crlb(P[0], P[1], P[2], *pb.covariance_m2)
    rng = np.random.default_rng(11)
    ab = rig.true_angles(P) + rng.normal(0.0, SIGMA_RAD, (N_MC, 3, 2, 2))
    fix = intersect_planes(rig.R_CW, rig.t_CW, ab)
    att = attitude_from_three_points(fix.X_W[:, 0], fix.X_W[:, 1], fix.X_W[:, 2])
    d = rotation_error_vector(att.R_OS, R_OS)
    assert 0.9 < np.trace(np.cov(d.T)) / np.trace(bound.covariance_rad2) < 1.1
    e = yaw_roll_pitch_from_matrix(att.R_OS) - yaw_roll_pitch_from_matrix(R_OS)
    e = (e + np.pi) % (2 * np.pi) - np.pi
    np.testing.assert_allclose(np.std(e, 0), bound.euler_sigma_rad, rtol=0.1)


def test_euler_bound_grows_as_one_over_cos_roll_near_the_gimbal_lock_while_the_rotation_bound_does_not():
    rig = paper_rig()
    rot, yaw = [], []
    rolls = np.array([60.0, 80.0, 88.67])
    for roll in rolls:
        P, _ = _leds([19.3189, roll, -22.1653])
        pb = point_crlb(rig.R_CW, rig.t_CW, P, SIGMA_RAD)
        b = attitude_crlb(P[0], P[1], P[2], *pb.covariance_m2)
        rot.append(b.rotation_rms_rad)
        yaw.append(b.euler_sigma_rad[0])
    assert max(rot) / min(rot) < 1.5
    amplification = np.array(yaw) / np.array(rot)
    # yaw error ∝ 1/cos(roll): the ratio between 88.67° and 60° is cos 60° / cos 88.67° ≈ 21.5 (within 35 %)
    assert amplification[2] / amplification[0] == pytest.approx(np.cos(np.deg2rad(60)) / np.cos(np.deg2rad(88.67)),
                                                                 rel=0.35)


def test_attitude_of_a_failed_fix_is_reported_not_raised():
    P, _ = _leds([-22.0581, 59.1990, 6.0103])
    a = np.stack([P[0], np.full(3, np.nan)])
    att = attitude_from_three_points(a, P[1], P[2])
    assert att.ok.tolist() == [True, False]
    assert att.failure_reason.tolist() == ["", "non-finite point"] and np.isnan(att.R_OS[1]).all()
