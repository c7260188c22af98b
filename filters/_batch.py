"""Private batched linear algebra of the filters' hot loop: small matrices over a trial axis ``M``.

A Monte Carlo step touches ~100 arrays of shape ``(M, ≤11, ≤11)``; at M = 100 the cost is the
number of numpy calls, not arithmetic.  Nothing here validates input (the public classes do).
The rotation kernels (``[v×]``, Ξ(q), quaternion products, …) live in :mod:`attitude.batch`.
"""

from __future__ import annotations

import numpy as np

from attitude.batch import cross_product_matrices

__all__ = ["as_batch", "inv3", "sym", "positive_definite"]


def as_batch(a: np.ndarray, m: int, tail: tuple[int, ...], name: str) -> np.ndarray:
    """Broadcast ``a`` of shape ``tail`` or ``(m, *tail)`` to ``(m, *tail)``; ``ValueError`` otherwise."""
    a = np.asarray(a, dtype=float)
    if a.shape == tail:
        return np.broadcast_to(a, (m, *tail))
    if a.shape == (m, *tail):
        return a
    raise ValueError(f"{name}: expected shape {tail} or {(m, *tail)}, got {a.shape}")


def inv3(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of a batch of 3×3 matrices by the adjugate, with the determinants.

    Rows whose determinant is not strictly positive and finite get an identity "inverse"; the
    caller reads ``det`` to flag them (no exception inside a batch).
    """
    a = A[..., :, 0]
    b = A[..., :, 1]
    c = A[..., :, 2]
    bc = (cross_product_matrices(b) @ c[..., None])[..., 0]
    ca = (cross_product_matrices(c) @ a[..., None])[..., 0]
    ab = (cross_product_matrices(a) @ b[..., None])[..., 0]
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
