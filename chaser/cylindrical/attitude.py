"""Attitude of a target from three point targets (paper 004 eq 5–11), in its corrected form.

The virtual point ``c′`` (corrected eq 5, flag P004-1), the Cayley least squares for the Rodrigues
parameters (flag P004-4) with the parameter-set switching of paper 001 near 180°
(``attitude.gibbs``), and yaw/roll/pitch by the corrected eq 9–11 (flags P004-2/P004-3,
docs/papers.md#p004-3): the Euler sequence is 3-1-2.

Frames: ``O`` is the reference (world) frame and ``S`` the target body frame of 004 eq (6)
(``−x_S ∥ ab``, ``y_S ∥ bc′``); 004's ``R_ob`` is ``R_OS`` (``n^t = R_ob n^s``, eq 7).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from attitude.euler import euler_from_matrix
from attitude.gibbs import (
    GIBBS_SET_MATRICES,
    gibbs_switch,
    quat_from_gibbs_set,
    shuster_matrix_from_gibbs_set,
)
from attitude.quaternion import quat_conjugate, quat_multiply, skew
from chaser.cylindrical._arrays import as_points

__all__ = [
    "N_S_BODY",
    "virtual_point",
    "sigma_from_vector_pairs",
    "yaw_roll_pitch_from_sigma",
    "yaw_roll_pitch_from_matrix",
    "ThreePointAttitude",
    "attitude_from_three_points",
]


#: Body-frame unit vectors of 004 eq (6): ``n_1^s = [0, 1, 0]`` (along bc′) and ``n_2^s = [−1, 0, 0]`` (along ab).
N_S_BODY = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


def virtual_point(a: ArrayLike, b: ArrayLike, c: ArrayLike) -> np.ndarray:
    """Virtual point ``c′`` of 004 eq (5), corrected form of flag P004-1.

    ``c′`` lies in the plane ``abc`` with ``bc′ ⊥ ab`` and ``|bc′| = |bc|``: the *vector* ``bc`` is
    rotated about the plane normal ``N = ab × bc / |ab × bc|`` through ``b`` by the complement
    ``θ₁ = π/2 − θ₀`` of the angle θ₀ between the vectors ``ab = b − a`` and ``bc = c − b``, with the
    Hamilton product: ``(0, c′ − b) = S ⊗ (0, c − b) ⊗ S̄``, ``S = [cos θ₁/2, N sin θ₁/2]``.

    Parameters
    ----------
    a, b, c : (..., 3) array
        Target positions (m).

    Returns
    -------
    (..., 3) ndarray
        ``c′``; NaN where ``a, b, c`` are collinear (no plane).
    """
    a = as_points(a, "a")
    b = as_points(b, "b")
    c = as_points(c, "c")
    ab = b - a
    bc = c - b
    cr = np.cross(ab, bc)
    ncr = np.linalg.norm(cr, axis=-1, keepdims=True)
    scale = np.linalg.norm(ab, axis=-1, keepdims=True) * np.linalg.norm(bc, axis=-1, keepdims=True)
    degenerate = ncr[..., 0] <= 1e-12 * np.maximum(scale[..., 0], 1e-300)
    with np.errstate(invalid="ignore", divide="ignore"):
        N = cr / ncr
        cos0 = np.clip(np.sum(ab * bc, -1) / scale[..., 0], -1.0, 1.0)
    theta1 = np.pi / 2 - np.arccos(cos0)
    S = np.concatenate([np.cos(theta1 / 2)[..., None], N * np.sin(theta1 / 2)[..., None]], -1)
    P = np.concatenate([np.zeros_like(bc[..., :1]), bc], -1)
    rotated = quat_multiply(quat_multiply(S, P), quat_conjugate(S))[..., 1:]
    return np.where(degenerate[..., None], np.nan, b + rotated)


def _cayley_solve(n_t: np.ndarray, n_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Batched Cayley LS ``[(n^t + n^s)×] σ = n^t − n^s`` over the pairs axis; returns σ, cond, null dir."""
    M = skew(n_t + n_s).reshape(n_t.shape[:-2] + (-1, 3))  # (..., 3·pairs, 3)
    rhs = (n_t - n_s).reshape(n_t.shape[:-2] + (-1,))
    U, s, Vt = np.linalg.svd(M, full_matrices=False)
    cond = s[..., 2] / np.maximum(s[..., 0], 1e-300)
    inv = np.where(s > 1e-12 * np.maximum(s[..., :1], 1e-300), 1.0 / np.where(s > 0, s, 1.0), 0.0)
    sigma = np.einsum("...ji,...j,...kj,...k->...i", Vt, inv, U, rhs)
    return sigma, cond, Vt[..., 2, :]


