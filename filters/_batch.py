"""Private batched kernels of the filters' hot loop: small-matrix algebra over a trial axis ``M``.

A Monte Carlo step touches ~100 arrays of shape ``(M, ≤11, ≤11)``; at M = 100 the cost is the
number of numpy calls, not arithmetic.  So the quaternion and cross-product matrices are built as
*one* matrix product with a constant tensor (``skew(v) = (v @ E).reshape(3, 3)``) instead of
stacking components, and nothing here validates input (the public classes do that).  Each kernel
is tested against its validated counterpart in :mod:`attitude.quaternion`.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "as_batch",
    "skew",
    "cross",
    "xi_matrix",
    "left_matrix",
    "right_matrix",
    "omega4",
    "qmul",
    "conj",
    "qexp_half",
    "rotvec",
    "inv3",
    "sym",
    "positive_definite",
    "matrix_from_unit_quat",
]

_CONJ = np.array([1.0, -1.0, -1.0, -1.0])


def _linear_map(builder, n_in: int) -> np.ndarray:
    """Constant tensor ``E (n_in, rows*cols)`` with ``builder(v).ravel() == v @ E``."""
    cols = [np.asarray(builder(np.eye(n_in)[i]), dtype=float).ravel() for i in range(n_in)]
    return np.stack(cols, 0)


def _skew_ref(v):
    x, y, z = v
    return [[0, -z, y], [z, 0, -x], [-y, x, 0]]


def _xi_ref(q):
    q0, q1, q2, q3 = q
    return [[-q1, -q2, -q3], [q0, -q3, q2], [q3, q0, -q1], [-q2, q1, q0]]


def _left_ref(q):
    q0, q1, q2, q3 = q
    return [[q0, -q1, -q2, -q3], [q1, q0, -q3, q2], [q2, q3, q0, -q1], [q3, -q2, q1, q0]]


def _right_ref(p):
    p0, p1, p2, p3 = p
    return [[p0, -p1, -p2, -p3], [p1, p0, p3, -p2], [p2, -p3, p0, p1], [p3, p2, -p1, p0]]


def _omega_ref(w):
    x, y, z = w
    return [[0, -x, -y, -z], [x, 0, z, -y], [y, -z, 0, x], [z, y, -x, 0]]


_E_SKEW = _linear_map(_skew_ref, 3)
_E_XI = _linear_map(_xi_ref, 4)
_E_LEFT = _linear_map(_left_ref, 4)
_E_RIGHT = _linear_map(_right_ref, 4)
_E_OMEGA = _linear_map(_omega_ref, 3)


def as_batch(a: np.ndarray, m: int, tail: tuple[int, ...], name: str) -> np.ndarray:
    """Broadcast ``a`` of shape ``tail`` or ``(m, *tail)`` to ``(m, *tail)``; ``ValueError`` otherwise."""
    a = np.asarray(a, dtype=float)
    if a.shape == tail:
        return np.broadcast_to(a, (m, *tail))
    if a.shape == (m, *tail):
        return a
    raise ValueError(f"{name}: expected shape {tail} or {(m, *tail)}, got {a.shape}")


def skew(v: np.ndarray) -> np.ndarray:
    """``[v×]``, ``(..., 3) → (..., 3, 3)``."""
    return (v @ _E_SKEW).reshape(v.shape[:-1] + (3, 3))


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` over the last axis, ``(M, 3)``."""
    return (skew(a) @ b[..., None])[..., 0]


def xi_matrix(q: np.ndarray) -> np.ndarray:
    """Ξ(q) of 003 eq (26), ``(..., 4) → (..., 4, 3)``: ``q ⊗ [0, v] = Ξ(q) v``."""
    return (q @ _E_XI).reshape(q.shape[:-1] + (4, 3))


def left_matrix(q: np.ndarray) -> np.ndarray:
    """``L(q)`` with ``q ⊗ p = L(q) p``, ``(..., 4) → (..., 4, 4)``."""
    return (q @ _E_LEFT).reshape(q.shape[:-1] + (4, 4))


