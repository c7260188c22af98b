"""003 Experiments B–D (Figs 7–12): the EKF on synthetic attitude measurements, and its sweep cell.

The truth is the paper's (003 eq 34, flag P003-13, docs/papers.md#p003-13): ``q₀ = [1, 0, 0, 0]``,
``ω₀ = [5, 5, 5] °/s``, torque-free with ``J = diag(1000, 800, 600) kg·m²`` (003 gives no inertia;
a tri-axial choice so that the body tumbles, flag P003-14, docs/papers.md#p003-14), propagated
exactly by :func:`attitude.rigid_body.propagate_torque_free`.  The filter starts from 003 eq (35)
and sees a measurement of attitude-angle error ``e`` each epoch (:class:`filters.MeasurementModel`:
``e`` is the norm of the 3-axis error, so σ_axis = e/√3).  Cases: fixed errors (Experiments B and C:
0.2° and 0.6°) and per-run errors drawn from the realistic observation window (Experiment D:
0.025–0.35° for 3 views, 0.03–0.85° for 2 views).  "Converged" follows
:class:`filters.ConvergenceCriterion`; the paper gives no threshold (flag P003-15,
docs/papers.md#p003-15), the configs use 0.5° and 0.05°/s held for the last 10 s.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import xarray as xr

from attitude.rigid_body import propagate_torque_free
from experiments.scenarios.formation.config import Config
from experiments.scenarios.formation.parts import criterion, make_estimator
from experiments.sweep import Metric, SweepCell, cell_seed_sequences
from filters import ConvergenceCriterion, MeasurementModel, MonteCarloResult, run_monte_carlo

__all__ = ["truth_history", "monte_carlo", "ekf_study", "criterion_text", "ekf_cell", "ekf_sweep_cell",
           "role_generator"]


def truth_history(cfg: Config) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(t_s (T,), q_NT (T, 4), omega_TN_T (T, 3) rad/s)`` of the configured torque-free target."""
    t = cfg.time.epochs()
    q, w = propagate_torque_free(np.asarray(cfg.target.q_NT0), cfg.omega0_rad_s(), cfg.inertia(), t)
    return t, q, w


def role_generator(seeds: Sequence[np.random.SeedSequence], role: int) -> np.random.Generator:
    """Generator whose ``spawn(M)`` children are independent per trial and per ``role``.

    The trial seeds of a sweep cell share their entropy; ``SeedSequence([*entropy, role])`` spawns
    child ``i`` for trial ``i``, so a batched Monte Carlo (which spawns one stream per trial from
    one generator) still gives trial ``i`` numbers that depend only on (seed, cell, trial, role).
    """
    ent = seeds[0].entropy
    ent = list(ent) if isinstance(ent, Sequence | np.ndarray) else [int(ent)]
    return np.random.default_rng(np.random.SeedSequence([*ent, 0x5EED0000 + int(role)]))


