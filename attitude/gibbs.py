"""Gibbs vectors (classical Rodrigues parameters) and modified Rodrigues parameters.

Two conventions meet here, and are kept apart by name (flag P001-3, docs/papers.md#p001-3):

* **Hamilton (project convention).** For ``q_AB = [w, v]`` the Gibbs vector is ``g = v / w =
  n tan(θ/2)`` and its active matrix is ``R_AB = matrix_from_gibbs(g) =
  ((1 − |g|²) I + 2 g gᵀ + 2 [g×]) / (1 + |g|²)``; composition ``gibbs_multiply(g1, g2)`` satisfies
  ``R(g1 ∘ g2) = R(g1) R(g2)``.
* **Shuster (paper 001).** The same numbers ``g`` describe Shuster's *attitude matrix*
  ``A(g) = ((1 − |g|²) I + 2 g gᵀ − 2 [g×]) / (1 + |g|²) = R_ABᵀ`` (001 eq 8′), the quaternion is
  scalar-last ``[q1, q2, q3, q4]`` and its product has a minus sign on the cross term.  The four
  parameter sets g^(0..3) (001 eq 4), the transforms T_j and the switching rule (001 eq 5) and the
  error composition (001 eq 10) are written in this convention, exactly as in the paper, in the
  functions prefixed ``shuster_``/``gibbs_set``.  Convert at the boundary with
  :func:`shuster_from_quat` and :func:`quat_from_shuster` (same four numbers, reordered).

Switching (001 §2): the set ``i`` uses as denominator the quaternion component ``q4`` (i = 0) or
``q_i`` (i = 1, 2, 3); whenever some ``|g_j| > 1`` the set is switched with ``T_j``, after which
every ``|g_j| <= 1`` and the rotation relative to the active reference frame ``r^(i)`` is at most
120° (001 eq (4)–(5); ``tests/attitude/test_gibbs.py`` checks it on random samples).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from attitude.quaternion import check_quat, check_vec3, quat_canonical, quat_normalize, skew

__all__ = [
    "gibbs_from_quat",
    "quat_from_gibbs",
    "matrix_from_gibbs",
    "gibbs_multiply",
    "shuster_from_quat",
    "quat_from_shuster",
    "shuster_quat_multiply",
    "shuster_matrix_from_gibbs",
    "shuster_gibbs_compose",
    "GIBBS_SET_MATRICES",
    "gibbs_set_from_shuster",
    "gibbs_set_from_quat",
    "best_gibbs_set",
    "quat_from_gibbs_set",
    "shuster_matrix_from_gibbs_set",
    "gibbs_transform",
    "gibbs_switch",
    "mrp_from_quat",
    "quat_from_mrp",
    "mrp_shadow",
]

#: R^(i) of 001 eq (8′): the reference frame r^(0) rotated by π about its own i-th axis.
GIBBS_SET_MATRICES = np.array(
    [np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.diag([-1.0, -1.0, 1.0])]
)


def _check_nonzero_quat(q: ArrayLike) -> np.ndarray:
    """Finite ``(..., 4)`` quaternions of non-zero norm (any norm otherwise: Gibbs sets are ratios)."""
    q = check_quat(q, name="q", unit=False)
    if np.any(np.linalg.norm(q, axis=-1) == 0):
        raise ValueError("q: the zero quaternion is no rotation")
    return q


# ---------------------------------------------------------------- Hamilton-facing Gibbs vector
def gibbs_from_quat(q: ArrayLike) -> np.ndarray:
    """Gibbs vector ``g = q_v / q_w = n tan(θ/2)`` of ``q_AB`` (001 eq 1–3), ``(..., 4) → (..., 3)``.

    Raises ``ValueError`` for a 180° rotation (``q_w = 0``), where ``g`` does not exist; use
    :func:`best_gibbs_set` for a representation that never is singular.
    """
    q = _check_nonzero_quat(q)
    w = q[..., :1]
    if np.any(w == 0):
        raise ValueError("q: rotation of 180 degrees (w = 0) has no Gibbs vector; use best_gibbs_set")
    return q[..., 1:] / w


def quat_from_gibbs(g: ArrayLike) -> np.ndarray:
    """Unit quaternion ``[1, g] / sqrt(1 + |g|²)`` (``w > 0``) of a Gibbs vector."""
    g = check_vec3(g, name="g")
    q = np.concatenate([np.ones_like(g[..., :1]), g], -1)
    return q / np.sqrt(1.0 + np.sum(g * g, -1, keepdims=True))


def matrix_from_gibbs(g: ArrayLike) -> np.ndarray:
    """Active (Hamilton) matrix ``R_AB = ((1 − |g|²) I + 2 g gᵀ + 2 [g×]) / (1 + |g|²)``."""
    g = check_vec3(g, name="g")
    gg = np.sum(g * g, -1)[..., None, None]
    eye = np.eye(3)
    return ((1.0 - gg) * eye + 2.0 * g[..., :, None] * g[..., None, :] + 2.0 * skew(g)) / (1.0 + gg)


def gibbs_multiply(g1: ArrayLike, g2: ArrayLike) -> np.ndarray:
    """Hamilton composition: ``R(g1 ∘ g2) = R(g1) R(g2)``, ``(g1 + g2 + g1 × g2) / (1 − g1·g2)``.

    Raises ``ValueError`` when the composed rotation is 180° (``g1·g2 = 1``).
    """
    g1 = check_vec3(g1, name="g1")
    g2 = check_vec3(g2, name="g2")
    den = 1.0 - np.sum(g1 * g2, -1, keepdims=True)
    if np.any(den == 0):
        raise ValueError("g1, g2: composition is a 180 degree rotation (g1·g2 = 1)")
    return (g1 + g2 + np.cross(g1, g2)) / den


# ---------------------------------------------------------------- Shuster (001) convention
def shuster_from_quat(q: ArrayLike) -> np.ndarray:
    """Shuster scalar-last quaternion ``[q1, q2, q3, q4]`` of the project's ``q_AB = [w, x, y, z]``.

    The four numbers are the same; Shuster's attitude matrix of the result is ``A = R_ABᵀ``
    (it maps A-components to B-components; flag P001-3, docs/papers.md#p001-3).
    """
    q = check_quat(q, name="q", unit=False)
    return np.concatenate([q[..., 1:], q[..., :1]], -1)


def quat_from_shuster(q_s: ArrayLike) -> np.ndarray:
    """Inverse of :func:`shuster_from_quat`: ``[q1, q2, q3, q4] → [w, x, y, z] = [q4, q1, q2, q3]``."""
    q_s = check_quat(q_s, name="q_s", unit=False)
    return np.concatenate([q_s[..., 3:], q_s[..., :3]], -1)


def shuster_quat_multiply(p: ArrayLike, q: ArrayLike) -> np.ndarray:
    """Shuster's product of scalar-last quaternions: ``A(p ⊗ q) = A(p) A(q)``.

    ``[p4 q_v + q4 p_v − p_v × q_v, p4 q4 − p_v·q_v]`` (the cross term has a minus sign).
    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    pv, p4 = p[..., :3], p[..., 3:]
    qv, q4 = q[..., :3], q[..., 3:]
    vec = p4 * qv + q4 * pv - np.cross(pv, qv)
    sca = p4 * q4 - np.sum(pv * qv, -1, keepdims=True)
    return np.concatenate([vec, sca], -1)


def shuster_matrix_from_gibbs(g: ArrayLike) -> np.ndarray:
    """Shuster attitude matrix ``A(g) = ((1 − |g|²) I + 2 g gᵀ − 2 [g×]) / (1 + |g|²)`` (001 eq 8′)."""
    return np.swapaxes(matrix_from_gibbs(g), -1, -2)


def shuster_gibbs_compose(dg: ArrayLike, g0: ArrayLike) -> np.ndarray:
    """001 eq (10): ``dg * g0 = (dg + g0 − dg × g0) / (1 − dg·g0)``, with ``A(dg * g0) = A(dg) A(g0)``."""
    dg = check_vec3(dg, name="dg")
    g0 = check_vec3(g0, name="g0")
    den = 1.0 - np.sum(dg * g0, -1, keepdims=True)
    if np.any(den == 0):
        raise ValueError("dg, g0: composition is a 180 degree rotation (dg·g0 = 1)")
    return (dg + g0 - np.cross(dg, g0)) / den


def gibbs_set_from_shuster(q_s: ArrayLike, i: ArrayLike) -> np.ndarray:
    """Parameter set ``g^(i)`` (001 eq 4) of a Shuster scalar-last quaternion; ``i`` in {0, 1, 2, 3}.

    ``g^(0) = [q1, q2, q3]/q4``, ``g^(1) = [−q4, q3, −q2]/q1``, ``g^(2) = [−q3, −q4, q1]/q2``,
    ``g^(3) = [q2, −q1, −q4]/q3``.  Division by a zero denominator gives ``inf``; pick ``i`` with
    :func:`best_gibbs_set` to avoid it.
    """
    q = np.asarray(q_s, dtype=float)
    i = np.asarray(i)
    if np.any((i < 0) | (i > 3)):
        raise ValueError(f"i: parameter-set index must be 0, 1, 2 or 3, got {i!r}")
    q1, q2, q3, q4 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    num = np.stack(
        [
            np.stack([q1, q2, q3], -1),
            np.stack([-q4, q3, -q2], -1),
            np.stack([-q3, -q4, q1], -1),
            np.stack([q2, -q1, -q4], -1),
        ],
        0,
    )
    den = np.stack([q4, q1, q2, q3], 0)
    ii = np.broadcast_to(i, q.shape[:-1])
    sel_num = np.take_along_axis(num, ii[None, ..., None].astype(int), 0)[0]
    sel_den = np.take_along_axis(den, ii[None, ...].astype(int), 0)[0]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return sel_num / sel_den[..., None]


def gibbs_set_from_quat(q: ArrayLike, i: ArrayLike) -> np.ndarray:
    """``g^(i)`` (001 eq 4) of the project's Hamilton ``q_AB`` (converted to Shuster first)."""
    return gibbs_set_from_shuster(shuster_from_quat(q), i)


def best_gibbs_set(q: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """The parameter set whose denominator is the largest-magnitude quaternion component.

    Returns ``(g, i)``; every ``|g_j| <= 1`` (Shuster's MSR criterion, 001 eq (5)).
    """
    q_s = shuster_from_quat(_check_nonzero_quat(q))
    k = np.argmax(np.abs(q_s), axis=-1)  # 0..2 → q1..q3, 3 → q4
    i = np.where(k == 3, 0, k + 1)
    return gibbs_set_from_shuster(q_s, i), i


def quat_from_gibbs_set(g: ArrayLike, i: ArrayLike) -> np.ndarray:
    """Hamilton ``q_AB`` (canonical sign) of the parameter set ``(g, i)``.

    ``q^(i) = q ⊗_S e_i`` (001 eq (4)), so ``q = q^(i) ⊗_S e_i⁻¹`` with ``q^(i) = [g, 1]/√(1+|g|²)``.
    """
    g = check_vec3(g, name="g")
    i = np.broadcast_to(np.asarray(i), g.shape[:-1])
    q_i = np.concatenate([g, np.ones_like(g[..., :1])], -1) / np.sqrt(1.0 + np.sum(g * g, -1, keepdims=True))
    e_inv = np.zeros(g.shape[:-1] + (4,))
    e_inv[..., 3] = np.where(i == 0, 1.0, 0.0)
    for k in (1, 2, 3):
        e_inv[..., k - 1] = np.where(i == k, -1.0, e_inv[..., k - 1])
    q_s = shuster_quat_multiply(q_i, e_inv)
    return quat_canonical(quat_normalize(quat_from_shuster(q_s)))


def shuster_matrix_from_gibbs_set(g: ArrayLike, i: ArrayLike) -> np.ndarray:
    """001 eq (8′): ``A(g^(i)) R^(i)``, the Shuster attitude matrix (``= R_ABᵀ``) of the set ``(g, i)``."""
    i = np.asarray(i, dtype=int)
    return shuster_matrix_from_gibbs(g) @ GIBBS_SET_MATRICES[i]


def gibbs_transform(g: ArrayLike, j: int) -> np.ndarray:
    """001 eq (5): ``T_1(g) = [−1, g3, −g2]/g1``, ``T_2(g) = [−g3, −1, g1]/g2``, ``T_3(g) = [g2, −g1, −1]/g3``."""
    g = check_vec3(g, name="g")
    g1, g2, g3 = g[..., 0], g[..., 1], g[..., 2]
    one = np.ones_like(g1)
    if j == 1:
        num, den = np.stack([-one, g3, -g2], -1), g1
    elif j == 2:
        num, den = np.stack([-g3, -one, g1], -1), g2
    elif j == 3:
        num, den = np.stack([g2, -g1, -one], -1), g3
    else:
        raise ValueError(f"j: transform index must be 1, 2 or 3, got {j!r}")
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return num / den[..., None]


def gibbs_switch(g: ArrayLike, i: ArrayLike, *, eta: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """001 switching rule: if the largest ``|g_j|`` exceeds ``1 + eta``, apply ``T_j``.

    The new set index is ``j`` if ``i = 0``, ``0`` if ``j = i``, and ``6 − j − i`` otherwise
    (001 eq 5).  ``eta > 0`` adds a hysteresis (the paper has none; η = 0.05 is a good choice) so the set
    does not alternate when ``|g_j| ≈ 1``.  Returns ``(g', i')``; with ``eta = 0`` every ``|g'_j| <= 1``.
    """
    if eta < 0:
        raise ValueError(f"eta: hysteresis must be >= 0, got {eta!r}")
    g = check_vec3(g, name="g")
    i = np.broadcast_to(np.asarray(i, dtype=int), g.shape[:-1])
    a = np.abs(g)
    j = np.argmax(a, axis=-1) + 1
    do = np.max(a, axis=-1) > 1.0 + eta
    out = g.copy()
    for jj in (1, 2, 3):
        m = do & (j == jj)
        if np.any(m):
            out[m] = gibbs_transform(g[m], jj)
    i_new = np.where(i == 0, j, np.where(j == i, 0, 6 - j - i))
    return out, np.where(do, i_new, i)


# ---------------------------------------------------------------- modified Rodrigues parameters
def mrp_from_quat(q: ArrayLike) -> np.ndarray:
    """Modified Rodrigues parameters ``p = q_v / (1 + q_w) = n tan(θ/4)`` (Hamilton ``q_AB``).

    The representative with ``w >= 0`` is used, so ``|p| <= 1`` (the short rotation).
    """
    q = quat_canonical(quat_normalize(check_quat(q, name="q", unit=False)))
    return q[..., 1:] / (1.0 + q[..., :1])


def quat_from_mrp(p: ArrayLike) -> np.ndarray:
    """Unit quaternion ``[(1 − |p|²), 2 p] / (1 + |p|²)`` of modified Rodrigues parameters."""
    p = check_vec3(p, name="p")
    pp = np.sum(p * p, -1, keepdims=True)
    return np.concatenate([1.0 - pp, 2.0 * p], -1) / (1.0 + pp)


def mrp_shadow(p: ArrayLike) -> np.ndarray:
    """Shadow set ``−p / |p|²``: the same attitude through ``−q``; raises for ``p = 0``."""
    p = check_vec3(p, name="p")
    pp = np.sum(p * p, -1, keepdims=True)
    if np.any(pp == 0):
        raise ValueError("p: the identity (p = 0) has no shadow set")
    return -p / pp
