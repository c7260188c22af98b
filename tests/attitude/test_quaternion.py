"""Quaternion algebra: conversions, composition law, sign invariance, kinematics (hypothesis)."""

import numpy as np
import pytest
from hypothesis import given, settings
from scipy.spatial.transform import Rotation

from attitude.matrix import check_rotation_matrix, orthonormalize, rot_x, rot_y, rot_z
from attitude.quaternion import (
    matrix_from_quat,
    omega_matrix,
    quat_angle,
    quat_angle_between,
    quat_conjugate,
    quat_derivative,
    quat_exp,
    quat_from_axis_angle,
    quat_from_matrix,
    quat_from_rotvec,
    quat_from_scipy,
    quat_log,
    quat_multiply,
    quat_propagate_constant_rate,
    quat_rotate,
    quat_slerp,
    rotvec_from_quat,
    scipy_from_quat,
)
from attitude.testing import assert_quat_equal
from tests.attitude.strategies import unit_quats, vectors


@given(unit_quats())
def test_matrix_round_trip_including_near_180(q):
    R = matrix_from_quat(q)
    check_rotation_matrix(R, atol=1e-12)
    q2 = quat_from_matrix(R)
    assert np.linalg.norm(q2) == pytest.approx(1.0, abs=1e-14)
    assert quat_angle_between(q, q2) < 1e-7
    np.testing.assert_allclose(matrix_from_quat(q2), R, atol=1e-14)


@given(unit_quats())
def test_q_and_minus_q_are_the_same_attitude(q):
    np.testing.assert_allclose(matrix_from_quat(q), matrix_from_quat(-q), atol=1e-15)
    assert quat_angle_between(q, -q) < 1e-7


@given(unit_quats(), unit_quats())
def test_composition_law_R_of_product_is_product_of_R(p, q):
    np.testing.assert_allclose(matrix_from_quat(quat_multiply(p, q)), matrix_from_quat(p) @ matrix_from_quat(q),
                               atol=1e-14)


@given(unit_quats(), vectors)
def test_rotation_maps_B_components_to_A_components(q, v):
    np.testing.assert_allclose(quat_rotate(q, v), matrix_from_quat(q) @ v, atol=1e-13)


@given(unit_quats())
def test_matrix_agrees_with_scipy_and_scalar_last_conversion(q):
    R_scipy = Rotation.from_quat(scipy_from_quat(q)).as_matrix()
    np.testing.assert_allclose(matrix_from_quat(q), R_scipy, atol=1e-14)
    np.testing.assert_allclose(quat_from_scipy(scipy_from_quat(q)), q)


@given(vectors)
def test_rotvec_round_trip_and_exp_log(v):
    ang = np.linalg.norm(v)
    if ang > np.pi - 1e-3:
        v = v / ang * (np.pi - 1e-3)
    q = quat_from_rotvec(v)
    np.testing.assert_allclose(rotvec_from_quat(q), v, atol=1e-12)
    np.testing.assert_allclose(quat_exp(quat_log(q)), q, atol=1e-14)
    assert quat_angle(q) == pytest.approx(np.linalg.norm(v), abs=1e-12)
    np.testing.assert_allclose(matrix_from_quat(q), Rotation.from_rotvec(v).as_matrix(), atol=1e-14)


@given(unit_quats())
def test_conjugate_is_inverse(q):
    np.testing.assert_allclose(matrix_from_quat(quat_conjugate(q)), matrix_from_quat(q).T, atol=1e-15)
    assert quat_angle(quat_multiply(q, quat_conjugate(q))) < 1e-7


