"""Batched rotation kernels for hot loops: plural names, leading batch axes, no validation.

Every function takes arrays with any number of leading axes — vectors ``(..., 3)``, quaternions
``(..., 4)`` (Hamilton, scalar first ``[w, x, y, z]``), matrices ``(..., 3, 3)`` — and returns
arrays with the same leading axes.  Nothing is checked: a NaN row gives a NaN row, a non-unit
quaternion gives whatever the formula gives.  The validated functions of
:mod:`attitude.quaternion` and :mod:`attitude.matrix` check their input and then call these
kernels, so each formula exists once.

The small matrices (``[v×]``, Ξ(q), the quaternion-product matrices, Ω(ω)) are built as *one*
matrix product with a constant tensor (``[v×] = (v @ E).reshape(3, 3)``) rather than by stacking
components: a filter step at M = 100 trials costs the number of NumPy calls, not arithmetic.

Conventions (``docs/conventions.md``): ``R_AB = matrices_from_quaternions(q_AB)`` maps
B-components to A-components and ``R(p ⊗ q) = R(p) R(q)``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = [
    "cross_product_matrices",
    "xi_matrices",
    "quaternion_left_matrices",
    "quaternion_right_matrices",
    "omega_matrices",
    "quaternion_products",
    "quaternion_conjugates",
    "canonical_quaternions",
    "quaternions_from_rotvecs",
    "rotvecs_from_quaternions",
    "matrices_from_quaternions",
    "quaternions_from_matrices",
    "matrices_from_rotvecs",
    "rotvecs_from_matrices",
]

_CONJ = np.array([1.0, -1.0, -1.0, -1.0])


def _linear_map(builder: Callable[[np.ndarray], list], n_in: int) -> np.ndarray:
    """Constant tensor ``E (n_in, rows*cols)`` with ``builder(v).ravel() == v @ E``."""
    cols = [np.asarray(builder(np.eye(n_in)[i]), dtype=float).ravel() for i in range(n_in)]
    return np.stack(cols, 0)


def _skew_ref(v: np.ndarray) -> list:
    x, y, z = v
    return [[0, -z, y], [z, 0, -x], [-y, x, 0]]


def _xi_ref(q: np.ndarray) -> list:
    q0, q1, q2, q3 = q
    return [[-q1, -q2, -q3], [q0, -q3, q2], [q3, q0, -q1], [-q2, q1, q0]]


def _left_ref(q: np.ndarray) -> list:
    q0, q1, q2, q3 = q
    return [[q0, -q1, -q2, -q3], [q1, q0, -q3, q2], [q2, q3, q0, -q1], [q3, -q2, q1, q0]]


def _right_ref(p: np.ndarray) -> list:
    p0, p1, p2, p3 = p
    return [[p0, -p1, -p2, -p3], [p1, p0, p3, -p2], [p2, -p3, p0, p1], [p3, p2, -p1, p0]]


def _omega_ref(w: np.ndarray) -> list:
    x, y, z = w
    return [[0, -x, -y, -z], [x, 0, z, -y], [y, -z, 0, x], [z, y, -x, 0]]


_E_SKEW = _linear_map(_skew_ref, 3)
_E_XI = _linear_map(_xi_ref, 4)
_E_LEFT = _linear_map(_left_ref, 4)
_E_RIGHT = _linear_map(_right_ref, 4)
_E_OMEGA = _linear_map(_omega_ref, 3)


def cross_product_matrices(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices ``[v×]`` with ``[v×] w = v × w``.

    Parameters
    ----------
    v : ndarray, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    return (v @ _E_SKEW).reshape(v.shape[:-1] + (3, 3))


def xi_matrices(q: np.ndarray) -> np.ndarray:
    """Ξ(q) of 003 eq (26): ``q ⊗ [0, v] = Ξ(q) v``; ``(..., 4) → (..., 4, 3)``."""
    return (q @ _E_XI).reshape(q.shape[:-1] + (4, 3))


def quaternion_left_matrices(q: np.ndarray) -> np.ndarray:
    """Left-product matrices ``L(q)`` with ``q ⊗ p = L(q) p``; ``(..., 4) → (..., 4, 4)``."""
    return (q @ _E_LEFT).reshape(q.shape[:-1] + (4, 4))


def quaternion_right_matrices(p: np.ndarray) -> np.ndarray:
    """Right-product matrices ``Rm(p)`` with ``q ⊗ p = Rm(p) q``; ``(..., 4) → (..., 4, 4)``."""
    return (p @ _E_RIGHT).reshape(p.shape[:-1] + (4, 4))


def omega_matrices(w: np.ndarray) -> np.ndarray:
    """Ω(ω) of 003 eq (26): ``q ⊗ [0, ω] = Ω(ω) q``, so ``q̇ = ½ Ω(ω) q``; ``(..., 3) → (..., 4, 4)``."""
    return (w @ _E_OMEGA).reshape(w.shape[:-1] + (4, 4))


def quaternion_products(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton products ``p ⊗ q = [p0 q0 − p·q, p0 q + q0 p + p × q]``; ``(..., 4)`` broadcast.

    ``matrices_from_quaternions(p ⊗ q) = R(p) R(q)``.
    """
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


