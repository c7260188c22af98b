"""Matrix doors of ``attitude`` refuse what is not a rotation (issue 17): quaternion, Euler angles,
rotation angle, projection; Gibbs and axis-angle doors refuse a zero quaternion and NaN angles."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from attitude.euler import euler_from_matrix, matrix_from_euler
from attitude.gibbs import best_gibbs_set, gibbs_from_quat
from attitude.matrix import check_rotation_matrix, orthonormalize, rotation_angle
from attitude.quaternion import (
    matrix_from_quat,
    quat_angle_between,
    quat_from_axis_angle,
    quat_from_matrix,
)
from tests.attitude.strategies import unit_quats

NOT_ROTATIONS = {
    "zeros": np.zeros((3, 3)),
    "twice identity": 2.0 * np.eye(3),
    "reflection diag(1, 1, -1)": np.diag([1.0, 1.0, -1.0]),
    "sheared": np.array([[1.0, 0.2, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
}
DOORS = {
    "quat_from_matrix": quat_from_matrix,
    "euler_from_matrix 321": lambda R: euler_from_matrix(R, "321"),
    "euler_from_matrix 312": lambda R: euler_from_matrix(R, "312"),
    "rotation_angle": rotation_angle,
}


@pytest.mark.parametrize("door", DOORS)
@pytest.mark.parametrize("case", NOT_ROTATIONS)
def test_matrix_doors_refuse_a_non_rotation_with_a_one_line_error_naming_R(door, case):
    with pytest.raises(ValueError, match=r"^R: not a rotation matrix") as info:
        DOORS[door](NOT_ROTATIONS[case])
    assert "\n" not in str(info.value)


def test_error_names_the_index_and_the_value_of_the_first_bad_matrix_in_a_batch():
    R = np.stack([np.eye(3), np.eye(3), np.diag([1.0, 1.0, -1.0])])
    with pytest.raises(ValueError, match=r"at index \(2,\).*det = -1.*\[\[ *1\.,"):
        quat_from_matrix(R)


def test_rounding_level_non_orthogonality_is_accepted_and_1e_minus_5_is_refused():
    R = matrix_from_quat([0.3, -0.5, 0.1, 0.8])
    quat_from_matrix(R + 1e-9)  # within the 1e-6 tolerance
    with pytest.raises(ValueError, match="R: not a rotation matrix"):
        quat_from_matrix(R * (1.0 + 1e-5))


def test_euler_passes_whole_nan_matrices_as_nan_and_refuses_partial_nan_and_inf():
    R = np.stack([np.eye(3), np.full((3, 3), np.nan)])
    angles, lock = euler_from_matrix(R, "321")
    np.testing.assert_array_equal(angles[0], 0.0)
    assert np.isnan(angles[1]).all() and not lock[1]
    partial = np.eye(3)
    partial[0, 1] = np.nan
    with pytest.raises(ValueError, match="R: contains non-finite values"):
        euler_from_matrix(partial, "321")
    with pytest.raises(ValueError, match="R: contains non-finite values"):
        quat_from_matrix(np.full((3, 3), np.nan))


@given(unit_quats())
def test_any_proper_rotation_round_trips_through_the_quaternion_and_euler_doors(q):
    R = matrix_from_quat(q)
    assert quat_angle_between(quat_from_matrix(R), q) < 1e-7
    for seq in ("321", "312"):
        angles, _ = euler_from_matrix(R, seq)
        # near gimbal lock the middle angle comes from arcsin, good to about sqrt(eps) ≈ 1.5e-8
        np.testing.assert_allclose(matrix_from_euler(angles, seq), R, atol=5e-8)


@given(unit_quats(), st.integers(0, 2))
def test_any_matrix_with_negative_determinant_is_refused(q, axis):
    flip = np.ones(3)
    flip[axis] = -1.0
    with pytest.raises(ValueError, match="R: not a rotation matrix"):
        quat_from_matrix(matrix_from_quat(q) * flip)


@given(unit_quats(), st.floats(1e-4, 10.0), st.integers(0, 2))
def test_any_matrix_far_from_orthogonal_is_refused(q, stretch, axis):
    scale = np.ones(3)
    scale[axis] += stretch
    with pytest.raises(ValueError, match="R: not a rotation matrix"):
        euler_from_matrix(matrix_from_quat(q) * scale, "321")


def test_orthonormalize_refuses_non_finite_and_rank_deficient_matrices():
    with pytest.raises(ValueError, match="M: contains non-finite"):
        orthonormalize(np.full((3, 3), np.nan))
    with pytest.raises(ValueError, match="M: rank 0"):
        orthonormalize(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="M: rank 1"):
        orthonormalize(np.outer([1.0, 2.0, 3.0], [0.0, 1.0, 0.0]))
    check_rotation_matrix(orthonormalize(np.diag([1.0, 1.0, 0.0])), atol=1e-12)  # rank 2: unique


def test_gibbs_doors_refuse_the_zero_quaternion_and_axis_angle_refuses_nan_angles():
    for door in (gibbs_from_quat, best_gibbs_set):
        with pytest.raises(ValueError, match="q: the zero quaternion is no rotation"):
            door(np.zeros(4))
    with pytest.raises(ValueError, match="angle_rad: contains non-finite values, got nan"):
        quat_from_axis_angle([1.0, 0.0, 0.0], np.nan)
    with pytest.raises(ValueError, match="angles_rad: contains non-finite"):
        matrix_from_euler([0.0, np.inf, 0.0], "321")
