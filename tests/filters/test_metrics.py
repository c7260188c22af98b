"""Error metrics: rotation angle, 003 eq (36)–(37), convergence, NEES band, SPEED score."""

import numpy as np
import pytest

from attitude.euler import matrix_from_euler
from attitude.quaternion import quat_from_axis_angle, quat_from_matrix
from filters.metrics import (
    ConvergenceCriterion,
    attitude_error_angle,
    convergence_time,
    euler_angle_error,
    nees,
    nees_band,
    rate_error,
    speed_score,
)


def test_attitude_error_angle_is_the_relative_rotation_angle_and_sign_invariant():
    q = quat_from_axis_angle([0.3, -0.2, 0.9], 1.1)
    dq = quat_from_axis_angle([1.0, 2.0, 3.0], np.deg2rad(7.0))
    from attitude.quaternion import quat_multiply

    qe = quat_multiply(q, dq)
    assert attitude_error_angle(qe, q) == pytest.approx(np.deg2rad(7.0), abs=1e-12)
    assert attitude_error_angle(-qe, q) == pytest.approx(np.deg2rad(7.0), abs=1e-12)
    assert np.isnan(attitude_error_angle(np.full(4, np.nan), q))


def test_euler_error_eq36_on_a_yaw_offset_wraps_around_pi():
    a_true = np.deg2rad([179.0, 10.0, -20.0])
    a_est = np.deg2rad([-179.0, 10.5, -20.0])
    qt = quat_from_matrix(matrix_from_euler(a_true, "321"))
    qe = quat_from_matrix(matrix_from_euler(a_est, "321"))
    assert euler_angle_error(qe, qt) == pytest.approx(np.deg2rad(np.hypot(2.0, 0.5)), abs=1e-10)


def test_rate_error_eq37_is_the_euclidean_norm():
    assert rate_error([1.0, 2.0, 2.0], [0.0, 0.0, 0.0]) == pytest.approx(3.0)


def test_convergence_time_is_the_first_epoch_after_which_both_errors_stay_in_the_band():
    t = np.arange(0, 60.01, 0.1)
    crit = ConvergenceCriterion()  # defaults: 0.5°, 0.05°/s, last 10 s
    ea = np.deg2rad(np.where(t < 12.0, 5.0, 0.1))[None].repeat(3, 0)
    er = np.deg2rad(np.where(t < 20.0, 1.0, 0.01))[None].repeat(3, 0)
    ea[1, 550] = np.deg2rad(0.6)  # excursion inside the last 10 s: not converged
    er[2, 590:] = np.nan  # lost estimate at the end: not converged
    conv, tc = convergence_time(t, ea, er, criterion=crit)
    np.testing.assert_array_equal(conv, [True, False, False])
    assert tc[0] == pytest.approx(20.0, abs=1e-9)
    assert np.isnan(tc[1:]).all()
    euler = ConvergenceCriterion(attitude_metric="euler321", attitude_deg=1.0)
    assert euler.attitude_metric == "euler321"
    with pytest.raises(ValueError, match="hold_s"):
        convergence_time(t[:50], ea[:, :50], er[:, :50], criterion=crit)
    with pytest.raises(ValueError, match="attitude_metric"):
        ConvergenceCriterion(attitude_metric="gibbs")


def test_nees_band_reproduces_bar_shalom_example():
    """Bar-Shalom, Li, Kirubarajan (2001) §5.4.2: 50 runs, 2 states → [1.5, 2.6]."""
    lo, hi = nees_band(2, 50)
    assert lo == pytest.approx(1.48, abs=0.01)
    assert hi == pytest.approx(2.59, abs=0.01)


def test_average_nees_of_consistent_gaussian_errors_falls_in_the_band_95_percent_of_the_time():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(6, 6))
    P = A @ A.T + np.eye(6)
    L = np.linalg.cholesky(P)
    e = (L @ rng.normal(size=(2000, 100, 6, 1)))[..., 0]  # 2000 experiments of 100 runs
    m = nees(e, P).mean(1)
    lo, hi = nees_band(6, 100)
    inside = np.mean((m >= lo) & (m <= hi))
    assert 0.93 < inside < 0.97


def test_speed_score_sums_rotation_radians_and_relative_translation():
    q = np.array([1.0, 0, 0, 0])
    qe = quat_from_axis_angle([0, 0, 1.0], np.deg2rad(10.0))
    r = np.array([0.0, 0.0, 50.0])
    s = speed_score(qe, q, r_est=r + [0.0, 1.0, 0.0], r_true=r)
    assert s == pytest.approx(np.deg2rad(10.0) + 1.0 / 50.0)
    small = quat_from_axis_angle([0, 0, 1.0], np.deg2rad(0.1))
    assert speed_score(small, q, thresholds=True) == 0.0
    assert speed_score(small, q) == pytest.approx(np.deg2rad(0.1))
    with pytest.raises(ValueError, match="r_est/r_true"):
        speed_score(q, q, r_est=r)