def sigma_from_vector_pairs(n_t: ArrayLike, n_s: ArrayLike = N_S_BODY, *, gibbs_set: ArrayLike = 0) -> np.ndarray:
    """Rodrigues parameters from vector pairs ``n^t = A n^s`` (flag P004-4), in parameter set ``i``.

    Solves the stacked Cayley equations ``[(n^t + R^(i) n^s)×] σ = n^t − R^(i) n^s`` by least squares,
    where ``A = A(σ) R^(i)`` is the Shuster attitude matrix of the set (001 eq 8′; ``i = 0`` is 004's
    eq 8 with the sign of flag P004-2 corrected).

    Parameters
    ----------
    n_t : (..., P, 3) array
        Unit vectors in the reference frame.
    n_s : (P, 3) or (..., P, 3) array
        The same vectors in the body frame (default 004 eq 6).
    gibbs_set : int or (...,) int array
        Parameter set 0..3.

    Returns
    -------
    (..., 3) ndarray
    """
    n_t = np.asarray(n_t, dtype=float)
    if n_t.ndim < 2 or n_t.shape[-1] != 3:
        raise ValueError(f"n_t: expected shape (..., P, 3), got {n_t.shape}")
    i = np.broadcast_to(np.asarray(gibbs_set, dtype=int), n_t.shape[:-2])
    if np.any((i < 0) | (i > 3)):
        raise ValueError(f"gibbs_set: must be 0..3, got {gibbs_set!r}")
    n_s = np.broadcast_to(np.asarray(n_s, dtype=float), n_t.shape)
    n_s_i = np.einsum("...ij,...pj->...pi", GIBBS_SET_MATRICES[i], n_s)
    return _cayley_solve(n_t, n_s_i)[0]


def yaw_roll_pitch_from_sigma(sigma: ArrayLike) -> np.ndarray:
    """004 eq (9)–(11), corrected (flags P004-2, P004-3): ``(yaw, roll, pitch)`` rad from σ (set 0).

    ``yaw = atan2(2(σ₃ − σ₁σ₂), 1 − σ₁² + σ₂² − σ₃²)``,
    ``roll = arcsin(2(σ₂σ₃ + σ₁)/(1 + |σ|²))``,
    ``pitch = atan2(2(σ₂ − σ₁σ₃), 1 − σ₁² − σ₂² + σ₃²)``: the 3-1-2 angles of
    ``R_ob = R_y(pitch) R_x(roll) R_z(yaw)`` (frame rotations).
    """
    s = np.asarray(sigma, dtype=float)
    if s.ndim == 0 or s.shape[-1] != 3:
        raise ValueError(f"sigma: expected shape (..., 3), got {s.shape}")
    s1, s2, s3 = s[..., 0], s[..., 1], s[..., 2]
    n2 = s1 * s1 + s2 * s2 + s3 * s3
    yaw = np.arctan2(2 * (s3 - s1 * s2), 1 - s1 * s1 + s2 * s2 - s3 * s3)
    roll = np.arcsin(np.clip(2 * (s2 * s3 + s1) / (1 + n2), -1.0, 1.0))
    pitch = np.arctan2(2 * (s2 - s1 * s3), 1 - s1 * s1 - s2 * s2 + s3 * s3)
    return np.stack([yaw, roll, pitch], -1)


def yaw_roll_pitch_from_matrix(R_ob: ArrayLike) -> np.ndarray:
    """The same angles from the matrix (flag P004-3): ``yaw = atan2(−R₂₁, R₂₂)``, ``roll = arcsin R₂₃``,
    ``pitch = atan2(−R₁₃, R₃₃)`` (1-based), i.e. ``euler_from_matrix(R_obᵀ, "312")``."""
    R = np.asarray(R_ob, dtype=float)
    if R.ndim < 2 or R.shape[-2:] != (3, 3):
        raise ValueError(f"R_ob: expected shape (..., 3, 3), got {R.shape}")
    return euler_from_matrix(np.swapaxes(R, -1, -2), "312")[0]


@dataclass(frozen=True, eq=False)
class ThreePointAttitude:
    """Attitude of a target from three points (004 §2.2).

    Attributes
    ----------
    R_OS : (..., 3, 3) ndarray
        004's ``R_ob``: body-to-reference, ``n^t = R_OS n^s`` (eq 7).
    q_OS : (..., 4) ndarray
        Hamilton quaternion of ``R_OS`` (scalar first).
    sigma : (..., 3) ndarray
        Rodrigues parameters in the parameter set ``gibbs_set`` (001 eq 4).
    gibbs_set : (...,) int ndarray
        0 = 004's plain σ; 1..3 after switching near 180° (001).
    yaw_roll_pitch_rad : (..., 3) ndarray
        Corrected 004 eq (9)–(11) (3-1-2 sequence).
    gimbal_lock : (...,) bool ndarray
        Roll within ``1e-6`` of ±90°.
    virtual_point_W : (..., 3) ndarray
        ``c′`` (eq 5).
    condition : (...,) ndarray
        Smallest over largest singular value of the Cayley system that was solved.
    ok : (...,) bool ndarray
        False where the three points are collinear or not all finite.
    failure_reason : (...,) ndarray of str
        "" where ``ok``; otherwise why ("collinear points", "non-finite point": a fix that failed).
    """

    R_OS: np.ndarray
    q_OS: np.ndarray
    sigma: np.ndarray
    gibbs_set: np.ndarray
    yaw_roll_pitch_rad: np.ndarray
    gimbal_lock: np.ndarray
    virtual_point_W: np.ndarray
    condition: np.ndarray
    ok: np.ndarray
    failure_reason: np.ndarray


