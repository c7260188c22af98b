"""Batched rotation kernels: round trips, agreement with scipy, products against matrices (hypothesis)."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from attitude import batch as B
from attitude.quaternion import (
    matrix_from_quat,
    omega_matrix,
    quat_conjugate,
    quat_from_rotvec,
    quat_multiply,
    rotvec_from_quat,
    skew,
)
from attitude.testing import assert_quat_equal
from tests.attitude.strategies import unit_quats, vectors

quat_batches = st.lists(unit_quats(), min_size=1, max_size=6).map(np.stack)
vector_batches = st.lists(vectors, min_size=1, max_size=6).map(np.stack)


def to_scipy(q: np.ndarray) -> Rotation:
    """scipy's quaternions are scalar last: ``[x, y, z, w]``."""
    return Rotation.from_quat(np.concatenate([q[..., 1:], q[..., :1]], -1))


def from_scipy(r: Rotation) -> np.ndarray:
    xyzw = r.as_quat()
    return np.concatenate([xyzw[..., 3:], xyzw[..., :3]], -1)


@given(quat_batches)
def test_matrices_from_quaternions_agree_with_scipy(q):
    np.testing.assert_allclose(B.matrices_from_quaternions(q), to_scipy(q).as_matrix(), atol=1e-14)


@given(quat_batches)
def test_quaternion_matrix_round_trip_is_the_same_attitude_with_w_nonnegative(q):
    q2 = B.quaternions_from_matrices(B.matrices_from_quaternions(q))
    assert np.all(q2[:, 0] >= 0.0)
    assert_quat_equal(q2, q, atol=1e-7)  # near 180° the matrix fixes the axis only to ~1e-8
    assert_quat_equal(q2, from_scipy(Rotation.from_matrix(B.matrices_from_quaternions(q))), atol=1e-7)


@given(quat_batches, quat_batches)
def test_products_compose_matrices_and_equal_the_left_and_right_matrix_forms(p, q):
    n = min(len(p), len(q))
    p, q = p[:n], q[:n]
    pq = B.quaternion_products(p, q)
    np.testing.assert_allclose(B.matrices_from_quaternions(pq),
                               B.matrices_from_quaternions(p) @ B.matrices_from_quaternions(q), atol=1e-14)
    np.testing.assert_allclose((B.quaternion_left_matrices(p) @ q[..., None])[..., 0], pq, atol=1e-15)
    np.testing.assert_allclose((B.quaternion_right_matrices(q) @ p[..., None])[..., 0], pq, atol=1e-15)
    assert_quat_equal(pq, from_scipy(to_scipy(p) * to_scipy(q)), atol=1e-14)


@given(quat_batches)
def test_conjugate_is_the_inverse_rotation(q):
    identity = B.quaternion_products(q, B.quaternion_conjugates(q))
    assert_quat_equal(identity, np.broadcast_to([1.0, 0, 0, 0], q.shape), atol=1e-15)


@given(quat_batches, vector_batches)
def test_xi_and_omega_matrices_are_products_with_a_pure_quaternion(q, v):
    n = min(len(q), len(v))
    q, v = q[:n], v[:n]
    pure = np.concatenate([np.zeros((n, 1)), v], -1)
    expected = B.quaternion_products(q, pure)
    np.testing.assert_allclose((B.xi_matrices(q) @ v[..., None])[..., 0], expected, atol=1e-14)
    np.testing.assert_allclose((B.omega_matrices(v) @ q[..., None])[..., 0], expected, atol=1e-14)


@given(vector_batches, vector_batches)
def test_cross_product_matrices_give_the_cross_product(a, b):
    n = min(len(a), len(b))
    a, b = a[:n], b[:n]
    np.testing.assert_allclose((B.cross_product_matrices(a) @ b[..., None])[..., 0], np.cross(a, b), atol=1e-14)


@given(vector_batches)
def test_rotvec_quaternion_round_trip_agrees_with_scipy(v):
    q = B.quaternions_from_rotvecs(v)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-15)
    assert_quat_equal(q, from_scipy(Rotation.from_rotvec(v)), atol=1e-15)
    # |v| ≤ 3√3 may exceed π: the rotation vector comes back as the equivalent one of angle ≤ π
    np.testing.assert_allclose(B.matrices_from_quaternions(q),
                               B.matrices_from_rotvecs(B.rotvecs_from_quaternions(q)), atol=1e-13)
    np.testing.assert_allclose(B.rotvecs_from_quaternions(q), Rotation.from_rotvec(v).as_rotvec(), atol=1e-12)


@given(quat_batches)
def test_rotvecs_from_quaternions_are_sign_invariant_with_angle_at_most_pi(q):
    r = B.rotvecs_from_quaternions(q)
    np.testing.assert_array_equal(r, B.rotvecs_from_quaternions(-q))
    assert np.all(np.linalg.norm(r, axis=-1) <= np.pi + 1e-15)


@given(vector_batches)
def test_matrices_from_rotvecs_agree_with_scipy(v):
    np.testing.assert_allclose(B.matrices_from_rotvecs(v), Rotation.from_rotvec(v).as_matrix(), atol=1e-14)


@given(vector_batches)
def test_rotvecs_from_matrices_invert_rodrigues_below_179_degrees(v):
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    v = np.where(angle > np.deg2rad(179.0), v / np.maximum(angle, 1e-300) * np.deg2rad(179.0), v)
    np.testing.assert_allclose(B.rotvecs_from_matrices(B.matrices_from_rotvecs(v)), v, atol=1e-12)


