"""Torque-free rigid-body dynamics as a gtsam factor between two epochs, with unknown inertia.

The target's body frame T is the first frame's (flag P003-14a, docs/papers.md#p003-14a), not its
principal frame, so its inertia tensor in T is a full symmetric matrix.  Only its shape enters
Euler's torque-free equation (003 eq 27, ``J ω̇ = −ω × J ω``): five numbers.  The graph estimates
them as the tensor's own entries at trace 3 (:func:`tensor_from_entries`),
``p = (J₁₁, J₂₂, J₁₂, J₁₃, J₂₃)`` with ``J₃₃ = 3 − J₁₁ − J₂₂``, because Euler's equation is linear in
them: a short stretch of motion constrains ``p`` along a plane, where the principal axes and two
moment ratios see a curved ridge on which the Gaussian approximation of a young estimate is far
too confident (docs/closed_loop.md, "Consistency, measured").  :class:`InertiaShape` reports the
same shape as principal axes ``R_TP`` and log-ratios ``l = (ln J₂/J₁, ln J₃/J₁)``:

.. math::  J_T = R_{TP}\\,\\mathrm{diag}(1, e^{l_1}, e^{l_2})\\,R_{TP}^\\mathsf{T}.

Variables of the graph (gtsam keys): ``Y_k = R_TN(k)`` (:class:`gtsam.Rot3`, the transpose of the
attitude ``R_NT`` so that a registered increment is a plain :class:`gtsam.BetweenFactorRot3`),
``ω_k`` (body rate, rad/s, ``Vector3``) and ``p`` (``Vector5``).

The factor compares epoch ``k+1`` with the RK4 propagation of epoch ``k`` (003 eq 25–27):

.. math::
    r = \\begin{bmatrix} \\mathrm{Log}(\\hat R_{NT}(k{+}1)^\\mathsf{T} R_{NT}(k{+}1)) \\\\
                         \\omega_{k+1} - \\hat\\omega_{k+1} \\end{bmatrix}

with a small process noise.  Its Jacobians are finite differences of one batched RK4 call (the
nominal state and its 11 perturbations propagated together, compiled: :mod:`closed_loop._rk4_kernel`).
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from attitude.batch import matrices_from_rotvecs
from closed_loop._rk4_kernel import propagate_rk4, residuals, rotation_logs

__all__ = ["InertiaShape", "torque_free_factor", "propagate_batch", "rotation_error_T", "tensor_from_entries"]

_H = 1e-6  # finite-difference step (rad, rad/s, tensor entry)


@dataclass(frozen=True)
class InertiaShape:
    """The shape of an inertia tensor: principal axes in T and two log-ratios (module docstring).

    Attributes
    ----------
    R_TP : ndarray (3, 3)
        Principal axes (columns) in T.
    log_ratios : ndarray (2,)
        ``(ln J₂/J₁, ln J₃/J₁)`` of the principal moments in the columns' order.
    """

    R_TP: np.ndarray
    log_ratios: np.ndarray

    @property
    def J_T(self) -> np.ndarray:
        """The tensor in T, scaled so that ``J₁ = 1`` (``(3, 3)``)."""
        d = np.concatenate([[1.0], np.exp(self.log_ratios)])
        return (self.R_TP * d) @ self.R_TP.T

    @classmethod
    def from_tensor(cls, J_T: np.ndarray) -> InertiaShape:
        """The shape of a symmetric positive-definite tensor (principal axes sorted by moment, right-handed)."""
        J = 0.5 * (np.asarray(J_T, dtype=float) + np.asarray(J_T, dtype=float).T)
        m, V = np.linalg.eigh(J)
        if np.linalg.det(V) < 0:
            V[:, 2] = -V[:, 2]
        return cls(R_TP=V, log_ratios=np.log(m[1:] / m[0]))

    @property
    def entries(self) -> np.ndarray:
        """The tensor's five free entries ``(J₁₁, J₂₂, J₁₂, J₁₃, J₂₃)`` at trace 3 (:func:`tensor_from_entries`)."""
        J = self.J_T * (3.0 / np.trace(self.J_T))
        return np.array([J[0, 0], J[1, 1], J[0, 1], J[0, 2], J[1, 2]])

    @classmethod
    def from_entries(cls, entries: np.ndarray) -> InertiaShape:
        """The shape of the trace-3 tensor with these five entries (:func:`tensor_from_entries`)."""
        return cls.from_tensor(tensor_from_entries(np.asarray(entries, float)[None])[0])

    def principal_moments(self) -> np.ndarray:
        """Sorted principal moments ``(3,)`` with the smallest equal to 1."""
        m = np.sort(np.linalg.eigvalsh(self.J_T))
        return m / m[0]


