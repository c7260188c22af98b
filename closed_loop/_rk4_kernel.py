"""Compiled RK4 of the torque-free rigid body for small batches (the dynamics factor's inner loop).

The same steps as :func:`closed_loop.torque_free_factor.propagate_batch` describes (003 eq 25–27):
RK4 on Euler's equation for the rate, and the body-rate rotation vector of the step (Simpson's rule
on the stage rates plus the coning term) for the attitude, applied by Rodrigues' formula with the
Taylor coefficients below ``θ² = 1e-12`` (:func:`attitude.batch.matrices_from_rotvecs`).  A factor
propagates one state and its 6 or 11 perturbations per call; in NumPy the ~40 small-array calls of
a step cost more than the arithmetic.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["propagate_rk4", "residuals", "rotation_logs"]

_JIT = dict(cache=True, nogil=True, error_model="numpy")


@numba.njit(**_JIT)
def _euler_rate(w: np.ndarray, J: np.ndarray, J_inv: np.ndarray, out: np.ndarray) -> None:
    """``out = J⁻¹(−ω × Jω)`` for one rate (003 eq 27)."""
    a0 = J[0, 0] * w[0] + J[0, 1] * w[1] + J[0, 2] * w[2]
    a1 = J[1, 0] * w[0] + J[1, 1] * w[1] + J[1, 2] * w[2]
    a2 = J[2, 0] * w[0] + J[2, 1] * w[1] + J[2, 2] * w[2]
    c0 = w[1] * a2 - w[2] * a1
    c1 = w[2] * a0 - w[0] * a2
    c2 = w[0] * a1 - w[1] * a0
    for i in range(3):
        out[i] = -(J_inv[i, 0] * c0 + J_inv[i, 1] * c1 + J_inv[i, 2] * c2)


@numba.njit(**_JIT)
def _rotate(R: np.ndarray, v: np.ndarray) -> None:
    """``R ← R Exp(v)`` in place (Rodrigues' formula)."""
    th2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    if th2 < 1e-12:
        a = 1.0 - th2 / 6.0
        b = 0.5 - th2 / 24.0
    else:
        th = math.sqrt(th2)
        a = math.sin(th) / th
        b = (1.0 - math.cos(th)) / th2
    S = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    E = np.eye(3) + a * S + b * (S @ S)
    R[:, :] = R @ E


@numba.njit(**_JIT)
def propagate_rk4(R_NT: np.ndarray, omega_T: np.ndarray, J_T: np.ndarray, J_inv: np.ndarray, h: float,
                  n_substeps: int) -> tuple[np.ndarray, np.ndarray]:
    """RK4 of ``(M, 3, 3)`` attitudes and ``(M, 3)`` rates, each with its tensor ``J_T[m]`` and inverse, ``n_substeps`` steps of ``h`` s."""
    M = R_NT.shape[0]
    R_out = R_NT.copy()
    w_out = omega_T.copy()
    k1, k2, k3, k4 = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    w2, w3, w4, th = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    for m in range(M):
        J, Ji, w = J_T[m], J_inv[m], w_out[m]
        for _ in range(n_substeps):
            _euler_rate(w, J, Ji, k1)
            for i in range(3):
                w2[i] = w[i] + 0.5 * h * k1[i]
            _euler_rate(w2, J, Ji, k2)
            for i in range(3):
                w3[i] = w[i] + 0.5 * h * k2[i]
            _euler_rate(w3, J, Ji, k3)
            for i in range(3):
                w4[i] = w[i] + h * k3[i]
            _euler_rate(w4, J, Ji, k4)
            cross = (w[1] * w4[2] - w[2] * w4[1], w[2] * w4[0] - w[0] * w4[2], w[0] * w4[1] - w[1] * w4[0])
            for i in range(3):
                th[i] = (h / 6.0) * (w[i] + 2.0 * (w2[i] + w3[i]) + w4[i]) + (h * h / 12.0) * cross[i]
            _rotate(R_out[m], th)
            for i in range(3):
                w[i] = w[i] + (h / 6.0) * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
    return R_out, w_out


@numba.njit(**_JIT)
def rotation_logs(R_pred: np.ndarray, R_NT1: np.ndarray) -> np.ndarray:
    """``Log(R̂ᵀR₁)`` ``(M, 3)`` of ``M`` predicted attitudes against one (rad).

    From the skew part and the trace (:func:`attitude.batch.rotvecs_from_matrices`): the residuals
    are small rotations.
    """
    M = R_pred.shape[0]
    out = np.empty((M, 3))
    for m in range(M):
        E = R_pred[m].T @ R_NT1
        w0 = 0.5 * (E[2, 1] - E[1, 2])
        w1 = 0.5 * (E[0, 2] - E[2, 0])
        w2 = 0.5 * (E[1, 0] - E[0, 1])
        s = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        c = 0.5 * (E[0, 0] + E[1, 1] + E[2, 2] - 1.0)
        f = 1.0 if s < 1e-12 else math.atan2(s, c) / s
        out[m, 0], out[m, 1], out[m, 2] = w0 * f, w1 * f, w2 * f
    return out


@numba.njit(**_JIT)
def residuals(R_pred: np.ndarray, omega_pred: np.ndarray, R_NT1: np.ndarray, omega_T1: np.ndarray) -> np.ndarray:
    """``[Log(R̂ᵀR₁), ω₁ − ω̂]`` ``(M, 6)`` of ``M`` predictions against one state (the dynamics factor's residual)."""
    M = R_pred.shape[0]
    out = np.empty((M, 6))
    out[:, :3] = rotation_logs(R_pred, R_NT1)
    for m in range(M):
        for i in range(3):
            out[m, 3 + i] = omega_T1[i] - omega_pred[m, i]
    return out
