"""Weighted SVD pose of matched markers and its Euler angles (paper 000 §4).

**Euler sequence** (000 does not state one): pitch, yaw and roll are the 3-2-1 angles of
``R_SC = R_z(yaw) R_y(pitch) R_x(roll)`` (``attitude.euler``, sequence ``"321"``), i.e. yaw about
the camera boresight z_S, pitch about y_S, roll about x_S.

Frames: ``S`` camera (OpenCV), ``C`` marker plate; ``p_S = R_SC q_C + r_CS_S`` (000 eq 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from attitude.euler import euler_from_matrix

__all__ = ["RigidFit", "weighted_svd_pose", "pitch_yaw_roll_from_matrix"]


@dataclass(frozen=True)
class RigidFit:
    """Weighted absolute orientation ``p ≈ R q + r`` (000 eqs 27–38).

    Attributes
    ----------
    R_SC : (..., 3, 3) ndarray
    r_CS_S : (..., 3) ndarray
    singular_values : (..., 3) ndarray
        Of the weighted cross-covariance ``B`` (eq 33); ``σ₂ ≈ 0`` means collinear points.
    rms_residual_m : (...,) ndarray
        Weighted RMS of ``|p_i − R q_i − r|``.
    """

    R_SC: np.ndarray
    r_CS_S: np.ndarray
    singular_values: np.ndarray
    rms_residual_m: np.ndarray


def weighted_svd_pose(q_C: ArrayLike, p_S: ArrayLike, weights: ArrayLike | None = None) -> RigidFit:
    """Weighted SVD pose, 000 eqs (27)–(38) with flag P000-10 (docs/papers.md#p000-10) (Kabsch / Umeyama).

    ``q̄ = Σ w q / Σ w``, ``p̄ = Σ w p / Σ w`` (eq 30); ``B = Σ w (p − p̄)(q − q̄)ᵀ = U D Vᵀ``
    (eqs 33–34, centred); ``R = U diag(1, 1, det U det V) Vᵀ`` (eq 37); ``r = p̄ − R q̄`` (eq 38).

    Parameters
    ----------
    q_C : (..., m, 3) array_like
        Model points in C (m), m ≥ 3 (weights of 0 remove a point).
    p_S : (..., m, 3) array_like
        Matched measured points in S (m).
    weights : (..., m) array_like, optional
        Non-negative weights ``w_i`` (eq 28); default 1.
    """
    q = np.asarray(q_C, dtype=float)
    p = np.asarray(p_S, dtype=float)
    if q.shape[-1:] != (3,) or p.shape[-1:] != (3,) or q.shape[-2] < 3:
        raise ValueError(f"q_C, p_S: expected (..., m >= 3, 3) arrays, got {q.shape} and {p.shape}")
    q, p = np.broadcast_arrays(q, p)
    w = np.ones(p.shape[:-1]) if weights is None else np.broadcast_to(np.asarray(weights, dtype=float), p.shape[:-1])
    if np.any(w < 0) or not np.all(np.isfinite(w)):
        raise ValueError("weights: must be finite and >= 0")
    ws = w.sum(axis=-1, keepdims=True)
    if np.any(ws <= 0):
        raise ValueError("weights: every problem needs a positive total weight")
    qb = (w[..., None] * q).sum(-2) / ws
    pb = (w[..., None] * p).sum(-2) / ws
    B = np.einsum("...m,...mi,...mj->...ij", w, p - pb[..., None, :], q - qb[..., None, :])
    U, D, Vt = np.linalg.svd(B)
    s = np.sign(np.linalg.det(U) * np.linalg.det(Vt))
    s = np.where(s == 0, 1.0, s)
    Dm = np.zeros(B.shape)
    Dm[..., 0, 0] = 1.0
    Dm[..., 1, 1] = 1.0
    Dm[..., 2, 2] = s
    R = U @ Dm @ Vt
    r = pb - np.einsum("...ij,...j->...i", R, qb)
    res = p - (np.einsum("...ij,...mj->...mi", R, q) + r[..., None, :])
    rms = np.sqrt((w * (res**2).sum(-1)).sum(-1) / ws[..., 0])
    return RigidFit(R, r, D, rms)



def pitch_yaw_roll_from_matrix(R_SC: ArrayLike) -> np.ndarray:
    """Pitch, yaw, roll (rad) of ``R_SC`` for the 3-2-1 sequence ``R = R_z(yaw) R_y(pitch) R_x(roll)``.

    Returns ``(..., 3)`` in the paper's column order (pitch, yaw, roll).
    """
    ang, _ = euler_from_matrix(R_SC, "321")
    return np.stack([ang[..., 1], ang[..., 0], ang[..., 2]], axis=-1)