def tensor_from_entries(p: np.ndarray, floor: float = 0.05) -> np.ndarray:
    """Trace-3 tensors ``(M, 3, 3)`` from their entries ``(M, 5)``: ``(J₁₁, J₂₂, J₁₂, J₁₃, J₂₃)``, ``J₃₃ = 3 − J₁₁ − J₂₂``.

    Euler's equation ``J ω̇ = −ω × Jω`` is linear in these entries, so a short stretch of motion
    constrains them linearly, where the principal axes and log-ratios see a curved ridge.  A wild
    iterate that is not positive definite has its eigenvalues raised to ``floor`` (the prior and the
    data pull it back).
    """
    J = np.empty((p.shape[0], 3, 3))
    J[:, 0, 0], J[:, 1, 1], J[:, 2, 2] = p[:, 0], p[:, 1], 3.0 - p[:, 0] - p[:, 1]
    J[:, 0, 1] = J[:, 1, 0] = p[:, 2]
    J[:, 0, 2] = J[:, 2, 0] = p[:, 3]
    J[:, 1, 2] = J[:, 2, 1] = p[:, 4]
    # Sylvester's criterion on J − floor·I: every leading minor positive ⇔ every eigenvalue above the
    # floor, so only the tensors that fail it need an eigendecomposition (a factor's usual case: none)
    S = J - floor * np.eye(3)
    ok = (S[:, 0, 0] > 0) & (S[:, 0, 0] * S[:, 1, 1] - S[:, 0, 1] ** 2 > 0) & (np.linalg.det(S) > 0)
    if not ok.all():
        m, V = np.linalg.eigh(J[~ok])
        J[~ok] = (V * np.maximum(m, floor)[:, None, :]) @ np.swapaxes(V, 1, 2)
    return J


