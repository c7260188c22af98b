"""Orbit benchmarks: CW and Kepler propagation throughput against scipy's solve_ivp.

The figures are spacecraft-epochs per second (one relative or inertial state delivered at one
output epoch).  Each measurement runs in a child process with OpenBLAS/OpenMP limited to one
thread, so "one core" is literal; the peer integrates the same initial states to the same output
epochs with DOP853.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np

from experiments.bench import BenchRow, best_time, throughput_row

A_M = 6721.2e3


def _sizes(quick: bool) -> dict:
    return {"n_cw": 500 if quick else 4000, "t_cw": 601 if quick else 1201,
            "n_cw_peer": 50 if quick else 200, "n_kep": 50 if quick else 400,
            "t_kep": 301 if quick else 1201, "n_kep_peer": 5 if quick else 10}


def _measure(quick: bool) -> dict:
    """All timings, in this process (called in the single-threaded child)."""
    from scipy.integrate import solve_ivp

    from orbits import cw
    from orbits.two_body import MU_EARTH_M3_S2, propagate_kepler, state_from_elements

    s = _sizes(quick)
    rng = np.random.default_rng(0)
    n = float(cw.mean_motion(A_M))
    period = 2 * np.pi / n
    out: dict = {"sizes": s}

    # --- CW: bounded and drifting relative states, 1–500 m, two orbits.
    x0 = rng.normal(0.0, 1.0, (s["n_cw"], 6)) * np.array([100, 100, 100, 0.1, 0.1, 0.1])
    t = np.linspace(0.0, 2 * period, s["t_cw"])
    out["cw_ours_s"] = best_time(lambda: cw.propagate(x0, t, n), repeat=5)
    A = cw.system_matrix(n)
    k = s["n_cw_peer"]

    def peer_cw():
        def f(_, y):
            return (y.reshape(k, 6) @ A.T).ravel()
        return solve_ivp(f, (0.0, t[-1]), x0[:k].ravel(), t_eval=t, method="DOP853",
                         rtol=1e-10, atol=1e-9)

    out["cw_peer_s"] = best_time(peer_cw, repeat=1) * (s["n_cw"] / k)
    sol = peer_cw()
    x_peer = sol.y.reshape(k, 6, -1).transpose(0, 2, 1)
    out["cw_maxdiff_m"] = float(np.abs(cw.propagate(x0[:k], t, n)[..., :3] - x_peer[..., :3]).max())

    # --- Kepler: LEO to GEO, e up to 0.7, two periods of the 6721.2 km orbit.
    m = s["n_kep"]
    r0, v0 = state_from_elements(rng.uniform(6.7e6, 4.2e7, m), rng.uniform(0, 0.7, m),
                                 rng.uniform(0, np.pi, m), rng.uniform(0, 2 * np.pi, m),
                                 rng.uniform(0, 2 * np.pi, m), rng.uniform(0, 2 * np.pi, m))
    tk = np.linspace(0.0, 2 * period, s["t_kep"])
    out["kep_ours_s"] = best_time(lambda: propagate_kepler(r0, v0, tk), repeat=3)
    kp = s["n_kep_peer"]

    def f2(_, y):
        rr = y[:3]
        return np.concatenate([y[3:], -MU_EARTH_M3_S2 * rr / np.linalg.norm(rr) ** 3])

    def peer_kep():
        return [solve_ivp(f2, (0.0, tk[-1]), np.concatenate([r0[j], v0[j]]), t_eval=tk,
                          method="DOP853", rtol=1e-12, atol=1e-6).y[:3].T for j in range(kp)]

    out["kep_peer_s"] = best_time(peer_kep, repeat=1) * (m / kp)
    r_ours, _ = propagate_kepler(r0[:kp], v0[:kp], tk)
    out["kep_maxdiff_m"] = float(max(np.abs(r_ours[j] - p).max() for j, p in enumerate(peer_kep())))
    return out


def _measure_single_thread(quick: bool) -> dict:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    code = ("import json; from experiments.bench.bench_orbits import _measure; "
            f"print(json.dumps(_measure({quick!r})))")
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def run(*, quick: bool = False) -> list[BenchRow]:
    r = _measure_single_thread(quick)
    s = r["sizes"]
    rows = [
        throughput_row(
            f"CW propagate, {s['n_cw']} states x {s['t_cw']} epochs (1 core)",
            r["cw_ours_s"], r["cw_peer_s"], s["n_cw"] * s["t_cw"], "spacecraft-epochs/s",
            "scipy solve_ivp DOP853 (rtol 1e-10), states stacked",
            note=f"target >= 5e6; closed form; max diff {r['cw_maxdiff_m']:.1e} m",
        ),
        throughput_row(
            f"Kepler propagate (f and g), {s['n_kep']} orbits x {s['t_kep']} epochs (1 core)",
            r["kep_ours_s"], r["kep_peer_s"], s["n_kep"] * s["t_kep"], "spacecraft-epochs/s",
            "scipy solve_ivp DOP853 (rtol 1e-12), one orbit per call",
            note=f"exact two-body; max diff {r['kep_maxdiff_m']:.1e} m",
        ),
    ]
    return rows