def test_small_angle_branches_are_continuous_with_the_closed_forms():
    """The Taylor branches switch at |v|/2 = 1e-4 (exp), |q_v| = 1e-8 (log), θ² = 1e-12 (Rodrigues)."""
    axis = np.array([0.6, -0.48, 0.64])
    for angle in (1e-12, 1e-9, 2e-8 * (1 - 1e-9), 2e-8 * (1 + 1e-9), 1e-6 * (1 - 1e-9), 1e-6 * (1 + 1e-9),
                  2e-4 * (1 - 1e-9), 2e-4 * (1 + 1e-9), 1e-2):
        v = angle * axis
        q = B.quaternions_from_rotvecs(v)
        assert_quat_equal(q, from_scipy(Rotation.from_rotvec(v)), atol=1e-17)
        np.testing.assert_allclose(B.rotvecs_from_quaternions(q), v, rtol=1e-15, atol=0)
        np.testing.assert_allclose(B.matrices_from_rotvecs(v), Rotation.from_rotvec(v).as_matrix(), atol=1e-17)
        np.testing.assert_allclose(B.rotvecs_from_matrices(B.matrices_from_rotvecs(v)), v, rtol=1e-7, atol=1e-22)


def test_kernels_keep_leading_axes():
    q = from_scipy(Rotation.random(24, random_state=3)).reshape(2, 3, 4, 4)
    v = np.random.default_rng(0).normal(size=(2, 3, 4, 3))
    assert B.matrices_from_quaternions(q).shape == (2, 3, 4, 3, 3)
    assert B.quaternions_from_matrices(B.matrices_from_quaternions(q)).shape == (2, 3, 4, 4)
    assert B.quaternion_products(q, q[0, 0]).shape == (2, 3, 4, 4)
    assert B.xi_matrices(q).shape == (2, 3, 4, 4, 3)
    assert B.omega_matrices(v).shape == (2, 3, 4, 4, 4)
    assert B.cross_product_matrices(v).shape == (2, 3, 4, 3, 3)
    assert B.rotvecs_from_quaternions(q).shape == (2, 3, 4, 3)
    assert B.rotvecs_from_matrices(B.matrices_from_rotvecs(v)).shape == (2, 3, 4, 3)


def test_nan_rows_stay_nan_rows_without_touching_the_others():
    q = np.array([[1.0, 0, 0, 0], [np.nan] * 4])
    v = np.array([[0.1, 0.2, 0.3], [np.nan] * 3])
    for out in (B.matrices_from_quaternions(q), B.rotvecs_from_quaternions(q), B.quaternions_from_rotvecs(v),
                B.matrices_from_rotvecs(v), B.rotvecs_from_matrices(B.matrices_from_rotvecs(v))):
        assert np.all(np.isfinite(out[0])) and np.all(np.isnan(out[1]))


def test_assert_quat_equal_ignores_the_sign_but_not_the_attitude():
    q = from_scipy(Rotation.random(5, random_state=4))
    assert_quat_equal(-q, q, atol=0.0)
    assert_quat_equal(np.where(np.arange(5)[:, None] % 2 == 0, q, -q), q, atol=0.0)
    with pytest.raises(AssertionError, match="up to the sign"):
        assert_quat_equal(q, B.quaternion_products(q, B.quaternions_from_rotvecs(np.array([1e-6, 0.0, 0.0]))), atol=1e-9)
    with pytest.raises(ValueError, match="expected: expected shape"):
        assert_quat_equal(q, q[:, :3])


# --------------------------------------------------------------- kernels = validated doors
@given(unit_quats(), unit_quats())
def test_products_left_and_right_matrices_equal_hamilton_product(p, q):
    ref = quat_multiply(p, q)
    np.testing.assert_allclose(B.quaternion_products(p[None], q[None])[0], ref, atol=1e-15)
    np.testing.assert_allclose(B.quaternion_left_matrices(p) @ q, ref, atol=1e-15)
    np.testing.assert_allclose(B.quaternion_right_matrices(q) @ p, ref, atol=1e-15)
    np.testing.assert_allclose(B.quaternion_conjugates(q), quat_conjugate(q), atol=0)


@given(unit_quats(), vectors)
def test_xi_omega_and_skew_match_003_eq26_and_cross_product(q, v):
    np.testing.assert_allclose(B.xi_matrices(q) @ v, quat_multiply(q, np.r_[0.0, v]), atol=1e-14)
    np.testing.assert_allclose(B.omega_matrices(v), omega_matrix(v), atol=0)
    np.testing.assert_allclose(B.cross_product_matrices(v), skew(v), atol=0)
    w = v[::-1] + 0.3
    np.testing.assert_allclose((B.cross_product_matrices(v[None]) @ w[None, :, None])[0, :, 0], np.cross(v, w), atol=1e-14)


@given(vectors)
def test_rotvec_exp_and_log_are_inverse_and_match_attitude(v):
    v = v * 0.99 * np.pi / max(np.linalg.norm(v), np.pi)  # angle below π: unique rotation vector
    q = B.quaternions_from_rotvecs(v[None])[0]
    np.testing.assert_allclose(q, quat_from_rotvec(v), atol=1e-15)
    np.testing.assert_allclose(B.rotvecs_from_quaternions(q[None])[0], v, atol=1e-12)
    np.testing.assert_allclose(B.rotvecs_from_quaternions(-q[None])[0], rotvec_from_quat(q), atol=1e-12)


@given(unit_quats())
def test_unit_quaternion_matrices_equal_attitude_matrix(q):
    np.testing.assert_allclose(B.matrices_from_quaternions(q[None])[0], matrix_from_quat(q), atol=1e-14)