def right_matrix(p: np.ndarray) -> np.ndarray:
    """``Rm(p)`` with ``q ⊗ p = Rm(p) q``, ``(..., 4) → (..., 4, 4)``."""
    return (p @ _E_RIGHT).reshape(p.shape[:-1] + (4, 4))


def omega4(w: np.ndarray) -> np.ndarray:
    """Ω(ω) with ``q ⊗ [0, ω] = Ω(ω) q``, ``(..., 3) → (..., 4, 4)``."""
    return (w @ _E_OMEGA).reshape(w.shape[:-1] + (4, 4))


def qmul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p ⊗ q`` for ``(..., 4)`` arrays (p broadcast against q)."""
    L = left_matrix(p)
    return (L @ q[..., None])[..., 0]


def conj(q: np.ndarray) -> np.ndarray:
    return q * _CONJ


def qexp_half(v: np.ndarray) -> np.ndarray:
    """Unit quaternion ``exp(v/2) = [cos(|v|/2), sin(|v|/2) v/|v|]`` of a rotation vector ``(..., 3)``."""
    a = np.sqrt(np.sum(v * v, -1, keepdims=True))
    h = 0.5 * a
    small = a < 1e-6
    s = np.where(small, 0.5 - a * a / 48.0, np.sin(h) / np.where(small, 1.0, a))
    return np.concatenate([np.cos(h), s * v], -1)


def rotvec(q: np.ndarray) -> np.ndarray:
    """Rotation vector (angle in [0, π]) of a unit quaternion ``(..., 4)``; sign-invariant."""
    sgn = np.where(q[..., :1] < 0, -1.0, 1.0)
    w = q[..., :1] * sgn
    v = q[..., 1:] * sgn
    s = np.sqrt(np.sum(v * v, -1, keepdims=True))
    ang = 2.0 * np.arctan2(s, w)
    small = s < 1e-9
    return np.where(small, 2.0 / np.maximum(w, 0.5), ang / np.where(small, 1.0, s)) * v


def matrix_from_unit_quat(q: np.ndarray) -> np.ndarray:
    """``R(q)`` of unit quaternions ``(..., 4)`` via ``L(q) Rm(q*)`` (lower-right 3×3 block)."""
    return (left_matrix(q) @ right_matrix(conj(q)))[..., 1:, 1:]


def inv3(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of a batch of 3×3 matrices by the adjugate, with the determinants.

    Rows whose determinant is not strictly positive and finite get an identity "inverse"; the
    caller reads ``det`` to flag them (no exception inside a batch).
    """
    a = A[..., :, 0]
    b = A[..., :, 1]
    c = A[..., :, 2]
    bc = (skew(b) @ c[..., None])[..., 0]
    ca = (skew(c) @ a[..., None])[..., 0]
    ab = (skew(a) @ b[..., None])[..., 0]
    det = np.sum(a * bc, axis=-1)
    ok = np.isfinite(det) & (det > 0)
    inv = np.stack([bc, ca, ab], -2) / np.where(ok, det, 1.0)[..., None, None]
    if not ok.all():
        inv = np.where(ok[..., None, None], inv, np.eye(3))
    return inv, det


def sym(P: np.ndarray) -> np.ndarray:
    """Symmetric part ``(P + Pᵀ)/2`` over the last two axes."""
    return 0.5 * (P + P.mT)


def positive_definite(P: np.ndarray) -> np.ndarray:
    """Mask ``(M,)`` of the matrices in ``P (M, n, n)`` that are finite and positive definite.

    One batched Cholesky in the usual case; only when it fails are the rows tested one by one.
    """
    finite = np.isfinite(P).all(axis=(-1, -2))
    Pf = P if finite.all() else np.where(finite[:, None, None], P, np.eye(P.shape[-1]))
    try:
        np.linalg.cholesky(Pf)
        return finite
    except np.linalg.LinAlgError:
        ok = np.zeros(P.shape[0], dtype=bool)
        for i in np.flatnonzero(finite):
            try:
                np.linalg.cholesky(Pf[i])
                ok[i] = True
            except np.linalg.LinAlgError:
                ok[i] = False
        return ok
