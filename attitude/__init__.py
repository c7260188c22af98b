"""Rotation mathematics shared by every package, and torque-free rigid-body motion.

Conventions (ARCHITECTURE §2, ``docs/conventions.md``): Hamilton quaternions, scalar first
``[w, x, y, z]``; ``R_AB = matrix_from_quat(q_AB)`` maps B-components to A-components;
``R(q_AB ⊗ q_BC) = R_AB R_BC``; ``q̇_NB = ½ q_NB ⊗ [0, ω_B]``.  Paper 001's Shuster-convention
Gibbs algebra lives in :mod:`attitude.gibbs` under explicit ``shuster_`` names.
"""

from attitude.euler import euler_from_matrix, matrix_from_euler
from attitude.gibbs import (
    best_gibbs_set,
    gibbs_from_quat,
    gibbs_multiply,
    gibbs_switch,
    matrix_from_gibbs,
    mrp_from_quat,
    quat_from_gibbs,
    quat_from_gibbs_set,
    quat_from_mrp,
)
from attitude.matrix import check_rotation_matrix, orthonormalize, rot_x, rot_y, rot_z
from attitude.quaternion import (
    check_quat,
    matrix_from_quat,
    omega_matrix,
    quat_angle,
    quat_angle_between,
    quat_conjugate,
    quat_exp,
    quat_from_axis_angle,
    quat_from_matrix,
    quat_from_rotvec,
    quat_from_scipy,
    quat_log,
    quat_multiply,
    quat_normalize,
    quat_propagate_constant_rate,
    quat_rotate,
    quat_slerp,
    rotvec_from_quat,
    scipy_from_quat,
    skew,
)
from attitude.rigid_body import angular_momentum_N, kinetic_energy, propagate_torque_free

__all__ = [
    "best_gibbs_set",
    "check_quat",
    "check_rotation_matrix",
    "euler_from_matrix",
    "gibbs_from_quat",
    "gibbs_multiply",
    "gibbs_switch",
    "matrix_from_euler",
    "matrix_from_gibbs",
    "matrix_from_quat",
    "mrp_from_quat",
    "omega_matrix",
    "orthonormalize",
    "quat_angle",
    "quat_angle_between",
    "quat_conjugate",
    "quat_exp",
    "quat_from_axis_angle",
    "quat_from_gibbs",
    "quat_from_gibbs_set",
    "quat_from_matrix",
    "quat_from_mrp",
    "quat_from_rotvec",
    "quat_from_scipy",
    "quat_log",
    "quat_multiply",
    "quat_normalize",
    "quat_propagate_constant_rate",
    "quat_rotate",
    "quat_slerp",
    "propagate_torque_free",
    "angular_momentum_N",
    "kinetic_energy",
    "rot_x",
    "rot_y",
    "rot_z",
    "rotvec_from_quat",
    "scipy_from_quat",
    "skew",
]
