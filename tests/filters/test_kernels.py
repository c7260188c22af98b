"""The private batched kernels equal the validated rotation algebra of ``attitude`` (property tests)."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from attitude.quaternion import (
    matrix_from_quat,
    omega_matrix,
    quat_conjugate,
    quat_from_rotvec,
    quat_multiply,
    rotvec_from_quat,
    skew,
)
from filters import _batch as kb
from tests.attitude.strategies import unit_quats, vectors


@given(unit_quats(), unit_quats())
def test_qmul_left_and_right_matrices_equal_hamilton_product(p, q):
    ref = quat_multiply(p, q)
    np.testing.assert_allclose(kb.qmul(p[None], q[None])[0], ref, atol=1e-15)
    np.testing.assert_allclose(kb.left_matrix(p) @ q, ref, atol=1e-15)
    np.testing.assert_allclose(kb.right_matrix(q) @ p, ref, atol=1e-15)
    np.testing.assert_allclose(kb.conj(q), quat_conjugate(q), atol=0)


@given(unit_quats(), vectors)
def test_xi_omega_and_skew_match_003_eq26_and_cross_product(q, v):
    np.testing.assert_allclose(kb.xi_matrix(q) @ v, quat_multiply(q, np.r_[0.0, v]), atol=1e-14)
    np.testing.assert_allclose(kb.omega4(v), omega_matrix(v), atol=0)
    np.testing.assert_allclose(kb.skew(v), skew(v), atol=0)
    w = v[::-1] + 0.3
    np.testing.assert_allclose(kb.cross(v[None], w[None])[0], np.cross(v, w), atol=1e-14)


@given(vectors)
def test_qexp_half_and_rotvec_are_inverse_and_match_attitude(v):
    v = v * 0.99 * np.pi / max(np.linalg.norm(v), np.pi)  # angle below π: unique rotation vector
    q = kb.qexp_half(v[None])[0]
    np.testing.assert_allclose(q, quat_from_rotvec(v), atol=1e-15)
    np.testing.assert_allclose(kb.rotvec(q[None])[0], v, atol=1e-12)
    np.testing.assert_allclose(kb.rotvec(-q[None])[0], rotvec_from_quat(q), atol=1e-12)


@given(unit_quats())
def test_matrix_from_unit_quat_equals_attitude_matrix(q):
    np.testing.assert_allclose(kb.matrix_from_unit_quat(q[None])[0], matrix_from_quat(q), atol=1e-14)


@settings(max_examples=50)
@given(st.integers(0, 2**32 - 1))
def test_inv3_equals_numpy_inverse_and_flags_singular_rows(seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(5, 3, 3))
    A = A @ np.swapaxes(A, -1, -2) + 0.1 * np.eye(3)
    A[2] = np.diag([1.0, 1.0, 0.0])  # singular
    inv, det = kb.inv3(A)
    ok = np.array([True, True, False, True, True])
    np.testing.assert_allclose(inv[ok], np.linalg.inv(A[ok]), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(det, np.linalg.det(A), atol=1e-12)
    np.testing.assert_array_equal(inv[2], np.eye(3))


def test_positive_definite_flags_only_the_indefinite_and_non_finite_rows():
    P = np.tile(np.eye(4), (4, 1, 1))
    P[1, 2, 2] = -1e-3
    P[3, 0, 1] = np.nan
    np.testing.assert_array_equal(kb.positive_definite(P), [True, False, True, False])
