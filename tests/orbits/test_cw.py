"""Tests of orbits.cw: the HCW state transition matrix, natural orbits, CW vs two-body."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from orbits import cw

A_M = 6721.2e3
N = float(cw.mean_motion(A_M))
PERIOD_S = 2 * np.pi / N
times = st.floats(-3 * PERIOD_S, 3 * PERIOD_S)
# Velocities in units of n·m make every entry of Φ O(1) (up to the secular 3nt), so an absolute
# tolerance on the scaled matrix is a relative one on every entry.
S = np.diag([1.0, 1.0, 1.0, 1.0 / N, 1.0 / N, 1.0 / N])
S_INV = np.linalg.inv(S)


def _scaled(Phi):
    return S @ Phi @ S_INV


def test_mean_motion_of_001_orbit():
    """The 6721.2 km orbit of 001 Table 1 has a period of 5483.8 s."""
    assert abs(2 * np.pi / cw.mean_motion(A_M) - 5483.8) < 0.05


def test_stm_at_zero_is_identity():
    np.testing.assert_array_equal(cw.stm(0.0, N), np.eye(6))


@settings(max_examples=60, deadline=None)
@given(t1=times, t2=times)
def test_stm_semigroup(t1, t2):
    lhs = _scaled(cw.stm(t1 + t2, N))
    rhs = _scaled(cw.stm(t1, N) @ cw.stm(t2, N))
    np.testing.assert_allclose(lhs, rhs, atol=1e-11 * max(1.0, np.abs(lhs).max()))


@settings(max_examples=40, deadline=None)
@given(t=times)
def test_stm_derivative_is_A_phi(t):
    A = cw.system_matrix(N)
    h = 0.5  # s; central-difference truncation error ~ (nh)²/6 ≈ 5e-8 relative
    dPhi = _scaled(cw.stm(t + h, N) - cw.stm(t - h, N)) / (2 * h * N)  # dΦ̃/d(nt)
    expected = _scaled(A @ cw.stm(t, N)) / N
    np.testing.assert_allclose(dPhi, expected, atol=1e-6 * max(1.0, np.abs(expected).max()))


def test_stm_equals_matrix_exponential():
    A = cw.system_matrix(N)
    for t in (1.0, 600.0, 5000.0, -2000.0):
        np.testing.assert_allclose(cw.stm(t, N), expm(A * t), atol=1e-9, rtol=1e-9)


def test_propagate_matches_numerical_integration_and_shapes():
    rng = np.random.default_rng(7)
    x0 = rng.normal(0, [50, 50, 50, 0.05, 0.05, 0.05], (3, 4, 6))
    t = np.linspace(0, 2 * PERIOD_S, 50)
    x = cw.propagate(x0, t, N)
    assert x.shape == (3, 4, 50, 6)
    A = cw.system_matrix(N)
    sol = solve_ivp(lambda _, y: A @ y, (0, t[-1]), x0[1, 2], t_eval=t, method="DOP853",
                    rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(x[1, 2], sol.y.T, atol=1e-6)
    np.testing.assert_allclose(cw.propagate(x0[0, 0], t, N), x[0, 0], atol=0)


def test_drift_rate_matches_propagated_secular_motion():
    rng = np.random.default_rng(8)
    x0 = rng.normal(0, [30, 30, 30, 0.03, 0.03, 0.03], (20, 6))
    y = cw.propagate(x0, np.array([0.0, PERIOD_S]), N)[:, :, 1]
    np.testing.assert_allclose(y[:, 1] - y[:, 0], cw.along_track_drift_per_orbit(x0, N), atol=1e-9)


@pytest.mark.parametrize("builder", ["bounded", "nmc", "pse"])
def test_bounded_orbits_stay_bounded(builder):
    rng = np.random.default_rng(9)
    b = rng.uniform(1, 100, 30)
    c = rng.uniform(0, 100, 30)
    ph = rng.uniform(0, 2 * np.pi, 30)
    if builder == "bounded":
        x0 = cw.bounded_orbit_state(n=N, radial_amplitude_m=b, phase_rad=ph,
                                    cross_track_amplitude_m=c, cross_track_phase_rad=ph,
                                    along_track_offset_m=-b)
    elif builder == "nmc":
        x0 = cw.natural_motion_circumnavigation(2 * b, n=N, phase_rad=ph, cross_track_amplitude_m=c)
    else:
        x0 = cw.passive_safety_ellipse(b, c, n=N, phase_rad=ph)
    np.testing.assert_allclose(cw.drift_condition(x0, N), 0.0, atol=1e-15)
    t = np.linspace(0, 20 * PERIOD_S, 4001)
    x = cw.propagate(x0, t, N)
    yc = x0[:, 1] + 2 * b * np.sin(ph)
    # Exactly on the analytic ellipse for 20 orbits: |x| ≤ b, |y − y_c| ≤ 2b, |z| ≤ c.
    assert np.all(np.abs(x[..., 0]) <= b[:, None] * (1 + 1e-9))
    assert np.all(np.abs(x[..., 1] - yc[:, None]) <= 2 * b[:, None] * (1 + 1e-9) + 1e-9)
    assert np.all(np.abs(x[..., 2]) <= c[:, None] * (1 + 1e-9) + 1e-12)
    # And periodic: back to the start after whole orbits.
    np.testing.assert_allclose(x[:, -1], x0, atol=1e-8)


def test_passive_safety_ellipse_keeps_off_along_track_axis():
    x0 = cw.passive_safety_ellipse(np.array([10.0, 30.0]), np.array([20.0, 15.0]), n=N, phase_rad=0.4)
    np.testing.assert_allclose(cw.min_radial_cross_track_separation(x0, N), [10.0, 15.0], rtol=1e-6)
    # The same ellipse with cross-track in phase with radial crosses the axis.
    x_bad = cw.bounded_orbit_state(n=N, radial_amplitude_m=10.0, cross_track_amplitude_m=20.0)
    assert cw.min_radial_cross_track_separation(x_bad, N) < 1e-3


def test_impulse_changes_velocity_only():
    x = cw.apply_impulse(np.arange(6.0), [0.1, -0.2, 0.3])
    np.testing.assert_array_equal(x, [0, 1, 2, 3.1, 3.8, 5.3])


def test_two_impulse_transfer_reaches_target_state():
    rng = np.random.default_rng(11)
    x0 = rng.normal(0, [100, 100, 100, 0.1, 0.1, 0.1], (10, 6))
    xf = cw.natural_motion_circumnavigation(40.0, n=N, phase_rad=rng.uniform(0, 6, 10))
    tof = rng.uniform(600, 3000, 10)
    tr = cw.two_impulse_transfer(x0, xf, tof, N)
    assert np.all(tr.ok) and tr.failure_reason == ""
    for k in range(10):
        x1 = cw.apply_impulse(x0[k], tr.dv0_H[k])
        xa = cw.propagate(x1, tof[k], N)[0]
        np.testing.assert_allclose(cw.apply_impulse(xa, tr.dvf_H[k]), xf[k], atol=1e-8)


def test_two_impulse_transfer_reports_singular_time():
    tr = cw.two_impulse_transfer(np.zeros(6), np.array([0, 10.0, 0, 0, 0, 0]),
                                 np.array([PERIOD_S, 0.3 * PERIOD_S]), N)
    assert list(tr.ok) == [False, True]
    assert np.isnan(tr.total_dv_m_s[0]) and np.isfinite(tr.total_dv_m_s[1])
    assert "singular" in tr.failure_reason


@pytest.mark.parametrize("cross_track_m", [0.0, 25.0, 50.0])
def test_cw_error_below_2cm_over_two_orbits_for_50m_orbits(cross_track_m):
    """Issue #3 done-when: 50 m bounded orbits about a 6721.2 km circular chief (along-track
    semi-axis 50 m, 12 phases, cross-track amplitude up to 50 m, and passive-safety ellipses of
    the same size) keep the CW position error below 2 cm over two orbits."""
    t = np.linspace(0, 2 * PERIOD_S, 241)
    ph = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    x0 = np.concatenate([
        cw.natural_motion_circumnavigation(50.0, n=N, phase_rad=ph, cross_track_amplitude_m=cross_track_m),
        cw.passive_safety_ellipse(25.0, max(cross_track_m, 25.0), n=N, phase_rad=ph),
    ])
    err = cw.cw_error(x0, t, a_m=A_M)
    assert err.position_error_m.shape == (24, 241)
    assert err.max_position_error_m.max() < 0.02
    # Not trivially small: the second-order effect is there (mm level).
    assert err.max_position_error_m.max() > 1e-3


def test_cw_error_grows_quadratically_with_separation():
    """Linearisation error scales as ρ²/a: doubling the orbit size quadruples the error."""
    t = np.linspace(0, 2 * PERIOD_S, 121)
    e = cw.cw_error(cw.natural_motion_circumnavigation(np.array([25.0, 50.0, 100.0]), n=N), t, a_m=A_M)
    m = e.max_position_error_m
    np.testing.assert_allclose(m[1:] / m[:-1], 4.0, rtol=0.02)


def test_cw_error_with_inertial_chief_matches_circular_form():
    from orbits.two_body import state_from_elements

    r, v = state_from_elements(A_M, 0.0, 0.0, 0.0, 0.0, 0.0)
    x0 = cw.natural_motion_circumnavigation(50.0, n=N)
    t = np.linspace(0, PERIOD_S, 11)
    e1 = cw.cw_error(x0, t, a_m=A_M)
    e2 = cw.cw_error(x0, t, r_C0_N=r, v_C0_N=v)
    np.testing.assert_allclose(e1.position_error_m, e2.position_error_m, atol=1e-12)


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: cw.mean_motion(-6.7e6), "a_m"),
        (lambda: cw.stm(1.0, -N), "n"),
        (lambda: cw.stm(1.0, np.array([N, N])), "n"),
        (lambda: cw.propagate(np.zeros(5), [0.0, 1.0], N), "x0_H"),
        (lambda: cw.propagate(np.zeros(6), np.zeros((2, 2)), N), "t_s"),
        (lambda: cw.apply_impulse(np.zeros(6), np.zeros(2)), "dv_H"),
        (lambda: cw.two_impulse_transfer(np.zeros(6), np.zeros(6), -1.0, N), "tof_s"),
        (lambda: cw.bounded_orbit_state(n=N, radial_amplitude_m=-1.0), "radial_amplitude_m"),
        (lambda: cw.passive_safety_ellipse(1.0, -1.0, n=N), "cross_track_amplitude_m"),
        (lambda: cw.natural_motion_circumnavigation(np.nan, n=N), "semi_major_m"),
        (lambda: cw.cw_error(np.zeros(6), [0.0]), "a_m"),
        (lambda: cw.cw_error(np.zeros(6), [0.0], a_m=-1.0), "a_m"),
    ],
)
def test_cw_bad_input_names_argument(call, name):
    with pytest.raises(ValueError, match=name):
        call()
