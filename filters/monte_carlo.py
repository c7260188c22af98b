"""Batched Monte Carlo of the attitude filters: M trials advance together, one random stream each.

The truth (attitude and rate histories) is given by the caller, normally from
:func:`attitude.rigid_body.propagate_torque_free`.  For every trial an independent generator is
spawned from ``rng`` (``SeedSequence.spawn``), so trial ``i`` draws the same numbers whatever the
number of trials; it draws, in this order, the initial estimate (003 eq 35), then its
measurements (noise, missing-observer gaps, gross outliers).  All M filters then run in one
vectorised loop over epochs.

Measurement kinds (:class:`MeasurementModel`):

* ``"absolute"``  — the paper's simulation (003 Experiments B–D): ``z_k = q_NT(t_k) ⊗ exp(e/2)``;
* ``"increment"`` — the paper's pipeline: the registration increment between consecutive
  epochs in the rotating Hill frame, ``ΔR_H = exp([v×]) R_HT(t_k) R_HT(t_{k−1})ᵀ``, processed with
  stochastic cloning;
* ``"chained_absolute"`` — increments chained into an absolute attitude, ``z_k = Δq_N ⊗ z_{k−1}``,
  fed to the filter as if independent with constant covariance: the naive treatment of flag
  P003-14a (docs/papers.md#p003-14a), kept to show why cloning is needed (its error grows like a
  random walk).

``e`` and ``v`` are isotropic with σ_axis = angle_error/√3 (the quoted angle error is the 2-norm
of the three axes, :func:`filters.noise_mapping.rotvec_covariance_from_angle_error`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from attitude.matrix import rot_z
from attitude.quaternion import (
    quat_conjugate,
    quat_from_matrix,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    rotvec_from_quat,
)

from ._base import AttitudeFilter
from .measurements import AbsoluteAttitudeMeasurement, IncrementMeasurement
from .metrics import (
    ConvergenceCriterion,
    attitude_error_angle,
    convergence_time,
    euler_angle_error,
    nees,
    nees_band,
    rate_error,
    speed_score,
)
from .noise_mapping import rotvec_covariance_from_angle_error

__all__ = [
    "MeasurementModel",
    "MeasurementSeries",
    "MonteCarloResult",
    "draw_initial_estimates",
    "simulate_measurements",
    "hill_frame_rotation",
    "run_monte_carlo",
]


@dataclass(frozen=True)
class MeasurementModel:
    """Synthetic measurement stream of a Monte Carlo.

    Attributes
    ----------
    kind : {"absolute", "increment", "chained_absolute"}
    angle_error_deg : float
        Attitude-angle error ``e`` (2-norm over three axes, deg) of one measurement; the filter is
        told the matching covariance ``e²/3 I`` (rad²).
    angle_error_range_deg : (float, float) or None
        If given, each trial draws its ``e`` uniformly from this range (003 Experiment D) and
        ``angle_error_deg`` is ignored.
    missing_fraction : float
        Fraction of the run during which the observers are lost (no measurement), in gaps of
        ``gap_s`` seconds (the last one shorter if needed) placed at random without overlap.
    gap_s : float
        Length of each gap (s).
    outlier_fraction : float
        Fraction of the available measurements replaced by gross outliers.
    outlier_angle_deg : (float, float)
        An outlier's error is a rotation about a random axis by an angle uniform in this range.
    orbit_rate_rad_s : float
        Rate n of the Hill frame about N's z axis: ``R_NH(t) = R_z(n t)`` (increments only).
    """

    kind: Literal["absolute", "increment", "chained_absolute"] = "absolute"
    angle_error_deg: float = 0.2
    angle_error_range_deg: tuple[float, float] | None = None
    missing_fraction: float = 0.0
    gap_s: float = 5.0
    outlier_fraction: float = 0.0
    outlier_angle_deg: tuple[float, float] = (10.0, 180.0)
    orbit_rate_rad_s: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in ("absolute", "increment", "chained_absolute"):
            raise ValueError(f"kind: expected 'absolute', 'increment' or 'chained_absolute', got {self.kind!r}")
        if not np.isfinite(self.angle_error_deg) or self.angle_error_deg < 0:
            raise ValueError(f"angle_error_deg: must be finite and >= 0, got {self.angle_error_deg!r}")
        if self.angle_error_range_deg is not None:
            lo, hi = self.angle_error_range_deg
            if not (0 <= lo <= hi) or not np.isfinite(hi):
                raise ValueError(f"angle_error_range_deg: need 0 <= lo <= hi, got {self.angle_error_range_deg!r}")
        for name in ("missing_fraction", "outlier_fraction"):
            v = getattr(self, name)
            if not (0.0 <= v < 1.0):
                raise ValueError(f"{name}: must be in [0, 1), got {v!r}")
        if not np.isfinite(self.gap_s) or self.gap_s <= 0:
            raise ValueError(f"gap_s: must be finite and > 0, got {self.gap_s!r}")
        lo, hi = self.outlier_angle_deg
        if not (0 < lo <= hi <= 180):
            raise ValueError(f"outlier_angle_deg: need 0 < lo <= hi <= 180, got {self.outlier_angle_deg!r}")
        if not np.isfinite(self.orbit_rate_rad_s):
            raise ValueError(f"orbit_rate_rad_s: must be finite, got {self.orbit_rate_rad_s!r}")
        if self.kind == "chained_absolute" and self.missing_fraction > 0:
            raise ValueError("missing_fraction: a chained absolute attitude cannot bridge gaps; use 0")


@dataclass(frozen=True)
class MeasurementSeries:
    """Measurements of M trials over T epochs (epoch 0 carries none).

    Attributes
    ----------
    kind : str
    t_s : (T,) array
    values : (M, T, 4) array
        ``q_NT`` measurements (absolute kinds) or ``Δq_H`` increments from epoch k−1 to k;
        NaN rows where missing.
    cov_rotvec : (M, 3, 3) array
        Rotation-vector covariance the filter is given (rad²; body frame for absolute
        measurements, H frame left-perturbation for increments).
    R_NH : (T, 3, 3) array
        Hill frame at each epoch.
    available : (M, T) bool array
        A measurement exists (not in a gap).
    outlier : (M, T) bool array
        The measurement is a gross outlier.
    angle_error_rad : (M,) array
        The attitude-angle error of each trial.
    """

    kind: str
    t_s: np.ndarray
    values: np.ndarray
    cov_rotvec: np.ndarray
    R_NH: np.ndarray
    available: np.ndarray
    outlier: np.ndarray
    angle_error_rad: np.ndarray


def hill_frame_rotation(t_s: ArrayLike, orbit_rate_rad_s: float) -> np.ndarray:
    """``R_NH(t) = R_z(n t)``: a Hill frame turning at the orbit rate about N's z axis, ``(T, 3, 3)``."""
    return rot_z(float(orbit_rate_rad_s) * np.asarray(t_s, dtype=float))


