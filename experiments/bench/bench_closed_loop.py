"""Benchmark rows of the closed loop: the target model and the gtsam smoother beside today's EKF path.

* One whole closed-loop run (the 003 convergence-map cell at 50 m / 10°, 3 views, geometric mode,
  60 s at 2 Hz, the same seed): ``map`` + ``smoother`` (known inertia, as the EKF has it) beside
  ``ml`` + ``ekf``.  The issue's target: the model and the smoother add at most 50 % (ratio ≥ 0.67).
* The estimator's own time per epoch on the same synthetic increments (truth with a non-diagonal
  inertia, 0.3° registration noise, one increment per epoch and a closure to 40 s back every 4th):
  iSAM2's update (dynamics factor, gate, relative rotations, marginals) beside the EKF's predict
  and stochastic-cloning update.

Figures are CPU seconds of this process (``time.process_time``) so that a busy machine does not
inflate them.
"""

from __future__ import annotations

import time

import numpy as np

from attitude.quaternion import matrix_from_quat, quat_from_matrix, quat_from_rotvec, quat_multiply
from attitude.rigid_body import propagate_torque_free
from closed_loop.smoother import AttitudeSmoother, SmootherSettings
from experiments.bench import BenchRow, duration_row
from filters import AttitudeEKF, IncrementMeasurement

__all__ = ["run"]

J_TRUE_KG_M2 = np.array([[1000.0, 50.0, -30.0], [50.0, 800.0, 20.0], [-30.0, 20.0, 600.0]])


def _cpu(fn) -> float:
    t0 = time.process_time()
    fn()
    return time.process_time() - t0


def _whole_run(quick: bool) -> BenchRow:
    from experiments.bundled import bundled_config_path
    from experiments.config import load_config
    from experiments.scenarios.formation.closed_loop import closed_loop
    from experiments.sweep import child_seeds

    path = bundled_config_path("003_convergence_closed_loop.toml")
    over = {"time.duration_s": 20.0 if quick else 60.0}
    _, smooth = load_config(path, {**over, "estimator.registration": "map", "estimator.filter": "smoother",
                                   "estimator.estimate_inertia": False})
    _, ekf = load_config(path, {**over, "estimator.registration": "ml", "estimator.filter": "ekf"})
    seed = child_seeds(np.random.SeedSequence(2021), 1)[0]
    closed_loop(ekf, seed, snapshot=False)  # warm the caches (surface features, Numba)
    t_ekf = _cpu(lambda: closed_loop(ekf, seed, snapshot=False))
    t_sm = _cpu(lambda: closed_loop(smooth, seed, snapshot=False))
    return duration_row(f"closed-loop run, {over['time.duration_s']:.0f} s at 2 Hz, 3 views: map + smoother",
                        t_sm, t_ekf, "ml + ekf (today's path)",
                        "target: ratio >= 0.67 (the model and the smoother add at most 50 %)")


def _increments(T: int, rng: np.random.Generator):
    t = 0.5 * np.arange(T)
    q, w = propagate_torque_free(np.array([1.0, 0.0, 0.0, 0.0]), np.deg2rad([5.0, 5.0, 5.0]), J_TRUE_KG_M2, t)
    R = matrix_from_quat(q)
    sig = np.deg2rad(0.3)
    noise = rng.normal(size=(T, 3)) * sig
    return t, q, w, R, noise, sig


def _per_epoch(quick: bool) -> BenchRow:
    T = 60 if quick else 240
    t, q, w, R, noise, sig = _increments(T, np.random.default_rng(0))
    C = np.eye(3) * sig ** 2

    def smoother() -> None:
        sm = AttitudeSmoother(J_prior_kg_m2=J_TRUE_KG_M2, settings=SmootherSettings(estimate_inertia=False))
        sm.start(0.0, R[0], np.eye(3) * 1e-8, w[0], np.eye(3) * 1e-6)
        for k in range(1, T):
            sm.add_epoch(t[k])
            for j in [k - 1] + ([k - 80] if k >= 80 and k % 4 == 0 else []):
                meas = matrix_from_quat(quat_from_rotvec(noise[k])) @ R[k] @ R[j].T
                if sm.gate(j, k, meas, C).accepted:
                    sm.add_relative(j, k, meas, C)
            sm.update()
            sm.covariance_T(k)

    def ekf() -> None:
        f = AttitudeEKF(J_kg_m2=J_TRUE_KG_M2)
        s = f.initial_state(q[0], w[0], f.initial_covariance(sigma_q=1e-4, sigma_omega_rad_s=1e-3), t_s=0.0)
        s = f.clone(s)
        for k in range(1, T):
            s = f.predict(s, t[k] - t[k - 1])
            dq = quat_multiply(quat_from_rotvec(noise[k]), quat_from_matrix(R[k] @ R[k - 1].T))
            z = IncrementMeasurement(dq_H=dq[None], cov_rotvec_H=C[None], R_NH_prev=np.eye(3), R_NH_now=np.eye(3),
                                     cov_side="left")
            s = f.update_increment(s, z)
            f.tangent_covariance(s)

    t_sm = _cpu(smoother) / (T - 1)
    t_ekf = _cpu(ekf) / (T - 1)
    return duration_row(f"estimator update per epoch ({T} epochs, increments + closures): iSAM2", t_sm, t_ekf,
                        "EKF predict + increment update (no closures)",
                        "the smoother also takes a closure every 4th epoch, gates and computes marginals")


def run(*, quick: bool = False) -> list[BenchRow]:
    """The two rows of the module docstring."""
    return [_per_epoch(quick), _whole_run(quick)]
