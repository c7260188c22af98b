"""Torque-free attitude dynamics as the filters see them: RK4 propagation with its exact Jacobian.

State of the target T relative to the inertial frame N: ``q_NT`` (Hamilton, scalar first,
``R_NT = matrix_from_quat(q_NT)`` maps T- to N-components) and ``omega_TN_T`` (rad/s, T components),

* kinematics 003 eq (25)–(26): ``q̇ = ½ Ξ(q) ω = ½ q ⊗ [0, ω]``;
* Euler's torque-free equation 003 eq (27): ``J ω̇ = −ω × J ω``.

The inertia is either a known tensor ``J_kg_m2`` (3×3, any symmetric positive-definite matrix,
not necessarily diagonal) or, for the inertia-ratio filter, the two principal-inertia ratios
``p = (J_yy/J_xx, J_zz/J_xx)`` with ``J ∝ diag(1, p₁, p₂)`` (T taken along the principal axes;
only ratios enter (27)).

One step of the classical Runge–Kutta scheme is taken on the nominal state and, with the same
stages, on the linear variational equation ``Φ̇ = A(x(t)) Φ``.  For the 7-state additive filter
(``jacobian="quaternion"``) this Φ is exactly the Jacobian of the discrete RK4 map (Runge–Kutta
methods commute with differentiation), which is the ``F_{k−1}`` of 003 eq (17), (22) with the
continuous Jacobian of 003 eq (25)–(27) (the paper does not print it):

.. math::
    A = \\begin{bmatrix}\\tfrac12\\Omega(\\omega) & \\tfrac12\\Xi(q)\\\\ 0 & J^{-1}([J\\omega\\times]-[\\omega\\times]J)\\end{bmatrix}

For the multiplicative filter (``jacobian="error"``) the tangent is the local attitude error ``a``
(``q_true = q̂ ⊗ exp(a/2)``), rate error and ratio error, with
``ȧ = −[ω̂×] a + δω`` and the same rate block.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from attitude.batch import cross_product_matrices, omega_matrices, xi_matrices
from attitude.rigid_body import check_inertia

__all__ = [
    "euler_rate_jacobian",
    "inertia_from_ratios",
    "inertia_ratios_from_inertia",
    "propagate_rk4",
]


def inertia_from_ratios(ratios: ArrayLike) -> np.ndarray:
    """``diag(1, p₁, p₂)`` from ratios ``(..., 2)`` = (J_yy/J_xx, J_zz/J_xx); ``(..., 3, 3)``."""
    p = np.asarray(ratios, dtype=float)
    if p.ndim == 0 or p.shape[-1] != 2:
        raise ValueError(f"ratios: expected shape (..., 2), got {p.shape}")
    d = np.concatenate([np.ones_like(p[..., :1]), p], -1)
    return d[..., :, None] * np.eye(3)


def inertia_ratios_from_inertia(J_kg_m2: ArrayLike) -> np.ndarray:
    """Ratios (J_yy/J_xx, J_zz/J_xx) of a diagonal inertia tensor (principal axes along T)."""
    J = check_inertia(J_kg_m2, name="J_kg_m2")
    off = J - np.diag(np.diag(J))
    if np.abs(off).max() > 1e-9 * np.abs(J).max():
        raise ValueError(
            f"J_kg_m2: inertia ratios need T along the principal axes (diagonal J), got {J.tolist()}"
        )
    return np.array([J[1, 1] / J[0, 0], J[2, 2] / J[0, 0]])


def euler_rate_jacobian(omega_TN_T: ArrayLike, J_kg_m2: ArrayLike) -> np.ndarray:
    """``∂ω̇/∂ω = J⁻¹([Jω×] − [ω×] J)``, the derivative of 003 eq (27); ``(..., 3, 3)``."""
    w = np.asarray(omega_TN_T, dtype=float)
    J = np.asarray(J_kg_m2, dtype=float)
    Jw = np.einsum("...ij,...j->...i", J, w)
    return np.linalg.solve(J, cross_product_matrices(Jw) - cross_product_matrices(w) @ J)


class _Inertia:
    """Inertia in one of two forms, with fast ω̇, ∂ω̇/∂ω and ∂ω̇/∂p for a batch ``(M, 3)``."""

    def __init__(self, *, J: np.ndarray | None = None):
        self.J = J
        self.diag = None
        if J is not None:
            self.J_inv = np.linalg.inv(J)
            if np.abs(J - np.diag(np.diag(J))).max() <= 1e-12 * np.abs(J).max():
                self.diag = np.diag(J).copy()

    def rate(self, w: np.ndarray, j: np.ndarray | None, want_jac: bool, with_ratio_jac: bool):
        """``(ω̇, A_ωω, A_ωp)``; ``j (M, 3)`` are per-trial principal moments (ratio filter)."""
        if j is None:
            j = self.diag
        sk_w = cross_product_matrices(w)
        if j is not None:
            Jw = w * j
            wdot = -(sk_w @ Jw[..., None])[..., 0] / j
            if not want_jac:
                return wdot, None, None
            Aww = (cross_product_matrices(Jw) - sk_w * j[..., None, :]) / j[..., :, None]
            Awp = None
            if with_ratio_jac:
                # ∂ω̇/∂p_i = J⁻¹(−ω × E_i ω − E_i ω̇), E_1 = diag(0, 1, 0), E_2 = diag(0, 0, 1)
                w1, w2, w3 = w[:, 0], w[:, 1], w[:, 2]
                c1 = np.stack([w2 * w3, -wdot[:, 1], -w1 * w2], -1) / j
                c2 = np.stack([-w2 * w3, w1 * w3, -wdot[:, 2]], -1) / j
                Awp = np.stack([c1, c2], -1)
            return wdot, Aww, Awp
        Jw = w @ self.J.T
        wdot = -(sk_w @ Jw[..., None])[..., 0] @ self.J_inv.T
        if not want_jac:
            return wdot, None, None
        Aww = self.J_inv @ (cross_product_matrices(Jw) - sk_w @ self.J)
        return wdot, Aww, None


_EYE3 = np.eye(3)


def _stage(q, w, j, inertia: _Inertia, kind: str | None, n_ratio: int):
    """Derivatives ``(q̇, ω̇)`` and the tangent matrix A at one RK4 stage."""
    Xi = xi_matrices(q)
    qdot = 0.5 * (Xi @ w[..., None])[..., 0]
    wdot, Aww, Awp = inertia.rate(w, j, kind is not None, n_ratio > 0)
    if kind is None:
        return qdot, wdot, None
    M = q.shape[0]
    if kind == "quaternion":
        A = np.zeros((M, 7, 7))
        A[:, :4, :4] = 0.5 * omega_matrices(w)
        A[:, :4, 4:7] = 0.5 * Xi
        A[:, 4:7, 4:7] = Aww
        return qdot, wdot, A
    e = 6 + n_ratio
    A = np.zeros((M, e, e))
    A[:, :3, :3] = -cross_product_matrices(w)
    A[:, :3, 3:6] = _EYE3
    A[:, 3:6, 3:6] = Aww
    if n_ratio:
        A[:, 3:6, 6:8] = Awp
    return qdot, wdot, A


def propagate_rk4(
    q_NT: ArrayLike,
    omega_TN_T: ArrayLike,
    dt_s: float,
    *,
    J_kg_m2: ArrayLike | None = None,
    inertia_ratios: ArrayLike | None = None,
    jacobian: Literal["quaternion", "error"] | None = None,
    n_substeps: int = 1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Propagate a batch of torque-free states by ``dt_s`` with RK4 and its Jacobian.

    Parameters
    ----------
    q_NT : (M, 4) array
        Attitude (T to N), unit quaternions.
    omega_TN_T : (M, 3) array
        Body rate, rad/s, T components.
    dt_s : float
        Step in seconds (may be 0).
    J_kg_m2 : (3, 3) array, optional
        Known inertia tensor (kg·m²).  Exactly one of ``J_kg_m2`` and ``inertia_ratios``.
    inertia_ratios : (M, 2) array, optional
        (J_yy/J_xx, J_zz/J_xx) per trial, held constant over the step.
    jacobian : {"quaternion", "error", None}
        ``"quaternion"``: the 7×7 Jacobian of the RK4 map on ``[q, ω]`` (additive EKF, 003 eq 22).
        ``"error"``: the (6 or 8)-square transition of the error state ``[a, δω, (δp)]`` (MEKF).
    n_substeps : int
        RK4 sub-steps per call (the Jacobians compose).

    Returns
    -------
    q_NT : (M, 4) array
        Propagated attitude, renormalised (flag P003-14b, docs/papers.md#p003-14b; the Jacobian
        is that of the map before renormalisation, as in 003's filter).
    omega_TN_T : (M, 3) array
    Phi : (M, n, n) array or None
        Transition matrix over the whole step.
    """
    q = np.asarray(q_NT, dtype=float)
    w = np.asarray(omega_TN_T, dtype=float)
    if q.ndim != 2 or q.shape[1] != 4:
        raise ValueError(f"q_NT: expected shape (M, 4), got {q.shape}")
    if w.shape != (q.shape[0], 3):
        raise ValueError(f"omega_TN_T: expected shape ({q.shape[0]}, 3), got {w.shape}")
    if inertia_ratios is not None and np.shape(inertia_ratios) != (q.shape[0], 2):
        raise ValueError(f"inertia_ratios: expected shape ({q.shape[0]}, 2), got {np.shape(inertia_ratios)}")
    if (J_kg_m2 is None) == (inertia_ratios is None):
        raise ValueError("J_kg_m2/inertia_ratios: give exactly one of them")
    if n_substeps < 1:
        raise ValueError(f"n_substeps: must be >= 1, got {n_substeps}")
    if jacobian not in (None, "quaternion", "error"):
        raise ValueError(f"jacobian: expected 'quaternion', 'error' or None, got {jacobian!r}")
    if jacobian == "quaternion" and inertia_ratios is not None:
        raise ValueError("jacobian: 'quaternion' Jacobian is for a known inertia tensor only")
    inertia = _Inertia(J=None if J_kg_m2 is None else check_inertia(J_kg_m2, name="J_kg_m2"))
    j = None
    n_ratio = 0
    if inertia_ratios is not None:
        p = np.asarray(inertia_ratios, dtype=float)
        j = np.concatenate([np.ones_like(p[:, :1]), p], -1)
        n_ratio = 2
    return _rk4(q, w, j, float(dt_s), inertia, n_ratio, jacobian, n_substeps)


