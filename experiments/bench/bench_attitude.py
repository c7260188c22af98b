"""Attitude benchmarks: batched quaternion products against scipy, torque-free propagation throughput."""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from attitude.quaternion import quat_angle_between, quat_derivative, quat_from_scipy, quat_multiply
from attitude.rigid_body import propagate_torque_free
from experiments.bench import BenchRow, best_time, throughput_row


def run(*, quick: bool = False) -> list[BenchRow]:
    rows: list[BenchRow] = []
    n = 100_000 if quick else 1_000_000
    r1 = Rotation.random(n, random_state=1)
    r2 = Rotation.random(n, random_state=2)
    q1 = quat_from_scipy(r1.as_quat())
    q2 = quat_from_scipy(r2.as_quat())
    ours = best_time(lambda: quat_multiply(q1, q2))
    peer = best_time(lambda: r1 * r2)
    check = quat_angle_between(quat_multiply(q1, q2), quat_from_scipy((r1 * r2).as_quat())).max()
    rows.append(throughput_row(f"quaternion product, batch of {n:.0e}", ours, peer, n, "products/s",
                               "scipy Rotation composition",
                               note=f"max difference {np.rad2deg(check):.1e} deg"))

    # torque-free propagation: B bodies × T output epochs, against DOP853 (rtol = atol = 1e-12)
    B, T = (10, 301) if quick else (100, 601)
    rng = np.random.default_rng(0)
    J = np.diag([100.0, 120.0, 80.0])
    w0 = np.deg2rad(rng.uniform(-10, 10, size=(B, 3)))
    q0 = quat_from_scipy(Rotation.random(B, random_state=3).as_quat())
    t = np.linspace(0.0, 300.0, T)
    ours = best_time(lambda: propagate_torque_free(q0, w0, J, t), repeat=3)
    Jinv = np.linalg.inv(J)

    def f(_, x):
        return np.concatenate([quat_derivative(x[:4], x[4:]), -Jinv @ np.cross(x[4:], J @ x[4:])])

    def dop853(n_bodies):
        return np.array([solve_ivp(f, (0, t[-1]), np.concatenate([q0[b], w0[b]]), method="DOP853",
                                   rtol=1e-12, atol=1e-12, t_eval=t).y[:4].T for b in range(n_bodies)])

    n_peer = min(B, 10)  # the peer is timed on 10 bodies and scaled: it is linear in the body count
    peer = best_time(lambda: dop853(n_peer), repeat=1) * (B / n_peer)
    q_ours, _ = propagate_torque_free(q0[:n_peer], w0[:n_peer], J, t)
    err = np.rad2deg(quat_angle_between(q_ours, dop853(n_peer))).max()
    rows.append(throughput_row(f"torque-free propagation, {B} bodies x {T} epochs over 300 s", ours, peer,
                               B * T, "body-epochs/s", "scipy DOP853 (rtol=atol=1e-12)",
                               note=f"exact (elliptic); max difference {err:.1e} deg"))
    return rows
