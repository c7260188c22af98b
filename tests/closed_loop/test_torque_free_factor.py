"""The torque-free dynamics factor: propagation against the exact solution, Jacobians against the
RK4 variational equations, and the inertia shape's parameterisation."""

from __future__ import annotations

import gtsam
import numpy as np
from gtsam.symbol_shorthand import J, W, Y
from hypothesis import given, settings
from hypothesis import strategies as st

from attitude.quaternion import matrix_from_quat, quat_from_matrix
from attitude.rigid_body import propagate_torque_free
from closed_loop.torque_free_factor import (
    InertiaShape,
    propagate_batch,
    rotation_error_T,
    tensor_from_entries,
    torque_free_factor,
)
from filters.dynamics import propagate_rk4

J_T = np.array([[1000.0, 50.0, -30.0], [50.0, 800.0, 20.0], [-30.0, 20.0, 600.0]])


def _truth(T: int = 41, dt: float = 0.5):
    t = dt * np.arange(T)
    q, w = propagate_torque_free(np.array([1.0, 0.0, 0.0, 0.0]), np.deg2rad([5.0, -3.0, 4.0]), J_T, t)
    return t, matrix_from_quat(q), w


def test_propagation_matches_the_exact_torque_free_motion():
    """One 0.5 s RK4 step of 003 eq (25)–(27) with a non-diagonal tensor against the closed-form
    solution (attitude and rate): measured 1.8e-9 rad and 1.7e-11 rad/s; bound 1e-7 / 1e-9."""
    t, R, w = _truth()
    Rp, wp = propagate_batch(R[:-1], w[:-1], np.broadcast_to(J_T, (len(t) - 1, 3, 3)), 0.5)
    assert np.abs(rotation_error_T(Rp, R[1:])).max() < 1e-7
    assert np.abs(wp - w[1:]).max() < 1e-9


def _values(R0, w0, R1, w1, shape):
    v = gtsam.Values()
    v.insert(Y(0), gtsam.Rot3(R0.T))
    v.insert(W(0), w0)
    v.insert(Y(1), gtsam.Rot3(R1.T))
    v.insert(W(1), w1)
    v.insert(J(0), shape.entries)
    return v


def test_factor_jacobians_agree_with_the_rk4_variational_equations():
    """The factor's finite-difference Jacobians with respect to the earlier state against the exact
    Jacobian of the RK4 map (``filters.dynamics.propagate_rk4``, error-state form), carried to the
    graph's variables (``Y = R_TN``: a body perturbation ``a`` is ``−R_TN ε``); 1e-5 relative."""
    t, R, w = _truth(3)
    shape = InertiaShape.from_tensor(J_T)
    f = torque_free_factor(gtsam.noiseModel.Unit.Create(6), (Y(0), W(0), Y(1), W(1), J(0)), 0.5)
    lin = f.linearize(_values(R[0], w[0], R[1], w[1], shape))
    Jac, _ = lin.jacobian()
    _, _, Phi = propagate_rk4(quat_from_matrix(R[0])[None], w[0][None], 0.5, J_kg_m2=J_T, jacobian="error")
    Phi = Phi[0]
    # residual r = [Log(R̂ᵀ R₁), ω₁ − ω̂]: ∂r/∂a₀ = −Φ_aa, ∂r/∂ω₀ = −Φ_·ω; a₀ = −R₀ᵀ ε (Y₀ ⊕ ε)
    expect_Y0 = -Phi[:, :3] @ (-R[0].T)
    expect_w0 = -Phi[:, 3:]
    scale = np.abs(Phi).max()
    assert np.abs(Jac[:, 0:3] - expect_Y0).max() < 1e-5 * scale
    assert np.abs(Jac[:, 3:6] - expect_w0).max() < 1e-5 * scale
    # the later state enters as −R₁ᵀ ε (attitude) and I (rate)
    assert np.abs(Jac[:3, 6:9] + R[1].T).max() < 1e-5
    assert np.allclose(Jac[3:, 9:12], np.eye(3))


