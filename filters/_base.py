"""Machinery shared by the additive EKF and the MEKF: validation, gating, failure bookkeeping."""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np
from numpy.typing import ArrayLike
from scipy.stats import chi2

from attitude.batch import (
    matrices_from_quaternions,
    quaternion_conjugates,
    quaternion_products,
    rotvecs_from_quaternions,
)
from attitude.quaternion import quat_from_matrix
from attitude.rigid_body import check_inertia

from ._batch import as_batch, inv3, positive_definite, sym
from .dynamics import _Inertia
from .measurements import AbsoluteAttitudeMeasurement, IncrementMeasurement
from .state import FAILURE_NON_FINITE, FAILURE_NOT_PD, FilterState, ProcessNoise

_IDENTITY_Q = np.array([1.0, 0.0, 0.0, 0.0])
_EYES = {n: np.eye(n) for n in range(1, 16)}


def _eye(n: int) -> np.ndarray:
    return _EYES[n]


def _missing(z: object, kind: type) -> bool:
    """True for ``None`` (no measurement this epoch); ValueError unless ``z`` is a ``kind``."""
    if z is None:
        return True
    if not isinstance(z, kind):
        raise ValueError(f"z: expected an {kind.__name__} or None, got {type(z).__name__}")
    return False


def _no_measurement(M: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Rows of an epoch without measurement: identity quaternions, unit covariances, none valid,
    none bad.

    With nothing valid the gain is zero, so these placeholders never reach the estimate.
    """
    none = np.zeros(M, bool)
    return np.tile(_IDENTITY_Q, (M, 1)), np.tile(_eye(3), (M, 1, 1)), none, none


class AttitudeFilter(ABC):
    """Common base of :class:`~filters.AttitudeEKF` and :class:`~filters.MEKF` (not used directly).

    Subclasses define the covariance coordinates (``state_layout``), the propagation Jacobian and
    the measurement Jacobians; this base validates input, gates innovations (chi-square on three
    degrees of freedom), keeps the covariance symmetric (Joseph form), and flags trials whose
    covariance stops being positive definite instead of raising inside a batch.
    """

    #: number of covariance coordinates of the attitude/rate core (without clone)
    _n_core: int
    #: number of covariance coordinates of a clone
    _n_clone: int

    def __init__(
        self,
        *,
        J_kg_m2: ArrayLike,
        process_noise: ProcessNoise | None = None,
        gate_probability: float | None = 0.9999,
        reset_after_rejections: int | None = 10,
        n_substeps: int = 1,
    ) -> None:
        self.J_kg_m2 = check_inertia(J_kg_m2, name="J_kg_m2")
        self._inertia = _Inertia(J=self.J_kg_m2)
        self.process_noise = ProcessNoise() if process_noise is None else process_noise
        if not isinstance(self.process_noise, ProcessNoise):
            raise ValueError(f"process_noise: expected a ProcessNoise, got {process_noise!r}")
        if gate_probability is not None and not (0.0 < gate_probability < 1.0):
            raise ValueError(f"gate_probability: must be in (0, 1) or None, got {gate_probability!r}")
        self.gate_probability = gate_probability
        self.gate_threshold = np.inf if gate_probability is None else float(chi2.ppf(gate_probability, 3))
        if reset_after_rejections is not None and (int(reset_after_rejections) != reset_after_rejections
                                                   or reset_after_rejections < 1):
            raise ValueError(f"reset_after_rejections: must be an integer >= 1 or None, got {reset_after_rejections!r}")
        self.reset_after_rejections = None if reset_after_rejections is None else int(reset_after_rejections)
        if int(n_substeps) != n_substeps or n_substeps < 1:
            raise ValueError(f"n_substeps: must be an integer >= 1, got {n_substeps!r}")
        self.n_substeps = int(n_substeps)

    # ------------------------------------------------------------------ construction
    @property
    def estimates_inertia_ratios(self) -> bool:
        return False

    @property
    def n_tangent(self) -> int:
        """Dimension of the tangent error ``[a, δω, (δp)]`` used for NEES."""
        return 8 if self.estimates_inertia_ratios else 6

    def initial_state(
        self,
        q_NT: ArrayLike,
        omega_TN_T: ArrayLike,
        P0: ArrayLike,
        *,
        t_s: float = 0.0,
        inertia_ratios: ArrayLike | None = None,
    ) -> FilterState:
        """Initial state of a batch.

        Parameters
        ----------
        q_NT : (4,) or (M, 4) array
            Initial attitude estimates (normalised here).
        omega_TN_T : (3,) or (M, 3) array
            Initial rate estimates, rad/s.
        P0 : (n, n) or (M, n, n) array
            Initial covariance in the coordinates of :attr:`state_layout` without the clone
            (see :meth:`initial_covariance` for the one that matches 003 eq (35)).
        t_s : float
            Epoch of the initial estimate.
        inertia_ratios : (2,) or (M, 2) array, optional
            Initial inertia-ratio estimates (inertia-ratio MEKF only; default: those of ``J_kg_m2``).
        """
        q = np.asarray(q_NT, dtype=float)
        if q.ndim == 1:
            q = q[None]
        if q.ndim != 2 or q.shape[1] != 4 or not np.all(np.isfinite(q)):
            raise ValueError(f"q_NT: expected finite (4,) or (M, 4), got shape {np.shape(q_NT)}")
        n = np.linalg.norm(q, axis=1, keepdims=True)
        if np.any(n < 1e-6):
            raise ValueError("q_NT: zero quaternion")
        q = q / n
        M = q.shape[0]
        w = np.asarray(omega_TN_T, dtype=float)
        w = as_batch(w, M, (3,), "omega_TN_T").copy()
        if not np.all(np.isfinite(w)):
            raise ValueError("omega_TN_T: contains non-finite values")
        nc = self._n_core
        P = as_batch(np.asarray(P0, dtype=float), M, (nc, nc), "P0").copy()
        P = sym(P)
        if not np.all(positive_definite(P)):
            raise ValueError("P0: not positive definite")
        ratios = None
        if self.estimates_inertia_ratios:
            if inertia_ratios is None:
                inertia_ratios = self.default_inertia_ratios
            ratios = as_batch(np.asarray(inertia_ratios, dtype=float), M, (2,), "inertia_ratios").copy()
            if not np.all(np.isfinite(ratios)) or np.any(ratios <= 0):
                raise ValueError(f"inertia_ratios: must be finite and > 0, got {ratios.tolist()}")
        elif inertia_ratios is not None:
            raise ValueError("inertia_ratios: this filter uses the known J_kg_m2 (no ratio state)")
        return FilterState(
            t_s=float(t_s), q_NT=q, omega_TN_T=w, P=P, inertia_ratios=ratios, q_NT_clone=None,
            t_clone_s=None, n_accepted=np.zeros(M, dtype=int), n_rejected=np.zeros(M, dtype=int),
            n_consecutive_rejected=np.zeros(M, dtype=int), n_resets=np.zeros(M, dtype=int),
            P_reset=P.copy(),
            failed=np.zeros(M, dtype=bool), failure_reason=np.full(M, "", dtype=object),
            last_nis=np.full(M, np.nan),
        )

    # ------------------------------------------------------------------ the filter interface
    @abstractmethod
    def predict(self, state: FilterState, dt_s: float) -> FilterState:
        """Propagate every trial by ``dt_s`` through the torque-free dynamics (003 eq (25)–(27)).

        Parameters
        ----------
        state : FilterState
            Batch of ``M`` estimates; failed trials stay failed (NaN) and are not propagated.
        dt_s : float
            Time step, s, finite and ``>= 0``.  The nominal state takes ``n_substeps`` RK4 steps
            and the covariance the matching transition matrix plus ``dt_s`` times the process-noise
            density (no noise realisation: flag P003-9, docs/papers.md#p003-9).  A clone, if
            held, stays at its epoch; its cross-covariance is carried along.

        Returns
        -------
        FilterState
            A new state at ``state.t_s + dt_s``; a trial whose estimate turns non-finite is
            flagged ``failed``.

        Raises
        ------
        ValueError
            If ``state`` belongs to another filter or ``dt_s`` is negative or not finite.
        """

    @abstractmethod
    def update_absolute(self, state: FilterState, z: AbsoluteAttitudeMeasurement | None) -> FilterState:
        """Update every trial with a measured absolute attitude ``z.q_NT = q_NT ⊗ exp(e/2)``.

        Parameters
        ----------
        state : FilterState
        z : AbsoluteAttitudeMeasurement or None
            One row per trial (or one shared row).  All-NaN rows and ``None`` (no measurement
            this epoch) are missing: they leave those trials as they are, apart from the
            symmetrisation of P that every update applies and a NaN ``last_nis``.  Bad rows (±inf
            or partly NaN components, a zero quaternion, a covariance that is not finite or not
            positive definite) leave the trials as they are too, but are counted in
            ``n_rejected`` (not towards ``reset_after_rejections``).

        Returns
        -------
        FilterState
            The updated state.  A measurement whose normalised innovation squared (three rotational
            degrees of freedom) exceeds the chi-square gate is rejected and counted in
            ``n_rejected``; after ``reset_after_rejections`` consecutive rejections the trial's
            covariance is reset.  A trial whose covariance stops being positive definite is
            flagged ``failed`` (``ok`` false) instead of raising.

        Raises
        ------
        ValueError
            If ``state`` belongs to another filter or ``z`` has the wrong number of trials.
        """

    @abstractmethod
    def update_increment(self, state: FilterState, z: IncrementMeasurement | None) -> FilterState:
        """Update with the registered increment since the clone, then clone the current attitude.

        The increment, measured in the rotating Hill frame, is converted to N,
        ``Δq_N = q_NH(now) ⊗ Δq_H ⊗ q_NH(prev)⁻¹`` (``docs/conventions.md``), and compared with
        ``q_NT(now) ⊗ q_NT(clone)⁻¹`` (003 eq (29)–(32)) by stochastic cloning: the attitude of the
        earlier epoch is kept in the state with its cross-covariance, so the correlation between
        the two epochs is not ignored (flag P003-14a, docs/papers.md#p003-14a).

        Parameters
        ----------
        state : FilterState
            Must hold a clone (:meth:`clone`) taken at the earlier epoch of the increment.
        z : IncrementMeasurement or None
            One row per trial (or one shared row).  All-NaN rows and ``None`` (no increment
            this epoch) only re-clone those trials; bad rows (as in :meth:`update_absolute`) only
            re-clone them too and are counted in ``n_rejected``.

        Returns
        -------
        FilterState
            The updated state, cloned at its epoch; gating, resets and failures as in
            :meth:`update_absolute`.

        Raises
        ------
        ValueError
            If ``state`` holds no clone or belongs to another filter, or ``z`` has the wrong
            number of trials.
        """

    @abstractmethod
    def clone(self, state: FilterState) -> FilterState:
        """Copy the current attitude, with its covariance rows and columns, into the clone slot.

        Parameters
        ----------
        state : FilterState
            With or without a clone (an existing clone is replaced).

        Returns
        -------
        FilterState
            ``q_NT_clone = q_NT``, ``t_clone_s = t_s``; the covariance gains the clone block, an
            exact copy of the attitude block (so it is only positive semi-definite).
        """

    # ------------------------------------------------------------------ helpers
    def _check_state(self, state: FilterState) -> None:
        if not isinstance(state, FilterState):
            raise ValueError(f"state: expected a FilterState, got {type(state).__name__}")
        n = self._n_core + (self._n_clone if state.has_clone else 0)
        if state.P.shape[1:] != (n, n):
            raise ValueError(
                f"state: covariance of shape {state.P.shape[1:]} does not belong to "
                f"{type(self).__name__} (expected {(n, n)})"
            )

    def _sanitized(self, state: FilterState):
        """Arrays with failed rows replaced by harmless values (so batch kernels never see NaN)."""
        f = state.failed
        if not f.any():
            return state.q_NT, state.omega_TN_T, state.P, state.q_NT_clone, state.inertia_ratios
        q = np.where(f[:, None], _IDENTITY_Q, state.q_NT)
        w = np.where(f[:, None], 0.0, state.omega_TN_T)
        n = state.P.shape[-1]
        P = np.where(f[:, None, None], np.eye(n), state.P)
        qc = None if state.q_NT_clone is None else np.where(f[:, None], _IDENTITY_Q, state.q_NT_clone)
        p = None if state.inertia_ratios is None else np.where(f[:, None], 1.0, state.inertia_ratios)
        return q, w, P, qc, p

    def _finish(self, state: FilterState, *, q, w, P, qc, p, accepted=None, rejected=None,
                nis=None, t_s=None, t_clone_s=None, check_pd=True, bad=None) -> FilterState:
        """Assemble the new state: detect failures, NaN the failed rows, count measurements.

        ``bad`` rows (unusable measurement rows, see :meth:`_measurement_rows`) count in
        ``n_rejected`` but not towards ``reset_after_rejections``: they say nothing about the
        filter's own consistency.

        With ``check_pd`` (after updates) P is symmetrised and its core block Cholesky-tested; a
        prediction (``check_pd=False``) only tests that the estimates stayed finite, since
        ``F P Fᵀ + Q`` of a positive-definite P is positive definite.
        """
        failed = state.failed
        reason = state.failure_reason
        if check_pd:
            P = sym(P)
            finite = np.isfinite(q).all(1) & np.isfinite(w).all(1)
            nc = self._n_core
            ok = finite & positive_definite(P[:, :nc, :nc])
        else:
            ok = np.isfinite(q).all(1) & np.isfinite(w).all(1)
        new = ~failed & ~ok
        if new.any():
            failed = failed | new
            reason = reason.copy()
            reason[new & ~ok] = FAILURE_NOT_PD if check_pd else FAILURE_NON_FINITE
            if check_pd:
                nf = new & ~(np.isfinite(q).all(1) & np.isfinite(w).all(1)
                             & np.isfinite(P).all((1, 2)))
                reason[nf] = FAILURE_NON_FINITE
        if failed.any():
            fm = failed[:, None]
            q = np.where(fm, np.nan, q)
            w = np.where(fm, np.nan, w)
            P = np.where(failed[:, None, None], np.nan, P)
            if qc is not None:
                qc = np.where(fm, np.nan, qc)
            if p is not None:
                p = np.where(fm, np.nan, p)
        n_acc, n_rej = state.n_accepted, state.n_rejected
        consec, n_resets = state.n_consecutive_rejected, state.n_resets
        last_nis = state.last_nis
        if rejected is not None:
            acc = accepted & ~failed
            rej = rejected & ~failed
            n_acc = n_acc + acc
            n_rej = n_rej + rej
            if bad is not None:
                n_rej = n_rej + (bad & ~failed)
            consec = np.where(rej, consec + 1, np.where(acc, 0, consec))
            if self.reset_after_rejections is not None:
                reset = consec >= self.reset_after_rejections
                if reset.any():
                    # re-acquire: core covariance back to P_reset, cross-covariance with a clone zeroed
                    nc = self._n_core
                    P = P.copy()
                    P[reset, :nc, :] = 0.0
                    P[reset, :, :nc] = 0.0
                    P[reset, :nc, :nc] = state.P_reset[reset]
                    consec = np.where(reset, 0, consec)
                    n_resets = n_resets + reset
            last_nis = np.where(failed, np.nan, nis)
        elif nis is None and check_pd:
            last_nis = np.full(q.shape[0], np.nan)
        return FilterState(
            t_s=state.t_s if t_s is None else float(t_s), q_NT=q, omega_TN_T=w, P=P,
            inertia_ratios=p, q_NT_clone=qc,
            t_clone_s=state.t_clone_s if t_clone_s is None else t_clone_s,
            n_accepted=n_acc, n_rejected=n_rej, n_consecutive_rejected=consec, n_resets=n_resets,
            P_reset=state.P_reset, failed=failed, failure_reason=reason,
            last_nis=last_nis,
        )

    @staticmethod
    def _measurement_rows(z: np.ndarray, M: int, width: int, name: str
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Measurement batch ``(M, width)``, its validity mask and its mask of bad rows.

        A row whose components are all NaN is missing (neither valid nor bad).  A row with ±inf
        or only some NaN components, and for quaternions (``width == 4``) a row of norm
        ``<= 1e-6``, is bad: replaced by a harmless placeholder, never used, and counted as
        rejected by the caller.  Valid quaternions are normalised.
        """
        z = np.asarray(z, dtype=float)
        if z.shape == (width,):
            z = np.broadcast_to(z, (M, width))
        if z.shape != (M, width):
            raise ValueError(f"{name}: expected shape ({width},) or ({M}, {width}), got {z.shape}")
        valid = np.isfinite(z).all(1)
        bad = ~valid & ~np.isnan(z).all(1)
        if width == 4:
            if not valid.all():
                z = np.where(valid[:, None], z, _IDENTITY_Q)
            nz = np.sqrt(np.sum(z * z, 1, keepdims=True))
            small = nz[:, 0] <= 1e-6
            if small.any():
                valid = valid & ~small
                bad = bad | small
                z = np.where(small[:, None], _IDENTITY_Q, z)
                nz = np.where(small[:, None], 1.0, nz)
            z = z / nz
        return z, valid, bad

    @staticmethod
    def _cov_rows(cov: ArrayLike, M: int, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Symmetrised covariance batch ``(M, 3, 3)`` and the mask of usable rows.

        A row is usable when it is finite and positive definite (leading principal minors of its
        symmetric part > 0); the others are replaced by the identity, so that no NaN and no
        indefinite matrix reaches the filter's algebra.
        """
        cov = np.asarray(cov, dtype=float)
        cov = as_batch(cov, M, (3, 3), name)
        finite = np.isfinite(cov).all((1, 2))
        cov = sym(cov) if finite.all() else np.where(finite[:, None, None], sym(cov), np.eye(3))
        a, b, c = cov[:, 0, 0], cov[:, 0, 1], cov[:, 0, 2]
        d, e, f = cov[:, 1, 1], cov[:, 1, 2], cov[:, 2, 2]
        det = a * (d * f - e * e) - b * (b * f - c * e) + c * (b * e - c * d)
        ok = finite & (a > 0) & (a * d - b * b > 0) & (det > 0)
        if not ok.all():
            cov = np.where(ok[:, None, None], cov, np.eye(3))
        return cov, ok

    def _gated_update(self, P, r, H, R, valid, G=None):
        """Batched Kalman update with chi-square gating.

        ``r (M, m)`` innovation, ``R (M, m, m)``; ``H (M, m, n)``, or ``None`` for ``H = [I_m 0]``
        (the absolute-attitude measurements); ``G (M, 3, m)`` projects a 4-component quaternion
        innovation onto its 3 rotational degrees of freedom for the gate.
        Returns (dx, P_new, accepted, rejected, nis).
        """
        M, m = r.shape
        n = P.shape[-1]
        if H is None:
            PHt = P[:, :, :m]
            S = P[:, :m, :m] + R  # P and R symmetric
        else:
            PHt = P @ H.mT
            S = sym(H @ PHt + R)
        if m == 3:
            Sinv, det = inv3(S)
            good = det > 0  # False for NaN too
        else:
            good = np.isfinite(S).all((1, 2))
            Sg = S if good.all() else np.where(good[:, None, None], S, np.eye(m))
            try:
                Sinv = np.linalg.inv(Sg)
            except np.linalg.LinAlgError:
                Sinv = np.empty_like(Sg)
                for i in range(M):
                    try:
                        Sinv[i] = np.linalg.inv(Sg[i])
                    except np.linalg.LinAlgError:
                        Sinv[i] = np.eye(m)
                        good[i] = False
        if G is None:
            nis = (r[:, None, :] @ Sinv @ r[:, :, None])[:, 0, 0]
        else:
            r3 = (G @ r[:, :, None])[:, :, 0]
            S3inv, det3 = inv3(G @ S @ G.mT)
            good &= det3 > 0
            nis = (r3[:, None, :] @ S3inv @ r3[:, :, None])[:, 0, 0]
        use = valid & good
        passed = use & (nis <= self.gate_threshold)
        rejected = use & ~passed
        nis = np.where(use, nis, np.nan)
        K = PHt @ Sinv
        if not passed.all():
            K = np.where(passed[:, None, None], K, 0.0)
        dx = (K @ r[:, :, None])[:, :, 0]
        if H is None:
            IKH = np.tile(_eye(n), (M, 1, 1))
            IKH[:, :, :m] -= K
        else:
            IKH = _eye(n) - K @ H
        Pn = IKH @ P @ IKH.mT + K @ R @ K.mT
        return dx, Pn, passed, rejected, nis

    @staticmethod
    def _usable(state: FilterState, valid, bad, cov_ok):
        """``(valid, bad)`` of the trials: a present row with an unusable covariance is bad too;
        failed trials are neither."""
        bad = (bad | (valid & ~cov_ok)) & ~state.failed
        return valid & cov_ok & ~state.failed, bad

    def _absolute_inputs(self, state: FilterState, z: AbsoluteAttitudeMeasurement | None):
        """Checked rows of an absolute-attitude measurement:
        ``(z (M, 4), cov (M, 3, 3), valid (M,), bad (M,))``."""
        self._check_state(state)
        M = state.n_trials
        if _missing(z, AbsoluteAttitudeMeasurement):
            return _no_measurement(M)
        q, valid, bad = self._measurement_rows(z.q_NT, M, 4, "q_NT")
        cov, cov_ok = self._cov_rows(z.cov_rotvec_T, M, "cov_rotvec_T")
        return (q, cov, *self._usable(state, valid, bad, cov_ok))

    def _increment_inputs(self, state: FilterState, z: IncrementMeasurement | None):
        """Checked rows of a Hill-frame increment, converted to N: ``(dq_N, cov_N, valid, bad)``."""
        self._check_state(state)
        if not state.has_clone:
            raise ValueError("state: no clone; call clone(state) at the earlier epoch first")
        M = state.n_trials
        if _missing(z, IncrementMeasurement):
            return _no_measurement(M)
        dqH, valid, bad = self._measurement_rows(z.dq_H, M, 4, "dq_H")
        cov, cov_ok = self._cov_rows(z.cov_rotvec_H, M, "cov_rotvec_H")
        Rp = as_batch(z.R_NH_prev, M, (3, 3), "R_NH_prev")
        Rn = as_batch(z.R_NH_now, M, (3, 3), "R_NH_now")
        dqN, covN = self._increment_in_N(dqH, cov, Rp, Rn, z.cov_side)
        return (dqN, covN, *self._usable(state, valid, bad, cov_ok))

    @staticmethod
    def _increment_in_N(dq_H, cov_H, R_NH_prev, R_NH_now, cov_side):
        """ΔR_N = R_NH(now) ΔR_H R_NH(prev)ᵀ and the left-perturbation covariance in N."""
        q_now = quat_from_matrix(R_NH_now)
        q_prev = quat_from_matrix(R_NH_prev)
        dq_N = quaternion_products(quaternion_products(q_now, dq_H), quaternion_conjugates(q_prev))
        if cov_side == "right":
            dR = matrices_from_quaternions(dq_H)
            cov_H = dR @ cov_H @ dR.mT
        cov_N = R_NH_now @ cov_H @ R_NH_now.mT
        return dq_N, cov_N

    # ------------------------------------------------------------------ public evaluation
    def tangent_error(self, state: FilterState, q_NT_true: ArrayLike, omega_TN_T_true: ArrayLike,
                      inertia_ratios_true: ArrayLike | None = None) -> np.ndarray:
        """True error ``[a, δω, (δp)]`` of each trial, ``(M, 6 or 8)``, for NEES.

        ``a = log(q̂⁻¹ ⊗ q_true)`` (rad, T components), ``δω = ω_true − ω̂`` (rad/s),
        ``δp = p_true − p̂``.  Failed trials give NaN rows.
        """
        self._check_state(state)
        M = state.n_trials
        qt = as_batch(np.asarray(q_NT_true, dtype=float), M, (4,), "q_NT_true")
        wt = as_batch(np.asarray(omega_TN_T_true, dtype=float), M, (3,), "omega_TN_T_true")
        q, w, _, _, p = self._sanitized(state)
        a = rotvecs_from_quaternions(quaternion_products(quaternion_conjugates(q), qt))
        parts = [a, wt - w]
        if self.estimates_inertia_ratios:
            if inertia_ratios_true is None:
                raise ValueError("inertia_ratios_true: needed for the inertia-ratio filter's error")
            pt = as_batch(np.asarray(inertia_ratios_true, dtype=float), M, (2,), "inertia_ratios_true")
            parts.append(pt - p)
        e = np.concatenate(parts, -1)
        return np.where(state.failed[:, None], np.nan, e)

    @abstractmethod
    def tangent_covariance(self, state: FilterState) -> np.ndarray:
        """Covariance of the tangent error ``[a, δω, (δp)]`` of each trial, ``(M, n, n)``."""

    def nees(self, state: FilterState, q_NT_true: ArrayLike, omega_TN_T_true: ArrayLike,
             inertia_ratios_true: ArrayLike | None = None) -> np.ndarray:
        """Normalised estimation error squared of each trial, ``(M,)``, on ``n_tangent`` dof."""
        from .metrics import nees

        e = self.tangent_error(state, q_NT_true, omega_TN_T_true, inertia_ratios_true)
        return nees(e, self.tangent_covariance(state))