def propagate_batch(R_NT: np.ndarray, omega_T: np.ndarray, J_T: np.ndarray, dt_s: float,
                    n_substeps: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """RK4 of 003 eq (25)–(27) for a batch of states, each with its own inertia tensor.

    The rate is integrated with RK4 and the attitude with the matching 4th-order step of the
    body-rate rotation vector (``R ← R Exp(h (k₁ + 2k₂ + 2k₃ + k₄)/6)`` on the stage rates, which
    is RK4 of the kinematics to the order of the step; the attitude stays on SO(3)).

    Parameters
    ----------
    R_NT : ndarray (M, 3, 3)
    omega_T : ndarray (M, 3)
        Body rates, rad/s.
    J_T : ndarray (M, 3, 3)
        Inertia tensors (any scale).
    dt_s : float
    n_substeps : int

    Returns
    -------
    R_NT, omega_T : ndarray (M, 3, 3), (M, 3)
    """
    R = np.ascontiguousarray(R_NT, dtype=float)
    J = np.ascontiguousarray(np.broadcast_to(np.asarray(J_T, dtype=float), R.shape))
    # compiled (closed_loop._rk4_kernel): a factor's batch is 7 or 12 states, where NumPy's
    # per-call overhead outweighs the arithmetic
    return propagate_rk4(R, np.ascontiguousarray(omega_T, dtype=float), J, np.linalg.inv(J),
                         float(dt_s) / int(n_substeps), int(n_substeps))


def rotation_error_T(R_est: np.ndarray, R_true: np.ndarray) -> np.ndarray:
    """``Log(R_estᵀ R_true)`` for batches ``(M, 3, 3)``: the body-frame rotation from estimate to truth, rad."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.swapaxes(R_est, -1, -2) @ R_true).as_rotvec()


_EXP_MINUS_H = matrices_from_rotvecs(-_H * np.eye(3))
_EXP_PLUS_H = np.ascontiguousarray(np.swapaxes(_EXP_MINUS_H, 1, 2))


def torque_free_factor(noise: gtsam.noiseModel.Base, keys: tuple[int, ...], dt_s: float, *,
                       n_substeps: int = 1, J_T: np.ndarray | None = None) -> gtsam.CustomFactor:
    """The dynamics factor between two epochs (module docstring).

    Parameters
    ----------
    noise : gtsam.noiseModel.Base
        6-dimensional noise of ``[attitude (rad), rate (rad/s)]``.
    keys : (Y_k, ω_k, Y_{k+1}, ω_{k+1}, p) or (Y_k, ω_k, Y_{k+1}, ω_{k+1})
        gtsam keys of the two epochs' states and of the inertia entries (without them: ``J_T`` given).
    dt_s : float
        Time between the epochs, s.
    n_substeps : int
        RK4 sub-steps.
    J_T : ndarray (3, 3), optional
        A known inertia tensor (then ``keys`` has four entries).

    Returns
    -------
    gtsam.CustomFactor
    """
    eye = np.eye(3)
    known = J_T is not None
    if len(keys) != (4 if known else 5):
        raise ValueError(f"keys: expected 4 keys with J_T or 5 without, got {len(keys)}")
    J_known = None if J_T is None else np.asarray(J_T, float)

    def error(this: gtsam.CustomFactor, values: gtsam.Values, H: list[np.ndarray] | None) -> np.ndarray:
        ks = this.keys()
        R0 = values.atRot3(ks[0]).matrix().T
        w0 = values.atVector(ks[1])
        R1 = values.atRot3(ks[2]).matrix().T
        w1 = values.atVector(ks[3])
        want = H is not None
        M = (7 if known else 12) if want else 1
        Rb = np.empty((M, 3, 3))
        Rb[:] = R0
        wb = np.empty((M, 3))
        wb[:] = w0
        if want:
            # Y₀ ⊕ ε = Y₀ Exp(ε)  ⇒  R_NT ← Exp(−ε) R_NT
            Rb[1:4] = _EXP_MINUS_H @ R0
            wb[4:7] += _H * eye
        if known:
            J = np.broadcast_to(J_known, (M, 3, 3))
        else:
            pb = np.empty((M, 5))
            pb[:] = values.atVector(ks[4])
            if want:
                pb[7:12] += _H * np.eye(5)
            J = tensor_from_entries(pb)
        Rp, wp = propagate_batch(Rb, wb, J, dt_s, n_substeps)
        r = residuals(Rp, wp, R1, w1)
        r_att = r[:, :3]
        if want:
            D = (r[1:] - r[0]).T / _H  # (6, 11)
            # derivatives with respect to the later epoch: R₁ ← Exp(−ε) R₁, i.e. body perturbation −R₁ᵀ ε
            # (R̂ᵀ Exp(−ε) R₁ = (Exp(ε) R̂)ᵀ R₁)
            r_eps = rotation_logs(_EXP_PLUS_H @ Rp[0], R1)
            H[0] = D[:, 0:3]
            H[1] = D[:, 3:6]
            H[2] = np.vstack([(r_eps - r_att[0]).T / _H, np.zeros((3, 3))])
            H[3] = np.vstack([np.zeros((3, 3)), eye])
            if not known:
                H[4] = D[:, 6:11]
        return r[0]

    return gtsam.CustomFactor(noise, list(keys), error)
