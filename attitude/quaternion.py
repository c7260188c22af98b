"""Unit quaternions: Hamilton product, scalar first ``[w, x, y, z]`` (``docs/conventions.md``).

``q_AB`` is the rotation whose matrix ``R_AB = matrix_from_quat(q_AB)`` maps B-components to
A-components, ``v_A = R_AB @ v_B``, and ``R(q_AB ⊗ q_BC) = R_AB @ R_BC``.  ``q`` and ``-q`` are the
same attitude.  Every function is vectorised over leading batch axes: quaternions ``(..., 4)``,
vectors ``(..., 3)``, matrices ``(..., 3, 3)``.

Each function validates its input and then calls the unchecked kernel of :mod:`attitude.batch`
(the hot loops call those kernels directly).

Kinematics (003 eq 25–26): ``q̇_NB = ½ q_NB ⊗ [0, ω_B]`` with ω_B the rate of B relative to N in
B components.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from attitude import batch
from attitude.matrix import check_rotation_matrix

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
    """Cross-product matrix ``[v×]`` with ``skew(v) @ w == cross(v, w)``; ``(..., 3) → (..., 3, 3)``.

    Not value-checked: NaN components give NaN entries (the callers run inside sweeps).
    """
    v = _as_float(v)
    if v.ndim == 0 or v.shape[-1] != 3:
        raise ValueError(f"v: expected shape (..., 3), got {v.shape}")
    return batch.cross_product_matrices(v)


def quat_multiply(p: ArrayLike, q: ArrayLike) -> np.ndarray:
    """Hamilton product ``p ⊗ q`` (scalar first), broadcasting over leading axes.

    ``[p0 q0 − p·q, p0 q + q0 p + p × q]``; ``matrix_from_quat(p ⊗ q) = R(p) @ R(q)``.
    """
    return batch.quaternion_products(_as_float(p), _as_float(q))


def quat_conjugate(q: ArrayLike) -> np.ndarray:
    """Conjugate ``[w, −x, −y, −z]``: the inverse rotation of a unit quaternion (``q_BA`` from ``q_AB``)."""
    return batch.quaternion_conjugates(_as_float(q))


def quat_normalize(q: ArrayLike) -> np.ndarray:
    """Scale to unit norm; raises ``ValueError`` for a zero quaternion."""
    q = _as_float(q)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(n == 0) or not np.all(np.isfinite(n)):
        raise ValueError("q: cannot normalise a zero or non-finite quaternion")
    return q / n


def quat_canonical(q: ArrayLike) -> np.ndarray:
    """Representative with ``w >= 0`` (for ``w == 0`` the first non-zero component positive)."""
    return batch.canonical_quaternions(_as_float(q))


def matrix_from_quat(q: ArrayLike) -> np.ndarray:
    """Rotation matrix ``R_AB`` of ``q_AB`` (Hamilton, active): ``(..., 4) → (..., 3, 3)``.

    The quaternion is normalised first, so slightly non-unit input gives an orthonormal matrix.
    """
    return batch.matrices_from_quaternions(quat_normalize(q))


def quat_from_matrix(R: ArrayLike, *, atol: float = 1e-6) -> np.ndarray:
    """Unit quaternion of a rotation matrix, robust at any angle including 180° (Shepperd's method).

    For each matrix the largest of ``4w², 4x², 4y², 4z²`` is used as the pivot, so no division by
    a small number occurs.  The result has ``w >= 0``.  ``(..., 3, 3) → (..., 4)``.

    Parameters
    ----------
    R : array_like (..., 3, 3)
        Proper rotation matrices: ``max |R Rᵀ − I| <= atol`` and ``det R > 0``
        (:func:`attitude.matrix.check_rotation_matrix`).  Anything else (the zero matrix, ``2 I``,
        a reflection, a matrix far from orthonormal, a non-finite entry) raises ``ValueError``;
        project a nearly orthonormal matrix with :func:`attitude.matrix.orthonormalize` first.
    atol : float, keyword-only
        Orthogonality tolerance.

    Returns
    -------
    ndarray (..., 4)
    """
    return batch.quaternions_from_matrices(check_rotation_matrix(R, name="R", atol=atol))


def quat_from_axis_angle(axis: ArrayLike, angle_rad: ArrayLike) -> np.ndarray:
    """Quaternion of a rotation by ``angle_rad`` about the unit ``axis`` ``(..., 3)``."""
    axis = check_vec3(axis, name="axis")
    n = np.linalg.norm(axis, axis=-1, keepdims=True)
    if np.any(n == 0):
        raise ValueError("axis: zero-length rotation axis")
    angle = _as_float(angle_rad)
    if not np.all(np.isfinite(angle)):
        raise ValueError(f"angle_rad: contains non-finite values, got {float(angle[~np.isfinite(angle)].ravel()[0])!r}")
    half = 0.5 * angle[..., None]
    u = axis / n
    shape = np.broadcast_shapes(half.shape[:-1], u.shape[:-1])
    half = np.broadcast_to(half, shape + (1,))
    return np.concatenate([np.cos(half), np.sin(half) * np.broadcast_to(u, shape + (3,))], -1)


def quat_exp(v: ArrayLike) -> np.ndarray:
    """Quaternion exponential of the pure quaternion ``[0, v]``: ``[cos|v|, sin|v| v/|v|]``.

    ``quat_exp(θ n / 2)`` is the rotation by θ about n.  Accurate for ``|v| → 0`` (Taylor series).
    """
    return batch.quaternions_from_rotvecs(2.0 * check_vec3(v, name="v"))


def quat_log(q: ArrayLike) -> np.ndarray:
    """Vector part of the logarithm of a unit quaternion (inverse of :func:`quat_exp`).

    Uses the representative with ``w >= 0`` so the result has norm ``<= π/2``.
    """
    return 0.5 * batch.rotvecs_from_quaternions(quat_normalize(q))


def quat_from_rotvec(rotvec: ArrayLike) -> np.ndarray:
    """Quaternion of a rotation vector ``θ n`` (rad)."""
    return batch.quaternions_from_rotvecs(check_vec3(rotvec, name="rotvec"))


def rotvec_from_quat(q: ArrayLike) -> np.ndarray:
    """Rotation vector ``θ n`` with ``θ ∈ [0, π]`` of a unit quaternion."""
    return batch.rotvecs_from_quaternions(quat_normalize(q))


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
    return batch.omega_matrices(check_vec3(omega, name="omega"))


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