def _trial_generators(rng, n_trials: int) -> list[np.random.Generator]:
    return np.random.default_rng(rng).spawn(n_trials)


def _check_truth(t_s, q_NT_true, omega_TN_T_true, n_trials):
    t = np.asarray(t_s, dtype=float)
    if t.ndim != 1 or t.size < 2 or not np.all(np.diff(t) > 0):
        raise ValueError(f"t_s: need an increasing (T,) array with T >= 2, got shape {t.shape}")
    T = t.size
    q = np.asarray(q_NT_true, dtype=float)
    w = np.asarray(omega_TN_T_true, dtype=float)
    if q.shape == (T, 4):
        q = np.broadcast_to(q, (n_trials, T, 4))
    if w.shape == (T, 3):
        w = np.broadcast_to(w, (n_trials, T, 3))
    if q.shape != (n_trials, T, 4):
        raise ValueError(f"q_NT_true: expected ({T}, 4) or ({n_trials}, {T}, 4), got {np.shape(q_NT_true)}")
    if w.shape != (n_trials, T, 3):
        raise ValueError(f"omega_TN_T_true: expected ({T}, 3) or ({n_trials}, {T}, 3), got {np.shape(omega_TN_T_true)}")
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(w))):
        raise ValueError("q_NT_true/omega_TN_T_true: contain non-finite values")
    return t, q, w