def test_known_inertia_factor_has_zero_error_on_the_truth():
    """Four keys and a constant tensor: the exact motion gives a residual below 1e-8."""
    t, R, w = _truth(2)
    f = torque_free_factor(gtsam.noiseModel.Unit.Create(6), (Y(0), W(0), Y(1), W(1)), 0.5, J_T=J_T)
    v = _values(R[0], w[0], R[1], w[1], InertiaShape.from_tensor(J_T))
    assert np.abs(f.unwhitenedError(v)).max() < 1e-8


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-np.pi, np.pi), min_size=3, max_size=3),
       st.floats(1.05, 2.0), st.floats(1.05, 2.0))
def test_inertia_shape_round_trip(rotvec, r1, r2):
    """A tensor built from principal axes and moments comes back with the same moments (ratios to
    the smallest) and the same tensor up to scale, whatever the axes."""
    from scipy.spatial.transform import Rotation

    Rm = Rotation.from_rotvec(rotvec).as_matrix()
    m = np.array([1.0, r1, r1 * r2])
    m = m if m[2] <= m[0] + m[1] else np.array([1.0, r1, 1.0 + r1 - 1e-6])
    J = (Rm * (300.0 * m)) @ Rm.T
    shape = InertiaShape.from_tensor(J)
    assert np.allclose(shape.principal_moments(), np.sort(m) / np.sort(m)[0], rtol=1e-9)
    assert np.allclose(shape.J_T * J[0, 0] / shape.J_T[0, 0], J, rtol=1e-8, atol=1e-8 * np.abs(J).max())
    assert np.isclose(np.linalg.det(shape.R_TP), 1.0)


def test_inertia_entry_jacobian_agrees_with_a_central_difference():
    """The factor's derivative with respect to the five tensor entries (forward difference inside
    the factor, step 1e-6) against a central difference of the RK4 map with a 1e-4 step, on a
    non-diagonal tensor; 1e-4 relative to the largest entry."""
    t, R, w = _truth(3)
    shape = InertiaShape.from_tensor(J_T)
    f = torque_free_factor(gtsam.noiseModel.Unit.Create(6), (Y(0), W(0), Y(1), W(1), J(0)), 0.5)
    Jac, _ = f.linearize(_values(R[0], w[0], R[1], w[1], shape)).jacobian()
    p0, h = shape.entries, 1e-4
    cols = []
    for i in range(5):
        dp = h * np.eye(5)[i]
        (Rp, wp), (Rm, wm) = (propagate_batch(R[:1], w[:1], tensor_from_entries((p0 + s * dp)[None]), 0.5)
                              for s in (1.0, -1.0))
        r = [np.concatenate([rotation_error_T(Rx, R[1:2])[0], w[1] - wx[0]]) for Rx, wx in ((Rp, wp), (Rm, wm))]
        cols.append((r[0] - r[1]) / (2 * h))
    expect = np.stack(cols, axis=1)
    assert np.abs(Jac[:, 12:17] - expect).max() < 1e-4 * np.abs(expect).max()


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-np.pi, np.pi), min_size=3, max_size=3),
       st.floats(1.05, 2.0), st.floats(1.05, 2.0))
def test_tensor_entries_round_trip(rotvec, r1, r2):
    """The five trace-3 entries of a tensor give back its shape: the same tensor up to scale and the
    same principal moments, whatever the axes (no eigenvalue floor is touched for a rigid body)."""
    from scipy.spatial.transform import Rotation

    Rm = Rotation.from_rotvec(rotvec).as_matrix()
    m = np.array([1.0, r1, min(r1 * r2, 1.0 + r1 - 1e-6)])
    Jt = (Rm * (300.0 * m)) @ Rm.T
    back = tensor_from_entries(InertiaShape.from_tensor(Jt).entries[None])[0]
    assert np.isclose(np.trace(back), 3.0)
    assert np.allclose(back, Jt * 3.0 / np.trace(Jt), atol=1e-10)
    assert np.allclose(InertiaShape.from_entries(InertiaShape.from_tensor(Jt).entries).principal_moments(),
                       np.sort(m) / np.sort(m)[0], rtol=1e-9)
