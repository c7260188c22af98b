"""Torque-free motion: exact propagation against DOP853, invariants, and analytic special cases."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.special import ellipk

from attitude.matrix import orthonormalize
from attitude.quaternion import quat_angle_between, quat_derivative, quat_from_axis_angle
from attitude.rigid_body import (
    angular_momentum_N,
    check_inertia,
    euler_rates,
    kinetic_energy,
    omega_closed_form,
    propagate_torque_free,
)

W0 = np.deg2rad([5.0, 5.0, 5.0])
J_DIAG = np.diag([100.0, 120.0, 80.0])
_R = orthonormalize(np.random.default_rng(7).normal(size=(3, 3)))
J_FULL = _R @ J_DIAG @ _R.T  # non-diagonal, same principal moments


def dop853(q0, w0, J, t):
    """Independent reference: scipy DOP853 on (q, ω) at rtol = atol = 1e-12."""
    Jinv = np.linalg.inv(J)

    def f(_, x):
        q, w = x[:4], x[4:]
        return np.concatenate([quat_derivative(q, w), -Jinv @ np.cross(w, J @ w)])

    sol = solve_ivp(f, (t[0], t[-1]), np.concatenate([q0, w0]), method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t)
    return sol.y[:4].T, sol.y[4:].T


@pytest.mark.parametrize("J", [J_DIAG, J_FULL], ids=["diagonal", "non-diagonal"])
def test_propagation_matches_dop853_to_1e_8_degree_over_300_s(J):
    t = np.linspace(0.0, 300.0, 301)
    q0 = quat_from_axis_angle([1.0, 2.0, 3.0], 2.0)
    q, w = propagate_torque_free(q0, W0, J, t)
    q_ref, w_ref = dop853(q0, W0, J, t)
    assert q.shape == (301, 4) and w.shape == (301, 3)
    assert np.rad2deg(quat_angle_between(q, q_ref)).max() < 1e-8
    assert np.abs(w - w_ref).max() < 1e-11


@pytest.mark.parametrize("J", [J_DIAG, J_FULL], ids=["diagonal", "non-diagonal"])
def test_inertial_angular_momentum_and_energy_are_conserved(J):
    t = np.linspace(0.0, 300.0, 601)
    q, w = propagate_torque_free([1.0, 0.0, 0.0, 0.0], W0, J, t)
    L = angular_momentum_N(q, w, J)
    assert np.abs(L - L[0]).max() / np.linalg.norm(L[0]) < 1e-9
    E = kinetic_energy(w, J)
    assert np.abs(E - E[0]).max() / E[0] < 1e-12


def test_elliptic_closed_form_matches_integration_and_has_the_analytic_period():
    """ω(t) of Landau & Lifshitz §37 against DOP853, and ω(t + 4K(m)/λ) = ω(t)."""
    J = np.diag([1000.0, 800.0, 600.0])
    t = np.linspace(0.0, 200.0, 201)
    w = omega_closed_form(W0, J, t)
    _, w_ref = dop853(np.array([1.0, 0, 0, 0]), W0, J, t)
    assert np.abs(w - w_ref).max() < 1e-11
    # analytic period: sorted moments I1 < I2 < I3 = 600, 800, 1000 (ω_P is a permutation of ω_B)
    I1, I2, I3 = 600.0, 800.0, 1000.0
    wp = np.array([W0[2], W0[1], W0[0]])
    M2 = np.sum((np.array([I1, I2, I3]) * wp) ** 2)
    E2 = np.sum(np.array([I1, I2, I3]) * wp**2)
    assert M2 > E2 * I2  # rotation about the major axis
    lam = np.sqrt((I3 - I2) * (M2 - E2 * I1) / (I1 * I2 * I3))
    m = (I2 - I1) * (E2 * I3 - M2) / ((I3 - I2) * (M2 - E2 * I1))
    T = 4 * ellipk(m) / lam
    w_shift = omega_closed_form(W0, J, t + T)
    np.testing.assert_allclose(w_shift, w, atol=1e-12)


def test_axisymmetric_body_matches_the_analytic_precession():
    """I1 = I2: ω3 constant and (ω1, ω2) turn at λ = (I3 − I1) ω3 / I1 (Landau & Lifshitz §33)."""
    I1, I3 = 100.0, 150.0
    J = np.diag([I1, I1, I3])
    w0 = np.array([0.02, 0.0, 0.1])
    t = np.linspace(0.0, 100.0, 51)
    _, w = propagate_torque_free([1.0, 0, 0, 0], w0, J, t)
    lam = (I3 - I1) * w0[2] / I1
    expected = np.stack([0.02 * np.cos(lam * t), 0.02 * np.sin(lam * t), np.full_like(t, 0.1)], -1)
    np.testing.assert_allclose(w, expected, atol=1e-13)


def test_pure_spin_about_a_principal_axis_is_a_constant_rotation():
    J = np.diag([100.0, 120.0, 80.0])
    w0 = np.array([0.0, 0.3, 0.0])  # intermediate axis: unstable equilibrium, exact solution stays
    t = np.array([0.0, 1.0, 10.0])
    q, w = propagate_torque_free([1.0, 0, 0, 0], w0, J, t)
    np.testing.assert_allclose(w, np.broadcast_to(w0, (3, 3)), atol=0)
    for k, tk in enumerate(t):
        assert quat_angle_between(q[k], quat_from_axis_angle([0, 1, 0], 0.3 * tk)) < 1e-12


def test_batched_initial_conditions_and_any_time_order():
    rng = np.random.default_rng(3)
    w0 = rng.normal(scale=0.1, size=(4, 3))
    q0 = quat_from_axis_angle(rng.normal(size=(4, 3)), rng.uniform(0, np.pi, 4))
    t = np.array([5.0, -3.0, 0.0, 12.5])
    q, w = propagate_torque_free(q0, w0, J_FULL, t)
    assert q.shape == (4, 4, 4) and w.shape == (4, 4, 3)
    for b in range(4):
        qb, wb = propagate_torque_free(q0[b], w0[b], J_FULL, t)
        assert quat_angle_between(q[b], qb).max() < 1e-12
        np.testing.assert_allclose(w[b], wb, atol=1e-15)
    assert quat_angle_between(q[:, 2], q0).max() < 1e-12  # t = 0 returns the initial attitude


def test_euler_rates_match_the_euler_equations():
    w = np.array([0.1, -0.2, 0.3])
    J = np.diag([100.0, 120.0, 80.0])
    expected = np.array([(120 - 80) * w[1] * w[2] / 100, (80 - 100) * w[2] * w[0] / 120, (100 - 120) * w[0] * w[1] / 80])
    np.testing.assert_allclose(euler_rates(w, J), expected, atol=1e-16)


@pytest.mark.parametrize(
    "J, match",
    [
        (np.diag([1.0, 1.0, 3.0]), "triangle inequality"),
        (np.diag([1.0, -1.0, 1.0]), "positive definite"),
        (np.array([[1.0, 0.5, 0], [0, 1, 0], [0, 0, 1]]), "symmetric"),
        (np.eye(4), "expected shape"),
    ],
)
def test_invalid_inertia_is_rejected_by_name(J, match):
    with pytest.raises(ValueError, match=f"J: .*{match}"):
        check_inertia(J)