def draw_initial_estimates(q_NT0: ArrayLike, omega_TN_T0: ArrayLike, *, sigma_q: float,
                           sigma_omega_rad_s: float, rngs: list[np.random.Generator]
                           ) -> tuple[np.ndarray, np.ndarray]:
    """003 eq (35): ``x̂₀ ~ N(x₀, diag(σ_q² I₄, σ_ω² I₃))``, quaternion renormalised (flag P003-13, docs/papers.md#p003-13).

    ``q_NT0 (4,)|(M, 4)``, ``omega_TN_T0 (3,)|(M, 3)``; one generator per trial; returns
    ``(q̂₀ (M, 4), ω̂₀ (M, 3))``.
    """
    M = len(rngs)
    q0 = np.broadcast_to(np.asarray(q_NT0, dtype=float), (M, 4))
    w0 = np.broadcast_to(np.asarray(omega_TN_T0, dtype=float), (M, 3))
    dq = np.empty((M, 4))
    dw = np.empty((M, 3))
    for i, g in enumerate(rngs):
        dq[i] = g.normal(size=4) * sigma_q
        dw[i] = g.normal(size=3) * sigma_omega_rad_s
    return quat_normalize(q0 + dq), w0 + dw


def _gap_mask(t: np.ndarray, fraction: float, gap_s: float, g: np.random.Generator) -> np.ndarray:
    """(T,) bool: True where observers are lost.

    The lost time ``fraction × duration`` is cut into gaps of ``gap_s`` (the last one shorter if
    needed), placed in random order at random non-overlapping positions.
    """
    T = t.size
    lost = np.zeros(T, dtype=bool)
    if fraction <= 0:
        return lost
    duration = t[-1] - t[0]
    total = fraction * duration
    n_full = int(np.floor(total / gap_s + 1e-9))
    lengths = [gap_s] * n_full
    rest = total - n_full * gap_s
    if rest > 1e-9:
        lengths.append(rest)
    lengths = np.asarray(lengths)[g.permutation(len(lengths))]
    free = duration - lengths.sum()
    u = np.sort(g.uniform(0.0, free, size=lengths.size))
    starts = u + np.concatenate([[0.0], np.cumsum(lengths)[:-1]]) + t[0]
    for s, length in zip(starts, lengths, strict=True):
        lost |= (t >= s) & (t < s + length)
    return lost


def _random_rotvec(g: np.random.Generator, n: int, lo_deg: float, hi_deg: float) -> np.ndarray:
    axis = g.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return axis * np.deg2rad(g.uniform(lo_deg, hi_deg, size=n))[:, None]


def simulate_measurements(t_s: ArrayLike, q_NT_true: ArrayLike, model: MeasurementModel, *,
                          rngs: list[np.random.Generator]) -> MeasurementSeries:
    """Draw the measurements of every trial (one generator per trial); see :class:`MeasurementModel`.

    ``q_NT_true`` is ``(T, 4)`` or ``(M, T, 4)`` with ``M = len(rngs)``.
    """
    if not isinstance(model, MeasurementModel):
        raise ValueError(f"model: expected a MeasurementModel, got {type(model).__name__}")
    M = len(rngs)
    t = np.asarray(t_s, dtype=float)
    T = t.size
    q = np.asarray(q_NT_true, dtype=float)
    if q.shape == (T, 4):
        q = np.broadcast_to(q, (M, T, 4))
    if q.shape != (M, T, 4):
        raise ValueError(f"q_NT_true: expected ({T}, 4) or ({M}, {T}, 4), got {q.shape}")
    R_NH = hill_frame_rotation(t, model.orbit_rate_rad_s if model.kind == "increment" else 0.0)
    q_NH = quat_from_matrix(R_NH)
    values = np.full((M, T, 4), np.nan)
    available = np.zeros((M, T), dtype=bool)
    outlier = np.zeros((M, T), dtype=bool)
    e_rad = np.empty(M)
    for i, g in enumerate(rngs):
        if model.angle_error_range_deg is not None:
            e_rad[i] = np.deg2rad(g.uniform(*model.angle_error_range_deg))
        else:
            e_rad[i] = np.deg2rad(model.angle_error_deg)
        sigma_axis = e_rad[i] / np.sqrt(3.0)
        noise = g.normal(size=(T, 3)) * sigma_axis
        lost = _gap_mask(t, model.missing_fraction, model.gap_s, g)
        if model.kind == "increment":
            avail = ~lost & ~np.r_[True, lost[:-1]]  # both clouds of the pair exist
        else:
            avail = ~lost
        avail[0] = False
        out = avail & (g.uniform(size=T) < model.outlier_fraction)
        noise[out] = _random_rotvec(g, int(out.sum()), *model.outlier_angle_deg)
        dnoise = quat_from_rotvec(noise)
        qi = q[i]
        if model.kind == "absolute":
            z = quat_multiply(qi, dnoise)
        else:
            q_HT = quat_multiply(quat_conjugate(q_NH), qi)
            dq_H = quat_multiply(q_HT[1:], quat_conjugate(q_HT[:-1]))
            dq_H = quat_multiply(dnoise[1:], dq_H)  # left perturbation in H
            if model.kind == "increment":
                z = np.concatenate([np.full((1, 4), np.nan), dq_H])
            else:  # chained_absolute: z_k = Δq_N ⊗ z_{k-1}, z_0 = q(t_0) (defines the body frame)
                dq_N = quat_multiply(quat_multiply(q_NH[1:], dq_H), quat_conjugate(q_NH[:-1]))
                z = np.empty((T, 4))
                z[0] = qi[0]
                for k in range(1, T):
                    z[k] = quat_multiply(dq_N[k - 1], z[k - 1])
                z = quat_normalize(z)
        values[i] = np.where(avail[:, None], z, np.nan)
        available[i] = avail
        outlier[i] = out
    cov = rotvec_covariance_from_angle_error(e_rad)
    return MeasurementSeries(kind=model.kind, t_s=t, values=values, cov_rotvec=cov, R_NH=R_NH,
                             available=available, outlier=outlier, angle_error_rad=e_rad)