@settings(max_examples=50)
@given(unit_quats(), vectors)
def test_kinematics_against_finite_differences(q, w):
    """q̇ = ½ q ⊗ [0, ω] (003 eq 25–26) against a central difference of the exact constant-rate step."""
    h = 1e-5
    fd = (quat_propagate_constant_rate(q, w, h) - quat_propagate_constant_rate(q, w, -h)) / (2 * h)
    np.testing.assert_allclose(quat_derivative(q, w), fd, atol=1e-8)
    np.testing.assert_allclose(0.5 * omega_matrix(w) @ q, quat_derivative(q, w), atol=1e-15)


@given(unit_quats(), vectors)
def test_constant_rate_step_is_rotation_about_body_axis(q, w):
    dt = 0.7
    q1 = quat_propagate_constant_rate(q, w, dt)
    np.testing.assert_allclose(matrix_from_quat(q1),
                               matrix_from_quat(q) @ Rotation.from_rotvec(w * dt).as_matrix(), atol=1e-13)


def test_slerp_endpoints_midpoint_and_shorter_arc():
    q0 = np.array([1.0, 0, 0, 0])
    q1 = quat_from_axis_angle([0, 0, 1], 1.2)
    np.testing.assert_allclose(quat_slerp(q0, q1, 0.0), q0, atol=1e-15)
    assert_quat_equal(quat_slerp(q0, q1, 1.0), q1, atol=1e-12)
    assert quat_angle_between(quat_slerp(q0, q1, 0.5), quat_from_axis_angle([0, 0, 1], 0.6)) < 1e-12
    # −q1 is the same attitude: slerp takes the shorter arc regardless of sign
    assert quat_angle_between(quat_slerp(q0, -q1, 0.5), quat_from_axis_angle([0, 0, 1], 0.6)) < 1e-12


def test_batched_shapes_broadcast_over_leading_axes():
    rng = np.random.default_rng(1)
    q = quat_from_scipy(Rotation.random(24, random_state=2).as_quat()).reshape(2, 3, 4, 4)
    w = rng.normal(size=(2, 3, 4, 3))
    assert matrix_from_quat(q).shape == (2, 3, 4, 3, 3)
    assert quat_multiply(q, q[0, 0]).shape == (2, 3, 4, 4)
    assert quat_from_matrix(matrix_from_quat(q)).shape == (2, 3, 4, 4)
    assert quat_derivative(q, w).shape == (2, 3, 4, 4)


def test_elementary_rotations_and_orthonormalize():
    a = 0.3
    np.testing.assert_allclose(rot_z(a), Rotation.from_euler("z", a).as_matrix(), atol=1e-15)
    np.testing.assert_allclose(rot_y(a), Rotation.from_euler("y", a).as_matrix(), atol=1e-15)
    np.testing.assert_allclose(rot_x(a), Rotation.from_euler("x", a).as_matrix(), atol=1e-15)
    R = rot_z(0.4) @ rot_x(-1.0)
    np.testing.assert_allclose(orthonormalize(R + 1e-4 * np.ones((3, 3))), R, atol=2e-4)


def test_bad_input_names_the_argument():
    with pytest.raises(ValueError, match="R: expected shape"):
        quat_from_matrix(np.eye(4))
    with pytest.raises(ValueError, match="omega_B"):
        quat_derivative([1.0, 0, 0, 0], [1.0, 2.0])
    with pytest.raises(ValueError, match="axis"):
        quat_from_axis_angle([0.0, 0.0, 0.0], 1.0)
    with pytest.raises(ValueError, match="R: not a rotation matrix"):
        check_rotation_matrix(np.diag([1.0, 1.0, -1.0]))


def test_axis_angle_broadcasts_a_scalar_angle_over_a_batch_of_axes():
    axes = np.eye(3)
    q = quat_from_axis_angle(axes, 0.5)
    assert q.shape == (3, 4)
    for k in range(3):
        np.testing.assert_allclose(matrix_from_quat(q[k]), Rotation.from_rotvec(0.5 * axes[k]).as_matrix(), atol=1e-15)
    assert quat_from_axis_angle([0, 0, 1], np.array([0.1, 0.2])).shape == (2, 4)
