"""Rotation matrices: validation, projection onto SO(3), elementary active rotations.

``R_AB`` maps B-components to A-components (``v_A = R_AB @ v_B``).  Shapes ``(..., 3, 3)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["check_rotation_matrix", "orthonormalize", "rot_x", "rot_y", "rot_z", "rotation_angle"]


def check_rotation_matrix(R: ArrayLike, *, name: str = "R", atol: float = 1e-6) -> np.ndarray:
    """Validate ``(..., 3, 3)`` proper orthonormal matrices; raise ``ValueError`` naming ``name``."""
    R = np.asarray(R, dtype=float)
    if R.ndim < 2 or R.shape[-2:] != (3, 3):
        raise ValueError(f"{name}: expected shape (..., 3, 3), got {R.shape}")
    if not np.all(np.isfinite(R)):
        raise ValueError(f"{name}: contains non-finite values")
    err = np.max(np.abs(R @ np.swapaxes(R, -1, -2) - np.eye(3)), axis=(-1, -2))
    det = np.linalg.det(R)
    if np.any(err > atol) or np.any(det < 0):
        raise ValueError(
            f"{name}: not a rotation matrix (max |R Rᵀ − I| = {np.max(err):.3g}, det = {np.min(det):.6g})"
        )
    return R


def orthonormalize(M: ArrayLike) -> np.ndarray:
    """Nearest rotation matrix in the Frobenius norm (SVD with the determinant correction)."""
    M = np.asarray(M, dtype=float)
    U, _, Vt = np.linalg.svd(M)
    d = np.sign(np.linalg.det(U @ Vt))
    D = np.ones(M.shape[:-2] + (3,))
    D[..., 2] = np.where(d == 0, 1.0, d)
    return (U * D[..., None, :]) @ Vt


def _elementary(angle: ArrayLike, axis: int) -> np.ndarray:
    a = np.asarray(angle, dtype=float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    if axis == 0:
        rows = [[o, z, z], [z, c, -s], [z, s, c]]
    elif axis == 1:
        rows = [[c, z, s], [z, o, z], [-s, z, c]]
    else:
        rows = [[c, -s, z], [s, c, z], [z, z, o]]
    return np.stack([np.stack(r, -1) for r in rows], -2)


def rot_x(angle_rad: ArrayLike) -> np.ndarray:
    """Active rotation by ``angle_rad`` about x (rotates vectors counter-clockwise)."""
    return _elementary(angle_rad, 0)


def rot_y(angle_rad: ArrayLike) -> np.ndarray:
    """Active rotation by ``angle_rad`` about y."""
    return _elementary(angle_rad, 1)


def rot_z(angle_rad: ArrayLike) -> np.ndarray:
    """Active rotation by ``angle_rad`` about z."""
    return _elementary(angle_rad, 2)


def rotation_angle(R: ArrayLike) -> np.ndarray:
    """Rotation angle in ``[0, π]`` rad of ``R`` (accurate near 0 and π via the quaternion)."""
    from attitude.quaternion import quat_angle, quat_from_matrix

    return quat_angle(quat_from_matrix(R))