@dataclass(frozen=True)
class MonteCarloResult:
    """Histories and summary figures of a batched Monte Carlo (M trials × T epochs).

    Attributes
    ----------
    t_s : (T,) array
    q_NT_est : (M, T, 4) array
    omega_TN_T_est : (M, T, 3) array
        rad/s.
    inertia_ratios_est : (M, T, 2) array or None
    attitude_error_rad : (M, T) array
        Rotation-angle error.
    euler_error_rad : (M, T) array
        003 eq (36) on 3-2-1 Euler angles.
    rate_error_rad_s : (M, T) array
        003 eq (37).
    speed_score : (M, T) array
        Kelvins/SPEED orientation score of each estimate (rad).
    nees : (M, T) array
        On ``nees_dof`` degrees of freedom ``[a, δω, (δp)]``.
    nees_dof : int
    sigma_tangent : (M, T, nees_dof) array
        Filter standard deviations of the tangent error.
    converged : (M,) bool array
    convergence_time_s : (M,) array
        NaN where not converged.
    n_accepted, n_rejected : (M,) int arrays
    n_outliers : (M,) int array
        Outliers injected.
    n_resets : (M,) int array
        Covariance resets after consecutive rejections (see ``FilterState.n_resets``).
    failed : (M,) bool array
        Trials whose filter failed (:attr:`ok` is the negation).
    failure_reason : (M,) str array
        Empty for the trials that did not fail.
    criterion : ConvergenceCriterion
    measurements : MeasurementSeries
    """

    t_s: np.ndarray
    q_NT_est: np.ndarray
    omega_TN_T_est: np.ndarray
    inertia_ratios_est: np.ndarray | None
    attitude_error_rad: np.ndarray
    euler_error_rad: np.ndarray
    rate_error_rad_s: np.ndarray
    speed_score: np.ndarray
    nees: np.ndarray
    nees_dof: int
    sigma_tangent: np.ndarray
    converged: np.ndarray
    convergence_time_s: np.ndarray
    n_accepted: np.ndarray
    n_rejected: np.ndarray
    n_outliers: np.ndarray
    n_resets: np.ndarray
    failed: np.ndarray
    failure_reason: np.ndarray
    criterion: ConvergenceCriterion
    measurements: MeasurementSeries = field(repr=False)

    @property
    def n_trials(self) -> int:
        """Number ``M`` of trials."""
        return self.q_NT_est.shape[0]

    @property
    def ok(self) -> np.ndarray:
        """``(M,)`` bool: trials whose filter did not fail (``failure_reason`` empty)."""
        return ~self.failed

    @property
    def fraction_converged(self) -> float:
        return float(np.mean(self.converged))

    @property
    def median_convergence_time_s(self) -> float:
        """Median over the converged runs (NaN if none converged)."""
        c = self.convergence_time_s[self.converged]
        return float(np.median(c)) if c.size else float("nan")

    def mean_nees(self) -> np.ndarray:
        """Average NEES over the non-failed trials at each epoch, ``(T,)``."""
        ok = ~self.failed
        return np.mean(self.nees[ok], axis=0) if ok.any() else np.full(self.t_s.size, np.nan)

    def nees_band(self, probability: float = 0.95) -> tuple[float, float]:
        return nees_band(self.nees_dof, int(np.sum(~self.failed)), probability=probability)

    def nees_inside_fraction(self, *, after_s: float = 0.0, probability: float = 0.95) -> float:
        """Fraction of epochs with ``t ≥ after_s`` whose average NEES lies in the band."""
        lo, hi = self.nees_band(probability)
        m = self.mean_nees()[self.t_s - self.t_s[0] >= after_s]
        return float(np.mean((m >= lo) & (m <= hi)))

    def summary(self, *, nees_after_s: float = 5.0) -> dict:
        """Headline figures (degrees at the edge, as the names say)."""
        fin = ~self.failed
        lo, hi = self.nees_band()
        return {
            "n_trials": self.n_trials,
            "fraction_converged": self.fraction_converged,
            "median_convergence_time_s": self.median_convergence_time_s,
            "final_rms_attitude_error_deg": float(np.rad2deg(np.sqrt(np.nanmean(
                self.attitude_error_rad[fin, -100:] ** 2)))) if fin.any() else float("nan"),
            "final_rms_rate_error_deg_s": float(np.rad2deg(np.sqrt(np.nanmean(
                self.rate_error_rad_s[fin, -100:] ** 2)))) if fin.any() else float("nan"),
            "mean_nees_after": float(np.mean(self.mean_nees()[self.t_s - self.t_s[0] >= nees_after_s])),
            "nees_dof": self.nees_dof,
            "nees_band_95": (lo, hi),
            "nees_inside_fraction": self.nees_inside_fraction(after_s=nees_after_s),
            "n_rejected": int(self.n_rejected.sum()),
            "n_outliers": int(self.n_outliers.sum()),
            "n_resets": int(self.n_resets.sum()),
            "n_failed": int(self.failed.sum()),
            "criterion": {"attitude_deg": self.criterion.attitude_deg,
                          "rate_deg_s": self.criterion.rate_deg_s,
                          "hold_s": self.criterion.hold_s,
                          "attitude_metric": self.criterion.attitude_metric},
        }


