"""Euler sequences 3-2-1 and 3-1-2 (004 eq 9–11 corrected, flags P004-2 (docs/papers.md#p004-2)/3)."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from attitude.euler import euler_from_matrix, matrix_from_euler
from attitude.gibbs import gibbs_from_quat
from attitude.quaternion import quat_from_matrix

angles = st.tuples(st.floats(-3.1, 3.1), st.floats(-1.55, 1.55), st.floats(-3.1, 3.1)).map(np.array)


@given(angles)
def test_321_matches_scipy_intrinsic_ZYX_and_round_trips(a):
    R = matrix_from_euler(a, "321")
    np.testing.assert_allclose(R, Rotation.from_euler("ZYX", a).as_matrix(), atol=1e-14)
    a2, lock = euler_from_matrix(R, "321")
    assert not lock
    np.testing.assert_allclose(matrix_from_euler(a2, "321"), R, atol=1e-12)
    np.testing.assert_allclose(a2, a, atol=1e-8)


@given(angles)
def test_312_matches_scipy_intrinsic_ZXY_and_round_trips(a):
    R = matrix_from_euler(a, "312")
    np.testing.assert_allclose(R, Rotation.from_euler("ZXY", a).as_matrix(), atol=1e-14)
    a2, lock = euler_from_matrix(R, "312")
    assert not lock
    np.testing.assert_allclose(a2, a, atol=1e-8)


@given(angles)
def test_312_angles_equal_the_corrected_004_gibbs_formulas(a):
    """004 eq (9), corrected (10) and (11) on σ of R_ob = R_ABᵀ (Shuster attitude matrix)."""
    R = matrix_from_euler(a, "312")
    q = quat_from_matrix(R)
    if abs(q[0]) < 1e-3:
        return
    s1, s2, s3 = gibbs_from_quat(q)
    n2 = 1 + s1 * s1 + s2 * s2 + s3 * s3
    yaw = np.arctan2(2 * (s3 - s1 * s2), 1 - s1 * s1 + s2 * s2 - s3 * s3)
    roll = np.arcsin(2 * (s2 * s3 + s1) / n2)
    pitch = np.arctan2(2 * (s2 - s1 * s3), 1 - s1 * s1 - s2 * s2 + s3 * s3)
    np.testing.assert_allclose(euler_from_matrix(R, "312")[0], [yaw, roll, pitch], atol=1e-8)


@pytest.mark.parametrize("seq, mid", [("321", np.pi / 2), ("321", -np.pi / 2), ("312", np.pi / 2), ("312", -np.pi / 2)])
def test_gimbal_lock_is_flagged_and_matrix_is_reproduced(seq, mid):
    R = matrix_from_euler([0.4, mid, -0.3], seq)
    a, lock = euler_from_matrix(R, seq)
    assert lock
    assert a[2] == 0.0
    np.testing.assert_allclose(matrix_from_euler(a, seq), R, atol=1e-12)


def test_unknown_sequence_is_rejected_by_name():
    with pytest.raises(ValueError, match="seq: Euler sequence"):
        matrix_from_euler([0, 0, 0], "123")
