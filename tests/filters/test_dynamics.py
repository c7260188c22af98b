"""RK4 torque-free propagation and its Jacobians (003 eq 25–27)."""

import numpy as np
import pytest

from attitude.batch import quaternion_conjugates, quaternions_from_rotvecs, rotvecs_from_quaternions
from attitude.quaternion import quat_angle_between, quat_multiply
from attitude.rigid_body import euler_rates, propagate_torque_free
from filters.dynamics import (
    euler_rate_jacobian,
    inertia_from_ratios,
    inertia_ratios_from_inertia,
    propagate_rk4,
)

from .conftest import J_KG_M2, OMEGA0_RAD_S

# a full (non-diagonal) inertia tensor, physically valid
J_FULL = np.array([[1000.0, 40.0, -25.0], [40.0, 800.0, 30.0], [-25.0, 30.0, 600.0]])


def _trials():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(4, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w = OMEGA0_RAD_S + np.deg2rad(2.0) * rng.normal(size=(4, 3))
    return q, w


@pytest.mark.parametrize("J", [J_KG_M2, J_FULL], ids=["diagonal", "full"])
def test_rk4_over_60s_matches_exact_torque_free_motion(J):
    q0, w0 = _trials()
    t = np.arange(601) * 0.1
    q_ref, w_ref = propagate_torque_free(q0, w0, J, t)
    q, w = q0, w0
    for _ in range(600):
        q, w, _ = propagate_rk4(q, w, 0.1, J_kg_m2=J)
    assert np.max(quat_angle_between(q, q_ref[:, -1])) < 1e-9
    np.testing.assert_allclose(w, w_ref[:, -1], atol=1e-11)


def test_inertia_ratio_propagation_equals_known_inertia():
    q0, w0 = _trials()
    ratios = np.tile(inertia_ratios_from_inertia(J_KG_M2), (4, 1))
    qa, wa, _ = propagate_rk4(q0, w0, 0.1, J_kg_m2=J_KG_M2)
    qb, wb, _ = propagate_rk4(q0, w0, 0.1, inertia_ratios=ratios)
    np.testing.assert_allclose(qb, qa, atol=1e-15)
    np.testing.assert_allclose(wb, wa, atol=1e-15)
    np.testing.assert_allclose(inertia_from_ratios(ratios[0]), J_KG_M2 / 1000.0)


def _rk4_unnormalised(x, h, J):
    """Independent single-trial RK4 of [q, ω] without renormalisation (finite-difference target)."""
    Ji = np.linalg.inv(J)

    def f(x):
        q, w = x[:4], x[4:]
        return np.r_[0.5 * quat_multiply(q, np.r_[0.0, w]), -Ji @ np.cross(w, J @ w)]

    k1 = f(x)
    k2 = f(x + h / 2 * k1)
    k3 = f(x + h / 2 * k2)
    k4 = f(x + h * k3)
    return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


@pytest.mark.parametrize("J", [J_KG_M2, J_FULL], ids=["diagonal", "full"])
def test_quaternion_jacobian_is_the_derivative_of_the_rk4_map(J):
    q0, w0 = _trials()
    _, _, F = propagate_rk4(q0, w0, 0.5, J_kg_m2=J, jacobian="quaternion")
    for i in range(q0.shape[0]):
        x = np.r_[q0[i], w0[i]]
        eps = 1e-6
        fd = np.stack([(_rk4_unnormalised(x + eps * e, 0.5, J) - _rk4_unnormalised(x - eps * e, 0.5, J))
                       / (2 * eps) for e in np.eye(7)], 1)
        np.testing.assert_allclose(F[i], fd, atol=1e-8)


@pytest.mark.parametrize("ratios", [False, True])
def test_error_state_transition_matches_finite_differences(ratios):
    q0, w0 = _trials()
    M = q0.shape[0]
    p0 = np.tile([0.8, 0.6], (M, 1))
    kw = {"inertia_ratios": p0} if ratios else {"J_kg_m2": J_KG_M2}
    h = 1.0
    q1, w1, Phi = propagate_rk4(q0, w0, h, jacobian="error", n_substeps=10, **kw)
    n = 8 if ratios else 6
    eps = 1e-6
    fd = np.zeros((M, n, n))
    for k in range(n):
        cols = []
        for s in (+1, -1):
            e = np.zeros((M, n))
            e[:, k] = s * eps
            qp = quat_multiply(q0, quaternions_from_rotvecs(e[:, :3]))
            kwp = {"inertia_ratios": p0 + e[:, 6:8]} if ratios else kw
            qe, we, _ = propagate_rk4(qp, w0 + e[:, 3:6], h, n_substeps=10, **kwp)
            out = [rotvecs_from_quaternions(quat_multiply(quaternion_conjugates(q1), qe)), we - w1]
            if ratios:
                out.append(e[:, 6:8])
            cols.append(np.concatenate(out, 1))
        fd[:, :, k] = (cols[0] - cols[1]) / (2 * eps)
    np.testing.assert_allclose(Phi, fd, atol=2e-6)


def test_euler_rate_jacobian_matches_finite_differences_for_a_full_tensor():
    w = np.deg2rad([5.0, -3.0, 4.0])
    eps = 1e-7
    fd = np.stack([(euler_rates(w + eps * e, J_FULL) - euler_rates(w - eps * e, J_FULL)) / (2 * eps)
                   for e in np.eye(3)], 1)
    np.testing.assert_allclose(euler_rate_jacobian(w, J_FULL), fd, atol=1e-10)


def test_bad_arguments_raise_naming_the_parameter():
    q0, w0 = _trials()
    with pytest.raises(ValueError, match="J_kg_m2/inertia_ratios"):
        propagate_rk4(q0, w0, 0.1)
    with pytest.raises(ValueError, match="n_substeps"):
        propagate_rk4(q0, w0, 0.1, J_kg_m2=J_KG_M2, n_substeps=0)
    with pytest.raises(ValueError, match="jacobian"):
        propagate_rk4(q0, w0, 0.1, J_kg_m2=J_KG_M2, jacobian="exact")
    with pytest.raises(ValueError, match="J_kg_m2"):
        inertia_ratios_from_inertia(J_FULL)
    with pytest.raises(ValueError, match="q_NT"):
        propagate_rk4(q0[0], w0[0], 0.1, J_kg_m2=J_KG_M2)
    with pytest.raises(ValueError, match="inertia_ratios"):
        propagate_rk4(q0, w0, 0.1, inertia_ratios=[0.8, 0.6])