def run_monte_carlo(
    estimator: AttitudeFilter,
    *,
    t_s: ArrayLike,
    q_NT_true: ArrayLike,
    omega_TN_T_true: ArrayLike,
    measurement: MeasurementModel = MeasurementModel(),
    n_trials: int = 100,
    sigma_q: float = 0.1,
    sigma_omega_rad_s: float = float(np.deg2rad(0.1)),
    inertia_ratios_true: ArrayLike | None = None,
    initial_inertia_ratios: ArrayLike | None = None,
    sigma_inertia_ratio: float | ArrayLike | None = None,
    criterion: ConvergenceCriterion = ConvergenceCriterion(),
    rng: np.random.Generator | int | None = None,
) -> MonteCarloResult:
    """Run ``n_trials`` filters at once on the same truth (or one truth per trial).

    Parameters
    ----------
    estimator : AttitudeEKF or MEKF
        The filter (model); its ``initial_covariance`` gives P0 matching eq (35).
    t_s : (T,) array
        Epochs (s); measurements at ``t_s[1:]``.
    q_NT_true : (T, 4) or (M, T, 4) array
    omega_TN_T_true : (T, 3) or (M, T, 3) array
        rad/s, T components.
    measurement : MeasurementModel
    n_trials : int
    sigma_q, sigma_omega_rad_s : float
        003 eq (35) sampling of the initial estimate: σ per quaternion component, and rad/s.
    inertia_ratios_true : (2,) array, optional
        True (J_yy/J_xx, J_zz/J_xx) (inertia-ratio MEKF: for its NEES).
    initial_inertia_ratios : (2,) or (M, 2) array, optional
        Initial ratio estimates (default: those of the filter's ``J_kg_m2``).
    sigma_inertia_ratio : float or (2,), optional
        Initial ratio standard deviation (default 30 % of the initial ratios).
    criterion : ConvergenceCriterion
    rng : Generator, int or None
        Parent of the per-trial generators.
    """
    if not isinstance(estimator, AttitudeFilter):
        raise ValueError(f"estimator: expected an AttitudeEKF or MEKF, got {type(estimator).__name__}")
    if int(n_trials) != n_trials or n_trials < 1:
        raise ValueError(f"n_trials: must be a positive integer, got {n_trials!r}")
    M = int(n_trials)
    t, q_true, w_true = _check_truth(t_s, q_NT_true, omega_TN_T_true, M)
    T = t.size
    ratios = estimator.estimates_inertia_ratios
    if ratios and inertia_ratios_true is None:
        raise ValueError("inertia_ratios_true: needed to evaluate the inertia-ratio filter")
    if not ratios and initial_inertia_ratios is not None:
        raise ValueError("initial_inertia_ratios: this estimator has no inertia-ratio state")
    rngs = _trial_generators(rng, M)
    q0, w0 = draw_initial_estimates(q_true[:, 0], w_true[:, 0], sigma_q=sigma_q,
                                    sigma_omega_rad_s=sigma_omega_rad_s, rngs=rngs)
    meas = simulate_measurements(t, q_true, measurement, rngs=rngs)
    if ratios:
        p0 = np.broadcast_to(np.asarray(estimator.default_inertia_ratios if initial_inertia_ratios is None
                                        else initial_inertia_ratios, dtype=float), (M, 2))
        s = 0.3 * np.abs(p0[0]) if sigma_inertia_ratio is None else sigma_inertia_ratio
        P0 = estimator.initial_covariance(sigma_q=sigma_q, sigma_omega_rad_s=sigma_omega_rad_s,
                                          sigma_inertia_ratio=s)
        state = estimator.initial_state(q0, w0, P0, t_s=t[0], inertia_ratios=p0)
    else:
        P0 = estimator.initial_covariance(sigma_q=sigma_q, sigma_omega_rad_s=sigma_omega_rad_s)
        state = estimator.initial_state(q0, w0, P0, t_s=t[0])
    increments = meas.kind == "increment"
    if increments:
        state = estimator.clone(state)
    d = estimator.n_tangent
    q_est = np.empty((M, T, 4))
    w_est = np.empty((M, T, 3))
    p_est = np.empty((M, T, 2)) if ratios else None
    cov_t = np.empty((M, T, d, d))

    def record(k, st):
        q_est[:, k] = st.q_NT
        w_est[:, k] = st.omega_TN_T
        if ratios:
            p_est[:, k] = st.inertia_ratios
        cov_t[:, k] = estimator.tangent_covariance(st)

    record(0, state)
    for k in range(1, T):
        state = estimator.predict(state, t[k] - t[k - 1])
        if increments:
            state = estimator.update_increment(state, IncrementMeasurement(
                dq_H=meas.values[:, k], cov_rotvec_H=meas.cov_rotvec,
                R_NH_prev=meas.R_NH[k - 1], R_NH_now=meas.R_NH[k]))
        else:
            state = estimator.update_absolute(state, AbsoluteAttitudeMeasurement(
                q_NT=meas.values[:, k], cov_rotvec_T=meas.cov_rotvec))
        record(k, state)

    ea = attitude_error_angle(q_est, q_true)
    ee = euler_angle_error(q_est, q_true)
    er = rate_error(w_est, w_true)
    conv, tc = convergence_time(t, ea if criterion.attitude_metric == "angle" else ee, er,
                                criterion=criterion)
    bad = ~np.all(np.isfinite(q_est), -1)
    qs = np.where(bad[..., None], np.array([1.0, 0, 0, 0]), q_est)
    a = rotvec_from_quat(quat_multiply(quat_conjugate(qs), q_true))
    err = [a, w_true - w_est]
    if ratios:
        err.append(np.asarray(inertia_ratios_true, dtype=float) - p_est)
    err = np.concatenate(err, -1)
    err = np.where(bad[..., None], np.nan, err)
    diag = np.diagonal(cov_t, axis1=-2, axis2=-1)
    sigma = np.sqrt(np.where(diag >= 0, diag, np.nan))
    return MonteCarloResult(
        t_s=t, q_NT_est=q_est, omega_TN_T_est=w_est, inertia_ratios_est=p_est,
        attitude_error_rad=ea, euler_error_rad=ee, rate_error_rad_s=er,
        speed_score=speed_score(q_est, q_true), nees=nees(err, cov_t), nees_dof=d,
        sigma_tangent=sigma, converged=conv & ~state.failed, convergence_time_s=np.where(
            state.failed, np.nan, tc),
        n_accepted=state.n_accepted.copy(), n_rejected=state.n_rejected.copy(),
        n_outliers=meas.outlier.sum(axis=1), n_resets=state.n_resets.copy(), failed=state.failed.copy(),
        failure_reason=state.failure_reason.copy(), criterion=criterion, measurements=meas,
    )
