"""Multiplicative (error-state) EKF for a tumbling target, optionally estimating inertia ratios.

Not in paper 003 (flag P003-14b, docs/papers.md#p003-14b, names it as the standard alternative
to the additive quaternion update).  The nominal state is ``[q_NT, ω_TN_T, (p)]``; the filter's covariance is on the error

* ``a`` — local attitude error, ``q_true = q̂ ⊗ exp(a/2)`` (rad, T components);
* ``δω = ω_true − ω̂`` (rad/s);
* ``δp = p_true − p̂`` with ``p = (J_yy/J_xx, J_zz/J_xx)`` when ``estimate_inertia_ratios=True``
  (flag P003-14c, docs/papers.md#p003-14c: for a non-cooperative target J is unknown; T is
  taken along the principal axes, and only the two ratios enter Euler's equation 003 eq 27);
* ``a_c`` — the local error of the cloned attitude, when a clone is held.

After each update the correction is folded into the nominal quaternion (``q̂ ← q̂ ⊗ exp(δa/2)``)
and the covariance is reset with ``G = I − ½[δa×]`` on the attitude blocks.

Measurements (same API as :class:`filters.AttitudeEKF`):

* absolute attitude ``z = q_NT ⊗ exp(e/2)``: residual ``r = log(q̂⁻¹ ⊗ z)``, ``H = [I₃ 0 …]``;
* registration increment in H, converted to N: residual ``r = log(Δq_N ⊗ (q̂ ⊗ q̂_c⁻¹)⁻¹)``
  (N components), ``H = [R̂_NT 0 … −R̂_NT]`` over ``[a, δω, (δp), a_c]`` (stochastic cloning:
  ``ΔR_true ΔR̂ᵀ ≈ exp([R̂_NT (a − a_c)×])``).

Covariance layout (``state_layout``): ``ax ay az dwx dwy dwz [dp1 dp2] [acx acy acz]``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from attitude.batch import (
    cross_product_matrices,
    matrices_from_quaternions,
    quaternion_conjugates,
    quaternion_products,
    quaternions_from_rotvecs,
    rotvecs_from_quaternions,
)

from ._base import AttitudeFilter
from .dynamics import _rk4, inertia_ratios_from_inertia
from .measurements import AbsoluteAttitudeMeasurement, IncrementMeasurement
from .state import FilterState, ProcessNoise

__all__ = ["MEKF"]


class MEKF(AttitudeFilter):
    """Multiplicative EKF on ``[a, δω, (δp)]`` for M trials at once.

    Parameters
    ----------
    J_kg_m2 : (3, 3) array
        Inertia tensor (kg·m²).  With ``estimate_inertia_ratios=False`` it is the known inertia;
        with ``True`` it must be diagonal and only supplies the default initial ratios.
    estimate_inertia_ratios : bool
        Augment the state with ``p = (J_yy/J_xx, J_zz/J_xx)``.
    process_noise : ProcessNoise, optional
    gate_probability : float or None
        Chi-square (3 dof) innovation gate; rejected measurements are counted in the state.
    reset_after_rejections : int or None
        After this many consecutive rejections the trial's covariance is reset to its initial
        value (re-acquisition; counted in ``FilterState.n_resets``).  ``None``: never.
    n_substeps : int
        RK4 sub-steps per :meth:`predict`.
    """

    _n_clone = 3

    def __init__(self, *, J_kg_m2: ArrayLike, estimate_inertia_ratios: bool = False,
                 process_noise: ProcessNoise | None = None, gate_probability: float | None = 0.9999,
                 reset_after_rejections: int | None = 10, n_substeps: int = 1) -> None:
        super().__init__(J_kg_m2=J_kg_m2, process_noise=process_noise,
                         gate_probability=gate_probability,
                         reset_after_rejections=reset_after_rejections, n_substeps=n_substeps)
        self._ratios = bool(estimate_inertia_ratios)
        self._n_core = 8 if self._ratios else 6
        self.default_inertia_ratios = (inertia_ratios_from_inertia(self.J_kg_m2) if self._ratios
                                       else None)

    @property
    def estimates_inertia_ratios(self) -> bool:
        return self._ratios

    def state_layout(self, *, with_clone: bool = False) -> tuple[str, ...]:
        names = ("ax", "ay", "az", "dwx", "dwy", "dwz")
        if self._ratios:
            names += ("dp1", "dp2")
        return names + (("acx", "acy", "acz") if with_clone else ())

    def initial_covariance(self, *, sigma_q: float = 0.1, sigma_omega_rad_s: float = np.deg2rad(0.1),
                           sigma_inertia_ratio: float | ArrayLike = 0.3) -> np.ndarray:
        """Covariance matching 003 eq (35) to first order: ``a ≈ 2 Ξᵀ δq`` gives ``4 σ_q² I₃``.

        ``sigma_inertia_ratio`` (scalar or (2,)) is used only by the inertia-ratio filter.
        """
        for v, name in ((sigma_q, "sigma_q"), (sigma_omega_rad_s, "sigma_omega_rad_s")):
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
        d = [np.full(3, 4.0 * sigma_q**2), np.full(3, sigma_omega_rad_s**2)]
        if self._ratios:
            s = np.broadcast_to(np.asarray(sigma_inertia_ratio, dtype=float), (2,))
            if not np.all(np.isfinite(s)) or np.any(s <= 0):
                raise ValueError(f"sigma_inertia_ratio: must be finite and > 0, got {sigma_inertia_ratio!r}")
            d.append(s**2)
        return np.diag(np.concatenate(d))

    # ------------------------------------------------------------------ propagation
    def predict(self, state: FilterState, dt_s: float) -> FilterState:
        """RK4 on the nominal state and on the variational equation of the error ``[a, δω, (δp)]``."""
        self._check_state(state)
        dt = float(dt_s)
        if not np.isfinite(dt) or dt < 0:
            raise ValueError(f"dt_s: must be finite and >= 0, got {dt_s!r}")
        q, w, P, qc, p = self._sanitized(state)
        j = np.concatenate([np.ones_like(p[:, :1]), p], -1) if self._ratios else None
        q1, w1, Phi = _rk4(q, w, j, dt, self._inertia, 2 if self._ratios else 0, "error",
                           self.n_substeps)
        nc = self._n_core
        pn = self.process_noise
        qdiag = [np.full(3, pn.attitude_psd_rad2_s), np.full(3, pn.rate_psd_rad2_s3)]
        if self._ratios:
            qdiag.append(np.full(2, pn.inertia_ratio_psd_1_s))
        Qc = np.diag(np.concatenate(qdiag))
        PhiT = Phi.mT
        Qd = dt * Qc
        if P.shape[-1] == nc:
            Pn = Phi @ P @ PhiT + Qd
        else:
            Pn = np.empty_like(P)
            Pn[:, :nc, :nc] = Phi @ P[:, :nc, :nc] @ PhiT + Qd
            Pn[:, :nc, nc:] = Phi @ P[:, :nc, nc:]
            Pn[:, nc:, :nc] = Pn[:, :nc, nc:].mT
            Pn[:, nc:, nc:] = P[:, nc:, nc:]
        return self._finish(state, q=q1, w=w1, P=Pn, qc=qc, p=p, t_s=state.t_s + dt, check_pd=False)

    # ------------------------------------------------------------------ measurements
    def update_absolute(self, state: FilterState, z: AbsoluteAttitudeMeasurement | None) -> FilterState:
        """Residual ``r = log(q̂⁻¹ ⊗ z)`` with ``H = [I₃ 0 …]``."""
        zq, cov, valid, bad = self._absolute_inputs(state, z)
        q, w, P, qc, p = self._sanitized(state)
        r = rotvecs_from_quaternions(quaternion_products(quaternion_conjugates(q), zq))
        dx, Pn, acc, rej, nis = self._gated_update(P, r, None, cov, valid)
        return self._apply(state, q, w, qc, p, dx, Pn, acc, rej, nis, bad)

    def update_increment(self, state: FilterState, z: IncrementMeasurement | None) -> FilterState:
        """Residual ``r = log(Δq_N ⊗ (q̂ ⊗ q̂_c⁻¹)⁻¹)``, ``H = [R̂_NT 0 … −R̂_NT]`` (module notes)."""
        dqN, covN, valid, bad = self._increment_inputs(state, z)
        M = state.n_trials
        q, w, P, qc, p = self._sanitized(state)
        dq_hat = quaternion_products(q, quaternion_conjugates(qc))
        r = rotvecs_from_quaternions(quaternion_products(dqN, quaternion_conjugates(dq_hat)))
        R_hat = matrices_from_quaternions(q)
        nc = self._n_core
        H = np.zeros((M, 3, nc + 3))
        H[:, :, :3] = R_hat
        H[:, :, nc:] = -R_hat
        dx, Pn, acc, rej, nis = self._gated_update(P, r, H, covN, valid)
        new = self._apply(state, q, w, qc, p, dx, Pn, acc, rej, nis, bad)
        return self.clone(new)

    def _apply(self, state, q, w, qc, p, dx, Pn, acc, rej, nis, bad):
        nc = self._n_core
        da = dx[:, :3]
        qn = quaternion_products(q, quaternions_from_rotvecs(da))
        qn /= np.sqrt(np.sum(qn * qn, 1, keepdims=True))
        wn = w + dx[:, 3:6]
        pn = None if p is None else p + dx[:, 6:8]
        n = Pn.shape[-1]
        G = np.zeros(Pn.shape)
        G[:] = np.eye(n)
        G[:, :3, :3] -= 0.5 * cross_product_matrices(da)
        qcn = None
        if qc is not None:
            dac = dx[:, nc:nc + 3]
            qcn = quaternion_products(qc, quaternions_from_rotvecs(dac))
            qcn /= np.sqrt(np.sum(qcn * qcn, 1, keepdims=True))
            G[:, nc:, nc:] -= 0.5 * cross_product_matrices(dac)
        Pn = G @ Pn @ G.mT
        return self._finish(state, q=qn, w=wn, P=Pn, qc=qcn, p=pn, accepted=acc, rejected=rej,
                            nis=nis, bad=bad)

    # ------------------------------------------------------------------ cloning
    def clone(self, state: FilterState) -> FilterState:
        """The clone is the local attitude error ``a`` (covariance rows ``a_c``)."""
        self._check_state(state)
        q, w, P, _, p = self._sanitized(state)
        nc = self._n_core
        M = state.n_trials
        Pc = np.empty((M, nc + 3, nc + 3))
        Pc[:, :nc, :nc] = P[:, :nc, :nc]
        Pc[:, :nc, nc:] = P[:, :nc, :3]
        Pc[:, nc:, :nc] = P[:, :3, :nc]
        Pc[:, nc:, nc:] = P[:, :3, :3]
        return self._finish(state, q=q, w=w, P=Pc, qc=q.copy(), p=p, t_clone_s=state.t_s,
                            check_pd=False)

    def drop_clone(self, state: FilterState) -> FilterState:
        """Remove the clone (back to the core covariance)."""
        self._check_state(state)
        if not state.has_clone:
            return state
        nc = self._n_core
        return state.replace(P=state.P[:, :nc, :nc].copy(), q_NT_clone=None, t_clone_s=None)

    # ------------------------------------------------------------------ evaluation
    def tangent_covariance(self, state: FilterState) -> np.ndarray:
        """Covariance ``(M, n_tangent, n_tangent)`` of ``[a, δω, (δp)]`` (the core block of P)."""
        self._check_state(state)
        nc = self._n_core
        return state.P[:, :nc, :nc].copy()