def quaternion_conjugates(q: np.ndarray) -> np.ndarray:
    """Conjugates ``[w, −x, −y, −z]`` (the inverse rotation of a unit quaternion); ``(..., 4)``."""
    return q * _CONJ


def canonical_quaternions(q: np.ndarray) -> np.ndarray:
    """Representatives with ``w >= 0`` (for ``w == 0`` the first non-zero component positive)."""
    s = np.sign(q[..., 0])
    for k in (1, 2, 3):
        s = np.where(s == 0, np.sign(q[..., k]), s)
    s = np.where(s == 0, 1.0, s)
    return q * s[..., None]


def quaternions_from_rotvecs(v: np.ndarray) -> np.ndarray:
    """Unit quaternions ``exp([0, v/2]) = [cos(θ/2), sin(θ/2) v/θ]`` of rotation vectors, ``θ = |v|``.

    Parameters
    ----------
    v : ndarray, shape (..., 3)
        Rotation vectors, rad.  Below ``θ/2 = 1e-4`` the factor ``sin(θ/2)/(θ/2)`` is its Taylor
        series ``1 − x²/6 + x⁴/120`` (``x = θ/2``).

    Returns
    -------
    ndarray, shape (..., 4)
    """
    half = 0.5 * v
    a = np.linalg.norm(half, axis=-1, keepdims=True)
    small = a < 1e-4
    a_safe = np.where(small, 1.0, a)
    sinc = np.where(small, 1.0 - a * a / 6.0 + a**4 / 120.0, np.sin(a_safe) / a_safe)
    return np.concatenate([np.cos(a), sinc * half], -1)


def rotvecs_from_quaternions(q: np.ndarray) -> np.ndarray:
    """Rotation vectors (angle in ``[0, π]``, rad) of unit quaternions; sign-invariant.

    Parameters
    ----------
    q : ndarray, shape (..., 4)
        Unit quaternions (not normalised here); ``q`` and ``−q`` give the same vector (the
        representative of :func:`canonical_quaternions` is used).

    Returns
    -------
    ndarray, shape (..., 3)
    """
    q = canonical_quaternions(q)
    w = np.clip(q[..., :1], -1.0, 1.0)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    a = np.arctan2(s, w)
    small = s < 1e-8
    # near identity w ≈ 1 and atan2(s, w)/s → 1/w (w > 0 there since |q| = 1 and w >= 0)
    factor = np.where(small, 1.0 / np.maximum(w, 0.5), a / np.where(small, 1.0, s))
    return 2.0 * (factor * v)