def _quat_error(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    """``q̂ − q`` with the sign of ``q̂`` chosen along ``q`` (the component errors of 003 Figs 7–8)."""
    s = np.sign(np.sum(q_est * q_true, -1, keepdims=True))
    s = np.where(s == 0, 1.0, s)
    return q_est * s - q_true


def monte_carlo(cfg: Config, t: np.ndarray, q: np.ndarray, w: np.ndarray, *, e_deg: float | None,
                window: Sequence[float] | None, runs: int, rng: np.random.Generator,
                orbit_rate: float = 0.0) -> MonteCarloResult:
    """``runs`` filters of the configured kind on synthetic measurements of the truth ``(t, q, w)``.

    ``e_deg``: a fixed attitude-angle error of the measurements, or ``window = (lo, hi)``: a
    per-run error drawn uniformly (degrees); ``rng`` spawns one stream per run.
    """
    meas = MeasurementModel(kind=cfg.ekf.measurement, angle_error_deg=e_deg if e_deg is not None else 0.0,
                            angle_error_range_deg=None if window is None else tuple(window),
                            orbit_rate_rad_s=orbit_rate)
    return run_monte_carlo(make_estimator(cfg), t_s=t, q_NT_true=q, omega_TN_T_true=w, measurement=meas,
                           n_trials=runs, sigma_q=cfg.estimator.sigma_q,
                           sigma_omega_rad_s=float(np.deg2rad(cfg.estimator.sigma_omega_deg_s)),
                           criterion=criterion(cfg), rng=rng)


def ekf_study(cfg: Config, *, progress: Callable[[int, int], None] | None = None) -> tuple[xr.Dataset, dict]:
    """Experiments B–D: every case of ``cfg.ekf`` × ``cfg.ekf.runs`` Monte Carlo runs.

    Returns the dataset (coordinates ``case``, ``run``, ``time_s``, ``quat_component``,
    ``axis``) and a summary dict (per case: fraction converged, median convergence time,
    final RMS errors).
    """
    t, q, w = truth_history(cfg)
    cases: list[tuple[str, float | None, list[float] | None]] = []
    for e in cfg.ekf.cases_deg:
        cases.append((f"{e:g} deg", e, None))
    for name, win in cfg.ekf.windows_deg.items():
        cases.append((f"{name} window", None, win))
    if not cases:
        raise ValueError("ekf: no cases (cases_deg and windows_deg are both empty)")
    M, T = cfg.ekf.runs, t.size
    shape = (len(cases), M, T)
    att = np.empty(shape, np.float32)
    eul = np.empty(shape, np.float32)
    rate = np.empty(shape, np.float32)
    qerr = np.empty((*shape, 4), np.float32)
    werr = np.empty((*shape, 3), np.float32)
    conv = np.zeros((len(cases), M), bool)
    tconv = np.full((len(cases), M), np.nan)
    e_used = np.empty((len(cases), M))
    failed = np.empty((len(cases), M), dtype=object)
    summary: dict = {"cases": {}}
    if progress:
        progress(0, len(cases))
    for i, (name, e_deg, win) in enumerate(cases):
        rng = np.random.default_rng(cell_seed_sequences(cfg.seed, {"ekf.case": name}, 1)[0])
        mc = monte_carlo(cfg, t, q, w, e_deg=e_deg, window=win, runs=M, rng=rng)
        att[i] = np.rad2deg(mc.attitude_error_rad)
        eul[i] = np.rad2deg(mc.euler_error_rad)
        rate[i] = np.rad2deg(mc.rate_error_rad_s)
        qerr[i] = _quat_error(mc.q_NT_est, q[None])
        werr[i] = np.rad2deg(mc.omega_TN_T_est - w[None])
        conv[i] = mc.converged
        tconv[i] = mc.convergence_time_s
        e_used[i] = np.rad2deg(mc.measurements.angle_error_rad)
        failed[i] = mc.failure_reason.astype(object)
        s = mc.summary()
        summary["cases"][name] = {k: s[k] for k in ("fraction_converged", "median_convergence_time_s",
                                                    "final_rms_attitude_error_deg",
                                                    "final_rms_rate_error_deg_s", "n_failed")}
        if progress:
            progress(i + 1, len(cases))
    crit = criterion(cfg)
    ds = xr.Dataset(
        {
            "attitude_error_deg": (("case", "run", "time_s"), att,
                                   {"units": "deg", "long_name": "rotation-angle error of the estimate"}),
            "euler_error_deg": (("case", "run", "time_s"), eul,
                                {"units": "deg", "long_name": "003 eq (36), 3-2-1 Euler angles"}),
            "rate_error_deg_s": (("case", "run", "time_s"), rate,
                                 {"units": "deg/s", "long_name": "003 eq (37)"}),
            "quat_error": (("case", "run", "time_s", "quat_component"), qerr,
                           {"units": "1", "long_name": "estimated minus true quaternion (Figs 7-8)"}),
            "rate_error_components_deg_s": (("case", "run", "time_s", "axis"), werr,
                                            {"units": "deg/s", "long_name": "estimated minus true body rate"}),
            "converged": (("case", "run"), conv, {"units": "1", "long_name": criterion_text(crit)}),
            "convergence_time_s": (("case", "run"), tconv, {"units": "s"}),
            "measurement_error_deg": (("case", "run"), e_used,
                                      {"units": "deg", "long_name": "attitude-angle error of the measurements"}),
            "failure_reason": (("case", "run"), failed),
        },
        coords={
            "case": [c[0] for c in cases],
            "run": np.arange(M),
            "time_s": ("time_s", t, {"units": "s"}),
            "quat_component": ["q0", "q1", "q2", "q3"],
            "axis": ["x", "y", "z"],
        },
        attrs={"study": "ekf", "measurement": cfg.ekf.measurement, "filter": cfg.estimator.filter,
               "typical_runs": cfg.ekf.typical_runs, "threshold_attitude_deg": crit.attitude_deg,
               "threshold_rate_deg_s": crit.rate_deg_s, "hold_s": crit.hold_s},
    )
    summary["criterion"] = criterion_text(crit)
    return ds, summary


def criterion_text(c: ConvergenceCriterion) -> str:
    """The criterion in words (the ``long_name`` of the ``converged`` variables)."""
    return (f"converged: attitude error < {c.attitude_deg:g} deg and rate error < {c.rate_deg_s:g} deg/s "
            f"for the last {c.hold_s:g} s")


# ----------------------------------------------------------------------------- sweep cell


def ekf_cell(cfg: Config, seeds: Sequence[np.random.SeedSequence]) -> dict[str, np.ndarray]:
    """Sweep cell: one Monte Carlo of ``len(seeds)`` runs at ``cfg.ekf.angle_error_deg``."""
    t, q, w = truth_history(cfg)
    mc = monte_carlo(cfg, t, q, w, e_deg=cfg.ekf.angle_error_deg, window=None, runs=len(seeds),
                      rng=role_generator(seeds, 1))
    tail = t >= t[-1] - cfg.estimator.convergence_hold_s
    return {
        "converged": mc.converged.astype(float),
        "convergence_time_s": mc.convergence_time_s,
        "final_attitude_error_deg": np.rad2deg(np.sqrt(np.mean(mc.attitude_error_rad[:, tail] ** 2, -1))),
        "final_rate_error_deg_s": np.rad2deg(np.sqrt(np.mean(mc.rate_error_rad_s[:, tail] ** 2, -1))),
        "failure_reason": mc.failure_reason,
    }


def ekf_sweep_cell(cfg: Config) -> SweepCell:
    """The sweep cell of the EKF study (:func:`ekf_cell`) with its metrics."""
    return SweepCell(
        fn=ekf_cell,
        metrics={
            "converged": Metric("1", long_name=criterion_text(criterion(cfg))),
            "convergence_time_s": Metric("s", long_name="time after which the run stays converged"),
            "final_attitude_error_deg": Metric("deg", long_name="RMS attitude error over the final hold window"),
            "final_rate_error_deg_s": Metric("deg/s", long_name="RMS rate error over the final hold window"),
        },
        name="ekf",
    )
