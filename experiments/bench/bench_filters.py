"""Benchmark rows of the attitude filters: the batched 003 EKF against a loop of filterpy EKFs.

The peer is the same problem solved the way a filterpy user would: one
:class:`filterpy.kalman.ExtendedKalmanFilter` per trial (``predict_x`` overridden with RK4, since
filterpy's is linear only), its ``F`` set from the RK4 Jacobian each step, and the measurement
covariance from filterpy's own sigma points and :func:`filterpy.kalman.unscented_transform`.
Both run 003 Experiment B/C settings (J = diag(1000, 800, 600) kg·m², Δt = 0.1 s, ω₀ = 5°/s per
axis, 0.2° absolute-attitude noise), without gating; the note gives the largest difference
between the two estimates, which must be at rounding level.  Figures are CPU seconds of this
process (``time.process_time``, one core: batched matrix products of this size are not threaded),
so that a busy shared machine does not inflate them.
"""

from __future__ import annotations

import time

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter, MerweScaledSigmaPoints, unscented_transform

from attitude.quaternion import quat_from_rotvec, quat_multiply
from attitude.rigid_body import propagate_torque_free
from experiments.bench import BenchRow, duration_row
from filters import (
    MEKF,
    AbsoluteAttitudeMeasurement,
    AttitudeEKF,
    AttitudeFilter,
    FilterState,
    MeasurementModel,
    MeasurementSeries,
    ProcessNoise,
    draw_initial_estimates,
    simulate_measurements,
)

J_KG_M2 = np.diag([1000.0, 800.0, 600.0])
DT_S = 0.1
UT_PARAMS = {"alpha": 1.0, "beta": 2.0, "kappa": 0.0}


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _xi(q):
    q0, q1, q2, q3 = q
    return np.array([[-q1, -q2, -q3], [q0, -q3, q2], [q3, q0, -q1], [-q2, q1, q0]])


def _omega(w):
    x, y, z = w
    return np.array([[0, -x, -y, -z], [x, 0, z, -y], [y, -z, 0, x], [z, y, -x, 0.0]])


class FilterpyAttitudeEKF(ExtendedKalmanFilter):
    """One trial of the 003 additive EKF on filterpy: RK4 ``predict_x`` and its Jacobian.

    Written independently of :mod:`filters` (plain per-trial numpy, the estimation model of
    003 eqs (23)-(27)), so that agreement with :class:`filters.AttitudeEKF` checks both.
    """

    def __init__(self, J, q_psd, w_psd, dt):
        super().__init__(dim_x=7, dim_z=4)
        self.J = np.asarray(J, dtype=float)
        self.J_inv = np.linalg.inv(self.J)
        self.q_psd = q_psd
        self.w_psd = w_psd
        self.dt = dt
        self.H = np.hstack([np.eye(4), np.zeros((4, 3))])
        self.points = MerweScaledSigmaPoints(3, **UT_PARAMS)

    def _f(self, x):
        q, w = x[:4], x[4:]
        return np.r_[0.5 * _xi(q) @ w, -self.J_inv @ np.cross(w, self.J @ w)]

    def _A(self, x):
        q, w = x[:4], x[4:]
        A = np.zeros((7, 7))
        A[:4, :4] = 0.5 * _omega(w)
        A[:4, 4:] = 0.5 * _xi(q)
        A[4:, 4:] = self.J_inv @ (_skew(self.J @ w) - _skew(w) @ self.J)
        return A

    def predict_x(self, u: float = 0) -> None:
        x, h = self.x, self.dt
        k1 = self._f(x)
        A1 = self._A(x)
        x2 = x + 0.5 * h * k1
        k2 = self._f(x2)
        A2 = self._A(x2)
        x3 = x + 0.5 * h * k2
        k3 = self._f(x3)
        A3 = self._A(x3)
        x4 = x + h * k3
        k4 = self._f(x4)
        A4 = self._A(x4)
        K2 = A2 + 0.5 * h * A2 @ A1
        K3 = A3 + 0.5 * h * A3 @ K2
        K4 = A4 + h * A4 @ K3
        self.F = np.eye(7) + h / 6.0 * (A1 + 2.0 * K2 + 2.0 * K3 + K4)
        Qc = np.zeros((7, 7))
        Xi = _xi(x[:4])
        Qc[:4, :4] = 0.25 * self.q_psd * Xi @ Xi.T
        Qc[4:, 4:] = self.w_psd * np.eye(3)
        self.Q = h * Qc
        xn = x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        xn[:4] /= np.linalg.norm(xn[:4])
        self.x = xn

    def measurement_cov(self, cov_rotvec: np.ndarray) -> np.ndarray:
        """filterpy UT of ``q ⊗ exp(e/2)`` about the prediction, completed along ``q`` (isotropic)."""
        q = self.x[:4]
        sig = self.points.sigma_points(np.zeros(3), cov_rotvec)
        z = quat_multiply(q, quat_from_rotvec(sig))
        _, R = unscented_transform(z, self.points.Wm, self.points.Wc)
        R = R + np.trace(R) / 3.0 * np.outer(q, q)
        return R + 1e-12 * np.eye(4)

    def step(self, z: np.ndarray | None, cov_rotvec: np.ndarray) -> None:
        """One predict and, when ``z`` is a finite measurement, one update."""
        self.predict()
        if z is None or not np.all(np.isfinite(z)):
            return
        if z @ self.x[:4] < 0:
            z = -z
        R = self.measurement_cov(cov_rotvec)
        self.update(z, HJacobian=lambda x: self.H, Hx=lambda x: x[:4], R=R)
        self.x[:4] /= np.linalg.norm(self.x[:4])