def matrices_from_quaternions(q: np.ndarray) -> np.ndarray:
    """Rotation matrices ``R_AB`` of unit quaternions ``q_AB`` (Hamilton, active).

    Parameters
    ----------
    q : ndarray, shape (..., 4)
        Unit quaternions (not normalised here: the formula uses ``w² + x² + y² + z² = 1``).

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
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


def quaternions_from_matrices(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (``w >= 0``) of rotation matrices by Shepperd's method.

    For each matrix the largest of ``4w², 4x², 4y², 4z²`` is the pivot, so no division by a
    small number occurs and every angle including 180° is handled.  The result is normalised and
    made canonical (:func:`canonical_quaternions`).  Non-orthonormal input is not projected.

    Parameters
    ----------
    R : ndarray, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 4)
    """
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = m00 + m11 + m22
    k = np.argmax(np.stack([tr, m00, m11, m22], -1), axis=-1)

    def _scale(r2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r = np.sqrt(np.maximum(r2, 0.0))
        return r, np.where(r > 0, 0.5 / np.where(r > 0, r, 1.0), 0.0)

    r, s = _scale(1.0 + tr)
    qw = np.stack([0.5 * r, (R[..., 2, 1] - R[..., 1, 2]) * s, (R[..., 0, 2] - R[..., 2, 0]) * s,
                   (R[..., 1, 0] - R[..., 0, 1]) * s], -1)
    r, s = _scale(1.0 + m00 - m11 - m22)
    qx = np.stack([(R[..., 2, 1] - R[..., 1, 2]) * s, 0.5 * r, (R[..., 0, 1] + R[..., 1, 0]) * s,
                   (R[..., 0, 2] + R[..., 2, 0]) * s], -1)
    r, s = _scale(1.0 - m00 + m11 - m22)
    qy = np.stack([(R[..., 0, 2] - R[..., 2, 0]) * s, (R[..., 0, 1] + R[..., 1, 0]) * s, 0.5 * r,
                   (R[..., 1, 2] + R[..., 2, 1]) * s], -1)
    r, s = _scale(1.0 - m00 - m11 + m22)
    qz = np.stack([(R[..., 1, 0] - R[..., 0, 1]) * s, (R[..., 0, 2] + R[..., 2, 0]) * s,
                   (R[..., 1, 2] + R[..., 2, 1]) * s, 0.5 * r], -1)
    kk = k[..., None]
    out = np.where(kk == 0, qw, np.where(kk == 1, qx, np.where(kk == 2, qy, qz)))
    return canonical_quaternions(out / np.linalg.norm(out, axis=-1, keepdims=True))


def matrices_from_rotvecs(v: np.ndarray) -> np.ndarray:
    """Rodrigues' formula ``exp([v×]) = I + a [v×] + b [v×]²`` of rotation vectors.

    Parameters
    ----------
    v : ndarray, shape (..., 3)
        Rotation vectors, rad.  Below ``θ² = 1e-12`` the coefficients ``a = sin θ/θ`` and
        ``b = (1 − cos θ)/θ²`` are their Taylor series ``1 − θ²/6`` and ``1/2 − θ²/24``.

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    th2 = np.sum(v * v, axis=-1)
    th = np.sqrt(th2)
    small = th2 < 1e-12
    th_s = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th2 / 6.0, np.sin(th_s) / th_s)
    b = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(th_s)) / np.where(small, 1.0, th2))
    S = cross_product_matrices(v)
    return np.eye(3) + a[..., None, None] * S + b[..., None, None] * (S @ S)


def rotvecs_from_matrices(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (rad) of rotation matrices, accurate for small angles.

    The axis comes from the skew part of ``R``, so the result degrades near 180° (valid below
    about 179°); meant for error vectors, which are small.

    Parameters
    ----------
    R : ndarray, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 3)
    """
    w = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                  R[..., 1, 0] - R[..., 0, 1]], -1) * 0.5
    s = np.linalg.norm(w, axis=-1)
    c = 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0)
    th = np.arctan2(s, c)
    small = s < 1e-12
    f = np.where(small, 1.0, th / np.where(small, 1.0, s))
    return w * f[..., None]
