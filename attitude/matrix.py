"""Rotation matrices: validation, projection onto SO(3), elementary active rotations.

``R_AB`` maps B-components to A-components (``v_A = R_AB @ v_B``).  Shapes ``(..., 3, 3)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["check_rotation_matrix", "orthonormalize", "rot_x", "rot_y", "rot_z", "rotation_angle"]


def check_rotation_matrix(R: ArrayLike, *, name: str = "R", atol: float = 1e-6,
                          allow_nan: bool = False) -> np.ndarray:
    """Validate proper orthonormal matrices ``(..., 3, 3)``; raise ``ValueError`` naming ``name``.

    Parameters
    ----------
    R : array_like (..., 3, 3)
        Candidate rotation matrices.
    name : str
        Argument name used in the error message.
    atol : float
        Tolerance of the test ``max |R Rᵀ − I| <= atol`` (element-wise) together with
        ``det R > 0``; the two put ``det R`` within ``1 ± 2·atol`` to first order.  So the zero
        matrix, ``2 I``, reflections such as ``diag(1, 1, −1)`` and any matrix that is not
        orthonormal to ``atol`` are refused; a product of a few rotations (error ~1e-15) passes.
    allow_nan : bool
        Let matrices whose nine entries are all NaN through unchecked (a failed pose inside a
        batch); a matrix with only some NaN entries, or any ±inf, is still refused.

    Returns
    -------
    ndarray (..., 3, 3)
        ``R`` as a float array.

    Raises
    ------
    ValueError
        One line naming ``name``, the orthogonality residual, the determinant and the first
        offending matrix.
    """
    R = np.asarray(R, dtype=float)
    if R.ndim < 2 or R.shape[-2:] != (3, 3):
        raise ValueError(f"{name}: expected shape (..., 3, 3), got {R.shape}")
    finite = np.isfinite(R)
    if not finite.all():
        missing = np.isnan(R).all(axis=(-2, -1))
        if not allow_nan or np.any(~finite.all(axis=(-2, -1)) & ~missing):
            raise ValueError(f"{name}: contains non-finite values"
                             + (" (only whole-NaN matrices are allowed)" if allow_nan else ""))
        R_chk = np.where(missing[..., None, None], np.eye(3), R)
    else:
        R_chk = R
    err = np.max(np.abs(R_chk @ np.swapaxes(R_chk, -1, -2) - np.eye(3)), axis=(-1, -2))
    det = np.linalg.det(R_chk)
    bad = (err > atol) | ~(det > 0)
    if np.any(bad):
        idx = tuple(int(i) for i in np.argwhere(bad)[0]) if bad.ndim else ()
        first = np.array2string(R_chk[idx], separator=", ", precision=6).replace("\n", "")
        where = f" at index {idx}" if idx else ""
        raise ValueError(f"{name}: not a rotation matrix{where} (max |R Rᵀ − I| = {err[idx]:.3g}, "
                         f"det = {det[idx]:.6g}, tolerance {atol:g}): {first}")
    return R


def orthonormalize(M: ArrayLike) -> np.ndarray:
    """Nearest rotation matrix in the Frobenius norm (SVD with the determinant correction).

    Raises ``ValueError`` for a non-finite matrix and for one of rank 0 or 1 (second singular value
    ``<= 1e-12`` times the first), whose nearest rotation is not unique (the zero matrix has no
    nearest rotation at all).
    """
    M = np.asarray(M, dtype=float)
    if M.ndim < 2 or M.shape[-2:] != (3, 3):
        raise ValueError(f"M: expected shape (..., 3, 3), got {M.shape}")
    if not np.all(np.isfinite(M)):
        raise ValueError("M: contains non-finite values")
    U, sv, Vt = np.linalg.svd(M)
    low = ~(sv[..., 1] > 1e-12 * sv[..., 0])
    if np.any(low):
        idx = tuple(int(i) for i in np.argwhere(low)[0]) if low.ndim else ()
        raise ValueError(f"M: rank {int(np.sum(sv[idx] > 1e-12 * sv[idx][0]))} matrix (singular values "
                         f"{np.array2string(sv[idx], precision=3)}) has no unique nearest rotation")
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
    """Rotation angle in ``[0, π]`` rad of ``R`` (accurate near 0 and π via the quaternion).

    ``R`` must be proper rotation matrices (:func:`check_rotation_matrix`); else ``ValueError``.
    """
    from attitude.quaternion import quat_angle, quat_from_matrix

    return quat_angle(quat_from_matrix(R))
