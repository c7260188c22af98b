"""Unit quaternions: Hamilton product, scalar first ``[w, x, y, z]`` (ARCHITECTURE §2).

``q_AB`` is the rotation whose matrix ``R_AB = matrix_from_quat(q_AB)`` maps B-components to
A-components, ``v_A = R_AB @ v_B``, and ``R(q_AB ⊗ q_BC) = R_AB @ R_BC``.  ``q`` and ``-q`` are the
same attitude.  Every function is vectorised over leading batch axes: quaternions ``(..., 4)``,
vectors ``(..., 3)``, matrices ``(..., 3, 3)``.

Kinematics (003 eq 25–26): ``q̇_NB = ½ q_NB ⊗ [0, ω_B]`` with ω_B the rate of B relative to N in
B components.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "check_quat",
    "quat_multiply",
    "quat_conjugate",
    "quat_normalize",
    "quat_canonical",
    "matrix_from_quat",
    "quat_from_matrix",
    "quat_from_axis_angle",
    "quat_exp",
    "quat_log",
    "quat_from_rotvec",
    "rotvec_from_quat",
    "quat_angle",
    "quat_angle_between",
    "quat_slerp",
    "quat_rotate",
    "omega_matrix",
    "quat_derivative",
    "quat_propagate_constant_rate",
    "quat_from_scipy",
    "scipy_from_quat",
    "skew",
]


def _as_float(a: ArrayLike) -> np.ndarray:
    return np.asarray(a, dtype=float)


def check_quat(q: ArrayLike, *, name: str = "q", unit: bool = True, atol: float = 1e-6) -> np.ndarray:
    """Validate a quaternion array ``(..., 4)``; raise ``ValueError`` naming ``name`` if invalid.

    With ``unit=True`` the norm must be 1 within ``atol``.
    """
    arr = _as_float(q)
    if arr.ndim == 0 or arr.shape[-1] != 4:
        raise ValueError(f"{name}: expected shape (..., 4), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: contains non-finite values")
    if unit:
        n = np.linalg.norm(arr, axis=-1)
        bad = np.abs(n - 1.0) > atol
        if np.any(bad):
            raise ValueError(f"{name}: not a unit quaternion (norm {n[bad].ravel()[0]!r})")
    return arr


def check_vec3(v: ArrayLike, *, name: str = "v") -> np.ndarray:
    """Validate a vector array ``(..., 3)``; raise ``ValueError`` naming ``name`` if invalid."""
    arr = _as_float(v)
    if arr.ndim == 0 or arr.shape[-1] != 3:
        raise ValueError(f"{name}: expected shape (..., 3), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: contains non-finite values")
    return arr


def skew(v: ArrayLike) -> np.ndarray:
    """Cross-product matrix ``[v×]`` with ``skew(v) @ w == cross(v, w)``; ``(..., 3) → (..., 3, 3)``."""
    v = _as_float(v)
    z = np.zeros_like(v[..., 0])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack(
        [np.stack([z, -w, y], -1), np.stack([w, z, -x], -1), np.stack([-y, x, z], -1)], -2
    )


def quat_multiply(p: ArrayLike, q: ArrayLike) -> np.ndarray:
    """Hamilton product ``p ⊗ q`` (scalar first), broadcasting over leading axes.

    ``[p0 q0 − p·q, p0 q + q0 p + p × q]``; ``matrix_from_quat(p ⊗ q) = R(p) @ R(q)``.
    """
    p = _as_float(p)
    q = _as_float(q)
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )


def quat_conjugate(q: ArrayLike) -> np.ndarray:
    """Conjugate ``[w, −x, −y, −z]``: the inverse rotation of a unit quaternion (``q_BA`` from ``q_AB``)."""
    q = _as_float(q)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q: ArrayLike) -> np.ndarray:
    """Scale to unit norm; raises ``ValueError`` for a zero quaternion."""
    q = _as_float(q)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(n == 0) or not np.all(np.isfinite(n)):
        raise ValueError("q: cannot normalise a zero or non-finite quaternion")
    return q / n


def quat_canonical(q: ArrayLike) -> np.ndarray:
    """Representative with ``w >= 0`` (for ``w == 0`` the first non-zero component positive)."""
    q = _as_float(q)
    s = np.sign(q[..., 0])
    for k in (1, 2, 3):
        s = np.where(s == 0, np.sign(q[..., k]), s)
    s = np.where(s == 0, 1.0, s)
    return q * s[..., None]


def matrix_from_quat(q: ArrayLike) -> np.ndarray:
    """Rotation matrix ``R_AB`` of ``q_AB`` (Hamilton, active): ``(..., 4) → (..., 3, 3)``.

    The quaternion is normalised first, so slightly non-unit input gives an orthonormal matrix.
    """
    q = quat_normalize(q)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return np.stack(
        [
            np.stack([1 - 2 * (yy + zz), 2 * (xy - wz), 2 * (xz + wy)], -1),
            np.stack([2 * (xy + wz), 1 - 2 * (xx + zz), 2 * (yz - wx)], -1),
            np.stack([2 * (xz - wy), 2 * (yz + wx), 1 - 2 * (xx + yy)], -1),
        ],
        -2,
    )


def quat_from_matrix(R: ArrayLike) -> np.ndarray:
    """Unit quaternion of a rotation matrix, robust at any angle including 180° (Shepperd's method).

    For each matrix the largest of ``4w², 4x², 4y², 4z²`` is used as the pivot, so no division by
    a small number occurs.  The result has ``w >= 0``.  ``(..., 3, 3) → (..., 4)``.
    Non-orthonormal input is not projected; use :func:`attitude.matrix.orthonormalize` first.
    """
    R = _as_float(R)
    if R.shape[-2:] != (3, 3):
        raise ValueError(f"R: expected shape (..., 3, 3), got {R.shape}")
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = m00 + m11 + m22
    cand = np.stack([tr, m00, m11, m22], -1)
    k = np.argmax(cand, axis=-1)
    out = np.empty(R.shape[:-2] + (4,))
    # case w largest
    r = np.sqrt(np.maximum(1.0 + tr, 0.0))
    s = np.where(r > 0, 0.5 / np.where(r > 0, r, 1.0), 0.0)
    qw = np.stack([0.5 * r, (R[..., 2, 1] - R[..., 1, 2]) * s, (R[..., 0, 2] - R[..., 2, 0]) * s,
                   (R[..., 1, 0] - R[..., 0, 1]) * s], -1)
    r = np.sqrt(np.maximum(1.0 + m00 - m11 - m22, 0.0))
    s = np.where(r > 0, 0.5 / np.where(r > 0, r, 1.0), 0.0)
    qx = np.stack([(R[..., 2, 1] - R[..., 1, 2]) * s, 0.5 * r, (R[..., 0, 1] + R[..., 1, 0]) * s,
                   (R[..., 0, 2] + R[..., 2, 0]) * s], -1)
    r = np.sqrt(np.maximum(1.0 - m00 + m11 - m22, 0.0))
    s = np.where(r > 0, 0.5 / np.where(r > 0, r, 1.0), 0.0)
    qy = np.stack([(R[..., 0, 2] - R[..., 2, 0]) * s, (R[..., 0, 1] + R[..., 1, 0]) * s, 0.5 * r,
                   (R[..., 1, 2] + R[..., 2, 1]) * s], -1)
    r = np.sqrt(np.maximum(1.0 - m00 - m11 + m22, 0.0))
    s = np.where(r > 0, 0.5 / np.where(r > 0, r, 1.0), 0.0)
    qz = np.stack([(R[..., 1, 0] - R[..., 0, 1]) * s, (R[..., 0, 2] + R[..., 2, 0]) * s,
                   (R[..., 1, 2] + R[..., 2, 1]) * s, 0.5 * r], -1)
    kk = k[..., None]
    out = np.where(kk == 0, qw, np.where(kk == 1, qx, np.where(kk == 2, qy, qz)))
    return quat_canonical(quat_normalize(out))


def quat_from_axis_angle(axis: ArrayLike, angle_rad: ArrayLike) -> np.ndarray:
    """Quaternion of a rotation by ``angle_rad`` about the unit ``axis`` ``(..., 3)``."""
    axis = check_vec3(axis, name="axis")
    n = np.linalg.norm(axis, axis=-1, keepdims=True)
    if np.any(n == 0):
        raise ValueError("axis: zero-length rotation axis")
    half = 0.5 * _as_float(angle_rad)[..., None]
    u = axis / n
    shape = np.broadcast_shapes(half.shape[:-1], u.shape[:-1])
    half = np.broadcast_to(half, shape + (1,))
    return np.concatenate([np.cos(half), np.sin(half) * np.broadcast_to(u, shape + (3,))], -1)


def quat_exp(v: ArrayLike) -> np.ndarray:
    """Quaternion exponential of the pure quaternion ``[0, v]``: ``[cos|v|, sin|v| v/|v|]``.

    ``quat_exp(θ n / 2)`` is the rotation by θ about n.  Accurate for ``|v| → 0`` (Taylor series).
    """
    v = check_vec3(v, name="v")
    a = np.linalg.norm(v, axis=-1, keepdims=True)
    small = a < 1e-4
    a_safe = np.where(small, 1.0, a)
    sinc = np.where(small, 1.0 - a * a / 6.0 + a**4 / 120.0, np.sin(a_safe) / a_safe)
    return np.concatenate([np.cos(a), sinc * v], -1)


def quat_log(q: ArrayLike) -> np.ndarray:
    """Vector part of the logarithm of a unit quaternion (inverse of :func:`quat_exp`).

    Uses the representative with ``w >= 0`` so the result has norm ``<= π/2``.
    """
    q = quat_canonical(quat_normalize(q))
    w = np.clip(q[..., :1], -1.0, 1.0)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    a = np.arctan2(s, w)
    small = s < 1e-8
    # near identity w ≈ 1 and atan2(s, w)/s → 1/w (w > 0 there since |q| = 1 and w >= 0)
    factor = np.where(small, 1.0 / np.maximum(w, 0.5), a / np.where(small, 1.0, s))
    return factor * v


def quat_from_rotvec(rotvec: ArrayLike) -> np.ndarray:
    """Quaternion of a rotation vector ``θ n`` (rad)."""
    return quat_exp(0.5 * check_vec3(rotvec, name="rotvec"))


def rotvec_from_quat(q: ArrayLike) -> np.ndarray:
    """Rotation vector ``θ n`` with ``θ ∈ [0, π]`` of a unit quaternion."""
    return 2.0 * quat_log(q)


def quat_angle(q: ArrayLike) -> np.ndarray:
    """Rotation angle in ``[0, π]`` rad of ``q`` (sign-invariant); accurate near 0 and π."""
    q = quat_normalize(q)
    return 2.0 * np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), np.abs(q[..., 0]))


def quat_angle_between(q1: ArrayLike, q2: ArrayLike) -> np.ndarray:
    """Angle in rad ``[0, π]`` of the rotation taking attitude ``q1`` to ``q2``; ``q`` and ``−q`` equal."""
    return quat_angle(quat_multiply(quat_conjugate(q1), q2))


def quat_slerp(q0: ArrayLike, q1: ArrayLike, s: ArrayLike) -> np.ndarray:
    """Spherical linear interpolation along the shorter arc; ``s`` in ``[0, 1]`` broadcasts."""
    q0 = quat_normalize(q0)
    q1 = quat_normalize(q1)
    d = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(d < 0, -q1, q1)
    rel = quat_multiply(quat_conjugate(q0), q1)
    s = _as_float(s)[..., None]
    return quat_normalize(quat_multiply(q0, quat_exp(s * quat_log(rel))))


def quat_rotate(q: ArrayLike, v: ArrayLike) -> np.ndarray:
    """Rotate vectors: ``R(q) @ v`` computed without forming the matrix, ``(..., 4), (..., 3)``."""
    q = _as_float(q)
    v = _as_float(v)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def omega_matrix(omega: ArrayLike) -> np.ndarray:
    """4×4 matrix Ω(ω) of 003 eq (26): ``q̇ = ½ Ω(ω) q`` for ``q̇ = ½ q ⊗ [0, ω]``, ``(..., 3) → (..., 4, 4)``."""
    w = check_vec3(omega, name="omega")
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    o = np.zeros_like(x)
    return np.stack(
        [
            np.stack([o, -x, -y, -z], -1),
            np.stack([x, o, z, -y], -1),
            np.stack([y, -z, o, x], -1),
            np.stack([z, y, -x, o], -1),
        ],
        -2,
    )


def quat_derivative(q: ArrayLike, omega_B: ArrayLike) -> np.ndarray:
    """``q̇_NB = ½ q_NB ⊗ [0, ω_B]`` (003 eq 25–26), ω in rad/s in body components."""
    w = check_vec3(omega_B, name="omega_B")
    return 0.5 * quat_multiply(q, np.concatenate([np.zeros_like(w[..., :1]), w], -1))


def quat_propagate_constant_rate(q: ArrayLike, omega_B: ArrayLike, dt_s: ArrayLike) -> np.ndarray:
    """Exact propagation over ``dt_s`` at constant body rate: ``q ⊗ exp(ω dt / 2)``."""
    w = check_vec3(omega_B, name="omega_B")
    dt = _as_float(dt_s)[..., None]
    return quat_multiply(q, quat_exp(0.5 * w * dt))


def quat_from_scipy(q_xyzw: ArrayLike) -> np.ndarray:
    """Convert scipy's scalar-last ``[x, y, z, w]`` (``Rotation.as_quat()``) to ``[w, x, y, z]``.

    scipy's ``Rotation.from_quat(xyzw).as_matrix()`` is the same active matrix ``R_AB``.
    """
    q = _as_float(q_xyzw)
    return np.concatenate([q[..., 3:], q[..., :3]], -1)


def scipy_from_quat(q: ArrayLike) -> np.ndarray:
    """Convert ``[w, x, y, z]`` to scipy's ``[x, y, z, w]``."""
    q = _as_float(q)
    return np.concatenate([q[..., 1:], q[..., :1]], -1)