def problem(n_trials: int, n_steps: int, *, angle_error_deg: float = 0.2, seed: int = 7
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, MeasurementSeries]:
    """003 Experiment B/C truth, eq (35) initial estimates and absolute measurements."""
    t = np.arange(n_steps + 1) * DT_S
    q, w = propagate_torque_free([1.0, 0, 0, 0], np.deg2rad([5.0, 5.0, 5.0]), J_KG_M2, t)
    rngs = np.random.default_rng(seed).spawn(n_trials)
    q0, w0 = draw_initial_estimates(q[0], w[0], sigma_q=0.1, sigma_omega_rad_s=np.deg2rad(0.1), rngs=rngs)
    meas = simulate_measurements(t, q, MeasurementModel(angle_error_deg=angle_error_deg), rngs=rngs)
    return t, q, w, q0, w0, meas


def run_batched(filt: AttitudeFilter, q0: np.ndarray, w0: np.ndarray, meas: MeasurementSeries,
                n_steps: int) -> FilterState:
    """All trials at once through one of our filters: ``n_steps`` predicts and absolute updates."""
    st = filt.initial_state(q0, w0, filt.initial_covariance())
    for k in range(1, n_steps + 1):
        st = filt.predict(st, DT_S)
        st = filt.update_absolute(st, AbsoluteAttitudeMeasurement(meas.values[:, k], meas.cov_rotvec))
    return st


def run_filterpy(q0: np.ndarray, w0: np.ndarray, meas: MeasurementSeries, n_steps: int,
                 process_noise: ProcessNoise) -> np.ndarray:
    """Trial by trial through the filterpy EKF; returns the final states ``(trials, 7)``."""
    out = np.empty((q0.shape[0], 7))
    P0 = AttitudeEKF(J_kg_m2=J_KG_M2).initial_covariance()
    for i in range(q0.shape[0]):
        f = FilterpyAttitudeEKF(J_KG_M2, process_noise.attitude_psd_rad2_s,
                                process_noise.rate_psd_rad2_s3, DT_S)
        f.x = np.r_[q0[i], w0[i]]
        f.P = P0.copy()
        for k in range(1, n_steps + 1):
            f.step(meas.values[i, k], meas.cov_rotvec[i])
        out[i] = f.x
    return out


PEER_TRIALS = 20


def _subset(meas, n):
    from dataclasses import replace

    return replace(meas, values=meas.values[:n], cov_rotvec=meas.cov_rotvec[:n])


def run(*, quick: bool) -> list[BenchRow]:
    n_trials, n_steps = (10, 100) if quick else (100, 600)
    t, q, w, q0, w0, meas = problem(n_trials, n_steps)
    pn = ProcessNoise()
    ekf = AttitudeEKF(J_kg_m2=J_KG_M2, process_noise=pn, gate_probability=None)
    mekf = MEKF(J_kg_m2=J_KG_M2, process_noise=pn, gate_probability=None)
    # CPU time of this process (best of 3): on a shared machine wall time measures the neighbours
    best_ours = np.inf
    for _ in range(3):
        t0 = time.process_time()
        st = run_batched(ekf, q0, w0, meas, n_steps)
        best_ours = min(best_ours, time.process_time() - t0)
    best_mekf = np.inf
    for _ in range(3):
        t0 = time.process_time()
        run_batched(mekf, q0, w0, meas, n_steps)
        best_mekf = min(best_mekf, time.process_time() - t0)
    # the peer is a plain loop over trials (cost linear in their number): time a subset and scale
    n_peer = min(n_trials, PEER_TRIALS)
    t0 = time.process_time()
    x_peer = run_filterpy(q0[:n_peer], w0[:n_peer], _subset(meas, n_peer), n_steps, pn)
    peer_s = (time.process_time() - t0) * n_trials / n_peer
    x_ours = np.c_[st.q_NT, st.omega_TN_T][:n_peer]
    diff = float(np.abs(x_ours - x_peer).max())
    size = f"{n_trials} trials × {n_steps} steps"
    scaled = "" if n_peer == n_trials else f"; peer timed on {n_peer} trials × {n_trials // n_peer}"
    return [
        duration_row(f"AttitudeEKF (003 7-state, batched), {size}", best_ours, peer_s,
                     "filterpy ExtendedKalmanFilter loop",
                     note=f"CPU s; target < 0.5 s (100×600); max |x − x_filterpy| = {diff:.1e}{scaled}"),
        BenchRow(f"MEKF (batched), {size}", best_mekf, "s",
                 note="CPU s; same problem, multiplicative error state"),
    ]
