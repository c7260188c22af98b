"""Euler-angle sequences 3-2-1 and 3-1-2, to and from rotation matrices.

Angles are given in sequence order and the matrix is the active ``R_AB`` (body B to reference A):

* ``"321"`` (yaw ψ, pitch θ, roll φ): ``R_AB = R_z(ψ) R_y(θ) R_x(φ)``; gimbal lock at θ = ±90°.
  This is the reading of 001 Table 1 that reproduces its failure time (flag P001-5, docs/papers.md#p001-5).
* ``"312"`` (yaw ψ, roll φ, pitch θ): ``R_AB = R_z(ψ) R_x(φ) R_y(θ)``; gimbal lock at φ = ±90°.
  This is the sequence implied by 004 eq (9)–(11) in the corrected form of flags P004-2/P004-3:
  004's ``R_ob`` is the frame-rotation (Shuster) matrix ``R_y(θ) R_x(φ) R_z(ψ)`` of passive
  elementary rotations, which equals ``R_ABᵀ`` here, so ``ψ = atan2(−R_ob21, R_ob22) =
  atan2(−R_AB01, R_AB11)``, ``φ = arcsin R_ob23 = arcsin R_AB21``, ``θ = atan2(−R_ob13, R_ob33) =
  atan2(−R_AB20, R_AB22)`` (1-based indices for R_ob, 0-based for R_AB).

Both agree with scipy's intrinsic sequences: ``Rotation.from_euler("ZYX", [ψ, θ, φ])`` and
``Rotation.from_euler("ZXY", [ψ, φ, θ])``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from attitude.matrix import check_rotation_matrix, rot_x, rot_y, rot_z

__all__ = ["SEQUENCES", "matrix_from_euler", "euler_from_matrix"]

SEQUENCES = ("321", "312")


def _check_seq(seq: str) -> None:
    if seq not in SEQUENCES:
        raise ValueError(f"seq: Euler sequence must be one of {SEQUENCES}, got {seq!r}")


def matrix_from_euler(angles_rad: ArrayLike, seq: str) -> np.ndarray:
    """Active matrix ``R_AB`` from Euler angles ``(..., 3)`` in sequence order (rad)."""
    _check_seq(seq)
    a = np.asarray(angles_rad, dtype=float)
    if a.ndim == 0 or a.shape[-1] != 3:
        raise ValueError(f"angles_rad: expected shape (..., 3), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError("angles_rad: contains non-finite values")
    if seq == "321":
        return rot_z(a[..., 0]) @ rot_y(a[..., 1]) @ rot_x(a[..., 2])
    return rot_z(a[..., 0]) @ rot_x(a[..., 1]) @ rot_y(a[..., 2])


def euler_from_matrix(R: ArrayLike, seq: str, *, lock_tol: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Euler angles (rad, sequence order) of ``R_AB`` and a gimbal-lock flag.

    The middle angle is in ``[−π/2, π/2]``, the others in ``(−π, π]``.  Where
    ``|cos(middle)| < lock_tol`` only the sum/difference of the outer angles is defined: the flag is
    set, the last angle is set to 0 and the first absorbs the rotation.

    ``R`` must hold proper rotation matrices (``max |R Rᵀ − I| <= 1e-6``, ``det R > 0``,
    :func:`attitude.matrix.check_rotation_matrix`): anything else raises ``ValueError``, since
    the angles of a non-rotation are meaningless.  A matrix whose nine entries are all NaN (a
    failed pose inside a batch) gives NaN angles and no lock flag.

    Returns
    -------
    angles : (..., 3) ndarray
    gimbal_lock : (...,) bool ndarray
    """
    _check_seq(seq)
    R = check_rotation_matrix(R, name="R", allow_nan=True)
    if seq == "321":
        s_mid = np.clip(-R[..., 2, 0], -1.0, 1.0)
        mid = np.arcsin(s_mid)
        first = np.arctan2(R[..., 1, 0], R[..., 0, 0])
        last = np.arctan2(R[..., 2, 1], R[..., 2, 2])
        first_lock = np.arctan2(-R[..., 0, 1], R[..., 1, 1])
    else:
        s_mid = np.clip(R[..., 2, 1], -1.0, 1.0)
        mid = np.arcsin(s_mid)
        first = np.arctan2(-R[..., 0, 1], R[..., 1, 1])
        last = np.arctan2(-R[..., 2, 0], R[..., 2, 2])
        first_lock = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    lock = np.sqrt(np.maximum(1.0 - s_mid * s_mid, 0.0)) < lock_tol
    first = np.where(lock, first_lock, first)
    last = np.where(lock, 0.0, last)
    return np.stack([first, mid, last], -1), lock