def attitude_from_three_points(a: ArrayLike, b: ArrayLike, c: ArrayLike, *, switch_eta: float = 0.0,
                               singular_tol: float = 1e-9) -> ThreePointAttitude:
    """Attitude of a target carrying LEDs ``a, b, c`` (004 eq 5–11, flags P004-1..4).

    1. ``c′`` = :func:`virtual_point` (corrected eq 5).
    2. ``n₁ᵗ = (c′ − b)/|c′ − b|``, ``n₂ᵗ = (b − a)/|b − a|`` (eq 7), against ``n₁ˢ = [0, 1, 0]``,
       ``n₂ˢ = [−1, 0, 0]`` (eq 6).
    3. Cayley least squares for σ (flag P004-4) in set 0.  Near 180° (``|σ_j| > 1 + switch_eta``, or a
       numerically singular system, whose null direction is then the rotation axis) the
       parameter set is switched with 001's rule (``attitude.gibbs.gibbs_switch``) and the Cayley
       system is solved again in the new set, where every ``|σ_j| ≤ 1``.
    4. ``R_ob = A(σ) R^(i)`` and the corrected eq (9)–(11) from its elements.

    Parameters
    ----------
    a, b, c : (..., 3) array
        Target positions in the reference frame (m).
    """
    a = as_points(a, "a")
    b = as_points(b, "b")
    c = as_points(c, "c")
    if switch_eta < 0:
        raise ValueError(f"switch_eta: must be >= 0, got {switch_eta!r}")
    batch = np.broadcast_shapes(a.shape, b.shape, c.shape)[:-1]
    a, b, c = (np.broadcast_to(v, batch + (3,)).reshape(-1, 3) for v in (a, b, c))
    cp = virtual_point(a, b, c)
    finite = np.isfinite(a).all(-1) & np.isfinite(b).all(-1) & np.isfinite(c).all(-1)
    ok = np.isfinite(cp).all(-1)
    safe_b = np.where(ok[..., None], b, 0.0)
    safe_cp = np.where(ok[..., None], cp, safe_b + np.array([0.0, 1.0, 0.0]))
    safe_a = np.where(ok[..., None], a, safe_b + np.array([1.0, 0.0, 0.0]))
    n1 = safe_cp - safe_b
    n2 = safe_b - safe_a
    n_t = np.stack([n1 / np.linalg.norm(n1, axis=-1, keepdims=True),
                    n2 / np.linalg.norm(n2, axis=-1, keepdims=True)], -2)
    n_s = np.broadcast_to(N_S_BODY, n_t.shape)
    sigma0, cond0, null0 = _cayley_solve(n_t, n_s)
    singular = cond0 < singular_tol
    probe = np.where(singular[..., None], null0 / singular_tol, sigma0)
    _, i_new = gibbs_switch(probe, np.zeros(probe.shape[:-1], dtype=int), eta=switch_eta)
    i_new = np.asarray(i_new)
    sigma = sigma0.copy()
    cond = cond0.copy()
    for i in (1, 2, 3):
        m = i_new == i
        if np.any(m):
            n_s_i = np.einsum("ij,...pj->...pi", GIBBS_SET_MATRICES[i], n_s[m])
            s_i, c_i, _ = _cayley_solve(n_t[m], n_s_i)
            sigma[m] = s_i
            cond[m] = c_i
    R_ob = shuster_matrix_from_gibbs_set(sigma, i_new)
    q_OS = quat_conjugate(quat_from_gibbs_set(sigma, i_new))
    angles, lock = euler_from_matrix(np.swapaxes(R_ob, -1, -2), "312")
    nan = ~ok

    def shape(x, tail=()):
        return x.reshape(batch + tail)

    return ThreePointAttitude(
        shape(np.where(nan[:, None, None], np.nan, R_ob), (3, 3)),
        shape(np.where(nan[:, None], np.nan, q_OS), (4,)),
        shape(np.where(nan[:, None], np.nan, sigma), (3,)),
        shape(i_new),
        shape(np.where(nan[:, None], np.nan, angles), (3,)),
        shape(lock & ok),
        shape(cp, (3,)),
        shape(np.where(nan, 0.0, cond)),
        shape(ok),
        shape(np.where(ok, "", np.where(finite, "collinear points", "non-finite point")).astype(object)),
    )
