"""The paper's 7-state additive-quaternion EKF (003 §2, eq 14–32), batched over trials.

State ``x = [q_NT, ω_TN_T]`` (003 eq 23), additive update of the four quaternion components
followed by renormalisation, with these corrections (docs/papers.md, paper 003):

* the prediction carries no noise realisation (flag P003-9, docs/papers.md#p003-9):
  ``x'_k = f(x_{k−1})``;
* propagation by RK4 with the exact Jacobian of the RK4 map (:mod:`filters.dynamics`);
* the measured quaternion's sign is chosen so that ``z · q̂ ≥ 0`` and the quaternion is
  renormalised after each update (flag P003-14b, docs/papers.md#p003-14b);
* the 4×4 measurement covariance from the unscented transform has rank 3 (nothing along ``q``).
  Completing it with only a ``1e-12 I`` jitter makes the filter badly overconfident
  (measured: average NEES ≈ 5000 instead of 6 over 100 runs), because the norm direction of the
  innovation, ``≈ −θ²/8`` for an angle θ between ``z`` and ``q̂``, is then read as a precise
  measurement and leaks into ω through the cross-covariances.  By default the missing direction
  is filled with the tangential variance, ``R = R_UT + (tr R_UT / 3) q̂ q̂ᵀ`` (``radial="isotropic"``;
  for isotropic noise this is ``σ_axis²/4 I₄``); ``radial="jitter"`` keeps the jitter-only form;
* the update is in Joseph form (remark under eq 21).

Measurements
------------
(a) :meth:`AttitudeEKF.update_absolute`: an absolute attitude ``z = q_NT ⊗ exp(e/2)``, ``e`` a
    body-frame rotation-vector error with covariance ``cov_rotvec_T``; ``H = [I₄ 0]`` (the paper's
    simulation, 003 Experiments B–D) and ``R`` the unscented-transform image of ``cov_rotvec_T``.
(b) :meth:`AttitudeEKF.update_increment`: the rotation increment between the last cloned epoch and
    now, measured by registration in the rotating Hill frame H (003 eq 29–32; frames in
    ``docs/conventions.md``).
    It is converted to N, ``Δq_N = q_NH(now) ⊗ Δq_H ⊗ q_NH(prev)⁻¹``, and compared with
    ``h(x) = q_NT(now) ⊗ q_NT(clone)⁻¹`` (eq 32) by stochastic cloning: the attitude of the earlier
    epoch is a copy kept in the state, with its cross-covariance, so the two-epoch measurement is
    processed without ignoring the correlation between the two attitudes.  This update is done on
    the three rotational components of the innovation, ``r = 2 Rm(h)[:, 1:]ᵀ (z − h)`` with
    ``R = cov_N``: the four-component form (with the radial completion below) makes the filter
    overconfident when the attitude is observed only through the dynamics (measured average NEES
    20 instead of 6 after 60 s of increments), because the discarded norm direction still removes
    covariance.

Covariance layout (``state_layout``): ``q0 q1 q2 q3 ωx ωy ωz`` then, with a clone,
``qc0 qc1 qc2 qc3``.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from attitude.batch import (
    quaternion_conjugates,
    quaternion_left_matrices,
    quaternion_products,
    quaternion_right_matrices,
    xi_matrices,
)

from ._base import AttitudeFilter
from ._batch import sym
from .dynamics import _rk4
from .measurements import AbsoluteAttitudeMeasurement, IncrementMeasurement
from .noise_mapping import rotation_noise_moments
from .state import FilterState, ProcessNoise

__all__ = ["AttitudeEKF"]

_CONJ_DIAG = np.diag([1.0, -1.0, -1.0, -1.0])


class AttitudeEKF(AttitudeFilter):
    """003's additive-quaternion EKF on ``[q_NT, ω_TN_T]`` with known inertia, for M trials at once.

    Parameters
    ----------
    J_kg_m2 : (3, 3) array
        Target inertia tensor (kg·m²), known to the filter (003 eq 27; flag P003-14c, docs/papers.md#p003-14c).
    process_noise : ProcessNoise, optional
        Spectral densities; the attitude part enters the quaternion block as ``¼ Ξ Σ Ξᵀ``.
    gate_probability : float or None
        Chi-square gate on the three rotational degrees of freedom of the innovation: a
        measurement whose NIS exceeds the ``gate_probability`` quantile of χ²₃ is rejected and
        counted.  ``None`` disables gating.
    reset_after_rejections : int or None
        After this many consecutive rejections the trial's covariance is reset to its initial
        value (re-acquisition; counted in ``FilterState.n_resets``).  ``None``: never.
    radial : {"isotropic", "jitter"}
        How the rank-3 quaternion measurement covariance is completed along the predicted
        measurement: with the mean tangential variance (default, consistent) or only with
        ``measurement_jitter`` (overconfident, see the module notes; flag P003-14b,
        docs/papers.md#p003-14b).
    measurement_jitter : float
        Added to the diagonal of the quaternion measurement covariance (flag P003-14b, docs/papers.md#p003-14b).
    n_substeps : int
        RK4 sub-steps per :meth:`predict`.
    """

    _n_core = 7
    _n_clone = 4

    def __init__(self, *, J_kg_m2: ArrayLike, process_noise: ProcessNoise | None = None,
                 gate_probability: float | None = 0.9999, reset_after_rejections: int | None = 10,
                 radial: Literal["isotropic", "jitter"] = "isotropic",
                 measurement_jitter: float = 1e-12, n_substeps: int = 1) -> None:
        super().__init__(J_kg_m2=J_kg_m2, process_noise=process_noise,
                         gate_probability=gate_probability,
                         reset_after_rejections=reset_after_rejections, n_substeps=n_substeps)
        if not np.isfinite(measurement_jitter) or measurement_jitter < 0:
            raise ValueError(f"measurement_jitter: must be finite and >= 0, got {measurement_jitter!r}")
        self.measurement_jitter = float(measurement_jitter)
        if radial not in ("isotropic", "jitter"):
            raise ValueError(f"radial: expected 'isotropic' or 'jitter', got {radial!r}")
        self.radial = radial
        self._ut_cache = None

    def _noise_moments(self, cov: np.ndarray) -> np.ndarray:
        """UT covariance of ``exp(e/2)`` for ``cov``, cached while ``cov`` does not change."""
        key = self._ut_cache
        if key is not None and key[0].shape == cov.shape and np.array_equal(key[0], cov):
            return key[1]
        C = rotation_noise_moments(cov)[1]
        self._ut_cache = (cov.copy(), C)
        return C

    def _complete(self, R4: np.ndarray, h: np.ndarray) -> np.ndarray:
        """Fill the null direction ``h`` of the UT covariance (see ``radial``) and add the jitter."""
        if self.radial == "isotropic":
            tr = (R4[:, 0, 0] + R4[:, 1, 1] + R4[:, 2, 2] + R4[:, 3, 3]) / 3.0
            R4 = R4 + tr[:, None, None] * (h[:, :, None] * h[:, None, :])
        return R4 + self.measurement_jitter * np.eye(4)

    def state_layout(self, *, with_clone: bool = False) -> tuple[str, ...]:
        names = ("q0", "q1", "q2", "q3", "wx", "wy", "wz")
        return names + (("qc0", "qc1", "qc2", "qc3") if with_clone else ())

    def initial_covariance(self, *, sigma_q: float = 0.1, sigma_omega_rad_s: float = np.deg2rad(0.1)
                           ) -> np.ndarray:
        """003 eq (35): ``P0 = diag(σ_q² I₄, σ_ω² I₃)`` (flag P003-13, docs/papers.md#p003-13: the paper calls it Q)."""
        _check_sigma(sigma_q, "sigma_q")
        _check_sigma(sigma_omega_rad_s, "sigma_omega_rad_s")
        return np.diag(np.r_[np.full(4, sigma_q**2), np.full(3, sigma_omega_rad_s**2)])

    # ------------------------------------------------------------------ propagation
    def predict(self, state: FilterState, dt_s: float) -> FilterState:
        """003 eq (16)–(17): RK4 on ``[q, ω]`` with the exact Jacobian of the RK4 map."""
        self._check_state(state)
        dt = float(dt_s)
        if not np.isfinite(dt) or dt < 0:
            raise ValueError(f"dt_s: must be finite and >= 0, got {dt_s!r}")
        q, w, P, qc, _ = self._sanitized(state)
        q1, w1, F = _rk4(q, w, None, dt, self._inertia, 0, "quaternion", self.n_substeps)
        M, n = P.shape[0], P.shape[1]
        pn = self.process_noise
        Xi = xi_matrices(q)
        Qc = np.zeros((M, 7, 7))
        Qc[:, :4, :4] = 0.25 * pn.attitude_psd_rad2_s * (Xi @ Xi.mT)
        Qc[:, 4:, 4:] = pn.rate_psd_rad2_s3 * np.eye(3)
        Qd = dt * Qc
        if n == 7:
            Pn = F @ P @ F.mT + Qd
        else:
            Pn = np.empty_like(P)
            Pn[:, :7, :7] = F @ P[:, :7, :7] @ F.mT + Qd
            Pn[:, :7, 7:] = F @ P[:, :7, 7:]
            Pn[:, 7:, :7] = Pn[:, :7, 7:].mT
            Pn[:, 7:, 7:] = P[:, 7:, 7:]
        return self._finish(state, q=q1, w=w1, P=Pn, qc=qc, p=None, t_s=state.t_s + dt, check_pd=False)

    # ------------------------------------------------------------------ measurements
    def update_absolute(self, state: FilterState, z: AbsoluteAttitudeMeasurement | None) -> FilterState:
        """003's additive update ``z = q + v`` with ``H = [I₄ 0]`` and the UT image of the noise."""
        zq, cov, valid, bad = self._absolute_inputs(state, z)
        q, w, P, qc, _ = self._sanitized(state)
        zq = np.where(np.sum(zq * q, axis=1, keepdims=True) < 0, -zq, zq)
        Lq = quaternion_left_matrices(q)
        R4 = self._complete(Lq @ self._noise_moments(cov) @ Lq.mT, q)
        G = 2.0 * xi_matrices(q).mT
        dx, Pn, acc, rej, nis = self._gated_update(P, zq - q, None, R4, valid, G=G)
        return self._apply(state, q, w, qc, dx, Pn, acc, rej, nis, bad)

    def update_increment(self, state: FilterState, z: IncrementMeasurement | None) -> FilterState:
        """Stochastic cloning on the three rotational components of the innovation (module notes)."""
        dqN, covN, valid, bad = self._increment_inputs(state, z)
        M = state.n_trials
        q, w, P, qc, _ = self._sanitized(state)
        h = quaternion_products(q, quaternion_conjugates(qc))
        zq = np.where(np.sum(dqN * h, axis=1, keepdims=True) < 0, -dqN, dqN)
        H = np.zeros((M, 4, 11))
        H[:, :, :4] = quaternion_right_matrices(quaternion_conjugates(qc))
        H[:, :, 7:] = quaternion_left_matrices(q) @ _CONJ_DIAG
        # the three rotational components of z − h: z ≈ h + ½ Rm(h)[:, 1:] v  ⇒  v ≈ G (z − h)
        G = 2.0 * quaternion_right_matrices(h)[:, :, 1:].mT
        r3 = (G @ (zq - h)[:, :, None])[:, :, 0]
        dx, Pn, acc, rej, nis = self._gated_update(P, r3, G @ H, covN, valid)
        new = self._apply(state, q, w, qc, dx, Pn, acc, rej, nis, bad)
        return self.clone(new)

    def _apply(self, state, q, w, qc, dx, Pn, acc, rej, nis, bad):
        qn = q + dx[:, :4]
        qn /= np.sqrt(np.sum(qn * qn, 1, keepdims=True))
        wn = w + dx[:, 4:7]
        qcn = None
        if qc is not None:
            qcn = qc + dx[:, 7:11]
            qcn /= np.sqrt(np.sum(qcn * qcn, 1, keepdims=True))
        return self._finish(state, q=qn, w=wn, P=Pn, qc=qcn, p=None, accepted=acc, rejected=rej,
                            nis=nis, bad=bad)

    # ------------------------------------------------------------------ cloning
    def clone(self, state: FilterState) -> FilterState:
        """The clone is the four quaternion components (covariance rows 7–10)."""
        self._check_state(state)
        q, w, P, _, _ = self._sanitized(state)
        M = state.n_trials
        Pc = np.empty((M, 11, 11))
        Pc[:, :7, :7] = P[:, :7, :7]
        Pc[:, :7, 7:] = P[:, :7, :4]
        Pc[:, 7:, :7] = P[:, :4, :7]
        Pc[:, 7:, 7:] = P[:, :4, :4]
        # the clone is an exact copy, so Pc is singular (PSD); failures are judged on the core block
        return self._finish(state, q=q, w=w, P=Pc, qc=q.copy(), p=None, t_clone_s=state.t_s,
                            check_pd=False)

    def drop_clone(self, state: FilterState) -> FilterState:
        """Remove the clone (back to the 7-state covariance)."""
        self._check_state(state)
        if not state.has_clone:
            return state
        return state.replace(P=state.P[:, :7, :7].copy(), q_NT_clone=None, t_clone_s=None)

    # ------------------------------------------------------------------ evaluation
    def tangent_covariance(self, state: FilterState) -> np.ndarray:
        """Covariance ``(M, 6, 6)`` of ``[a, δω]``: ``a ≈ 2 Ξ(q̂)ᵀ δq`` (body-frame rotation vector)."""
        self._check_state(state)
        q, _, P, _, _ = self._sanitized(state)
        M = state.n_trials
        Gm = np.zeros((M, 6, 7))
        Gm[:, :3, :4] = 2.0 * xi_matrices(q).mT
        Gm[:, 3:, 4:] = np.eye(3)
        C = sym(Gm @ P[:, :7, :7] @ Gm.mT)
        return np.where(state.failed[:, None, None], np.nan, C)


def _check_sigma(v: float, name: str) -> None:
    if not np.isfinite(v) or v <= 0:
        raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
