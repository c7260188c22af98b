"""The filters' private batched linear algebra: adjugate inverse and positive-definiteness mask."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from filters import _batch as kb


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