def _rk4(q, w, j, dt, inertia, n_ratio, kind, n_substeps):
    h = dt / n_substeps
    Phi = None
    for _ in range(n_substeps):
        qd1, wd1, A1 = _stage(q, w, j, inertia, kind, n_ratio)
        qd2, wd2, A2 = _stage(q + (0.5 * h) * qd1, w + (0.5 * h) * wd1, j, inertia, kind, n_ratio)
        qd3, wd3, A3 = _stage(q + (0.5 * h) * qd2, w + (0.5 * h) * wd2, j, inertia, kind, n_ratio)
        qd4, wd4, A4 = _stage(q + h * qd3, w + h * wd3, j, inertia, kind, n_ratio)
        q = q + (h / 6.0) * (qd1 + 2.0 * (qd2 + qd3) + qd4)
        q = q / np.sqrt(np.sum(q * q, -1, keepdims=True))
        w = w + (h / 6.0) * (wd1 + 2.0 * (wd2 + wd3) + wd4)
        if kind is not None:
            K2 = A2 + (0.5 * h) * (A2 @ A1)
            K3 = A3 + (0.5 * h) * (A3 @ K2)
            K4 = A4 + h * (A4 @ K3)
            step = (h / 6.0) * (A1 + 2.0 * (K2 + K3) + K4)
            step += np.eye(A1.shape[-1])
            Phi = step if Phi is None else step @ Phi
    return q, w, Phi
