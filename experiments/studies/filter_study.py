"""The validation studies of ``filters`` (docs/filters.md, docs/reproduction.md), run by ``coobs filter-study``.

Runs, with the 003 settings (J = diag(1000, 800, 600) kg·m², Δt = 0.1 s, q₀ = [1, 0, 0, 0],
ω₀ = 5°/s per axis, initial estimates from 003 eq (35) with σ_q = 0.1 and σ_ω = 0.1°/s):

* ``expbc``       — Experiments B/C: both filters at 0.2° and 0.6°, fraction converged and median
  convergence time under the convergence criterion of :class:`filters.ConvergenceCriterion`,
  final errors, NEES against its 95 % band;
* ``thresholds``  — fraction converged for stricter attitude thresholds (why the paper can report
  non-convergence at 0.6°);
* ``increments``  — registration increments in the rotating Hill frame (stochastic cloning), and
  the naive chained absolute attitude for contrast (flag P003-14a, docs/papers.md#p003-14a);
* ``ratios``      — the inertia-ratio MEKF starting 30 % off, 120 s;
* ``robust``      — the MEKF with 20 % of the time missing in 5 s gaps and 10 % gross outliers.

:func:`run_studies` returns the summary and writes the figures; the command prints the tables and
writes ``OUT/summary.json``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from attitude.rigid_body import propagate_torque_free
from filters import (
    MEKF,
    AttitudeEKF,
    ConvergenceCriterion,
    MeasurementModel,
    ProcessNoise,
    convergence_time,
    run_monte_carlo,
)

J_KG_M2 = np.diag([1000.0, 800.0, 600.0])
RATIOS_TRUE = np.array([0.8, 0.6])
DT_S = 0.1
QUIET = ProcessNoise(attitude_psd_rad2_s=1e-14, rate_psd_rad2_s3=1e-14)
STUDIES = ("expbc", "thresholds", "increments", "ratios", "robust")
#: the convergence criterion of every study, in words (the summary's ``criterion``)
CRITERION_TEXT = ("attitude < 0.5 deg and rate < 0.05 deg/s for the last 10 s "
                  "(filters.ConvergenceCriterion)")

__all__ = ["STUDIES", "J_KG_M2", "RATIOS_TRUE", "DT_S", "run_studies"]


def _truth(duration_s: float):
    t = np.arange(int(round(duration_s / DT_S)) + 1) * DT_S
    q, w = propagate_torque_free([1.0, 0.0, 0.0, 0.0], np.deg2rad([5.0, 5.0, 5.0]), J_KG_M2, t)
    return t, q, w


def _row(r, extra=None) -> dict:
    s = r.summary()
    s.pop("criterion")
    s["nees_band_95"] = list(s["nees_band_95"])
    if extra:
        s.update(extra)
    return s


def _study_expbc(trials, seed, figs):
    t, q, w = _truth(60.0)
    out, results = {}, {}
    for tuning, pn in (("spec_Q", ProcessNoise()), ("near_zero_Q", QUIET)):
        for name, F in (("AttitudeEKF", AttitudeEKF(J_kg_m2=J_KG_M2, process_noise=pn)),
                        ("MEKF", MEKF(J_kg_m2=J_KG_M2, process_noise=pn))):
            for e in (0.2, 0.6):
                t0 = time.perf_counter()
                r = run_monte_carlo(F, t_s=t, q_NT_true=q, omega_TN_T_true=w,
                                    measurement=MeasurementModel(angle_error_deg=e), n_trials=trials, rng=seed)
                key = f"{name} {e:g} deg {tuning}"
                out[key] = _row(r, {"wall_s": time.perf_counter() - t0})
                results[key] = r
    if figs is not None:
        _plot_runs(results, figs, "expbc")
        _plot_nees(results, figs, "expbc_nees")
    return out, results


def _study_thresholds(results):
    out = {}
    for key, r in results.items():
        if "near_zero" in key:
            continue
        row = {}
        for att, rate in ((0.5, 0.05), (0.2, 0.02), (0.1, 0.01), (0.05, 0.005)):
            crit = ConvergenceCriterion(attitude_deg=att, rate_deg_s=rate)
            conv, tc = convergence_time(r.t_s, r.attitude_error_rad, r.rate_error_rad_s, criterion=crit)
            row[f"{att:g} deg / {rate:g} deg/s"] = {
                "fraction_converged": float(conv.mean()),
                "median_convergence_time_s": float(np.median(tc[conv])) if conv.any() else float("nan")}
        out[key] = row
    return out


def _study_increments(trials, seed, figs):
    t, q, w = _truth(60.0)
    out, results = {}, {}
    for kind in ("increment", "chained_absolute"):
        for name, F in (("AttitudeEKF", AttitudeEKF(J_kg_m2=J_KG_M2, process_noise=QUIET)),
                        ("MEKF", MEKF(J_kg_m2=J_KG_M2, process_noise=QUIET))):
            model = MeasurementModel(kind=kind, angle_error_deg=0.2,
                                     orbit_rate_rad_s=0.0011 if kind == "increment" else 0.0)
            r = run_monte_carlo(F, t_s=t, q_NT_true=q, omega_TN_T_true=w, measurement=model,
                                n_trials=trials, sigma_q=0.01, rng=seed)
            key = f"{name} {kind}"
            lo, hi = r.nees_band()
            out[key] = _row(r, {"time_mean_nees_after_1s": float(np.mean(r.mean_nees()[r.t_s >= 1.0])),
                                "nees_band_95": [lo, hi]})
            results[key] = r
    if figs is not None:
        _plot_nees({k: v for k, v in results.items() if "chained" not in k}, figs, "increments_nees")
    return out


def _study_ratios(trials, seed, figs):
    t, q, w = _truth(120.0)
    F = MEKF(J_kg_m2=J_KG_M2, estimate_inertia_ratios=True)
    out, hist = {}, {}
    for fac in ((1.3, 1.3), (0.7, 0.7), (1.3, 0.7), (0.7, 1.3)):
        r = run_monte_carlo(F, t_s=t, q_NT_true=q, omega_TN_T_true=w, n_trials=trials,
                            inertia_ratios_true=RATIOS_TRUE, initial_inertia_ratios=RATIOS_TRUE * np.array(fac),
                            rng=seed)
        rel = np.abs(r.inertia_ratios_est / RATIOS_TRUE - 1.0)  # (M, T, 2)
        within = np.all(rel < 0.01, axis=-1)
        # first time after which every trial stays within 1 %
        ok = np.flip(np.logical_and.accumulate(np.flip(within.all(0)))) if within.size else within
        t1 = float(t[np.argmax(ok)]) if ok.any() else float("nan")
        key = f"start {fac[0] - 1:+.0%} / {fac[1] - 1:+.0%}"
        out[key] = {"max_rel_error_120s": rel[:, -1].max(0).tolist(),
                    "max_rel_error_60s": rel[:, 600].max(0).tolist(),
                    "all_trials_within_1pct_from_s": t1,
                    "fraction_converged": r.fraction_converged, "n_failed": int(r.failed.sum())}
        hist[key] = r
    if figs is not None:
        _plot_ratios(hist, figs)
    return out


def _study_robust(trials, seed):
    t, q, w = _truth(60.0)
    model = MeasurementModel(angle_error_deg=0.2, missing_fraction=0.2, gap_s=5.0, outlier_fraction=0.1)
    out = {}
    for name, F in (("MEKF", MEKF(J_kg_m2=J_KG_M2)), ("AttitudeEKF", AttitudeEKF(J_kg_m2=J_KG_M2)),
                    ("MEKF no reset", MEKF(J_kg_m2=J_KG_M2, reset_after_rejections=None))):
        r = run_monte_carlo(F, t_s=t, q_NT_true=q, omega_TN_T_true=w, measurement=model,
                            n_trials=trials, rng=seed)
        out[name] = _row(r, {"n_outliers": int(r.n_outliers.sum()),
                             "missing_fraction_measured": float(1 - r.measurements.available[:, 1:].mean())})
    return out


# ----------------------------------------------------------------------------- figures

def _plot_runs(results, figs: Path, stem: str) -> None:
    import matplotlib.pyplot as plt

    from experiments.plotting import legend_below, save

    keys = [k for k in results if "spec_Q" in k]
    fig, axes = plt.subplots(2, len(keys), figsize=(4 * len(keys), 6.4), sharex=True, squeeze=False,
                             layout="constrained")
    for j, key in enumerate(keys):
        r = results[key]
        for i in range(min(10, r.n_trials)):  # 10 typical runs, as 003 Figs 9–10
            axes[0, j].semilogy(r.t_s, np.rad2deg(r.attitude_error_rad[i]), lw=0.7)
            axes[1, j].semilogy(r.t_s, np.rad2deg(r.rate_error_rad_s[i]), lw=0.7)
        axes[0, j].axhline(r.criterion.attitude_deg, color="k", ls="--", lw=0.8, label="convergence threshold")
        axes[1, j].axhline(r.criterion.rate_deg_s, color="k", ls="--", lw=0.8)
        axes[0, j].set_title(key.replace(" spec_Q", ""), fontsize=9)
        axes[1, j].set_xlabel("time [s]")
    axes[0, 0].set_ylabel("attitude error [deg]")
    axes[1, 0].set_ylabel("rate error [deg/s]")
    legend_below(fig)
    save(fig, figs / f"{stem}.png", dpi=110)


def _plot_nees(results, figs: Path, stem: str) -> None:
    import matplotlib.pyplot as plt

    from experiments.plotting import legend_right, save

    fig, ax = plt.subplots(figsize=(8, 4), layout="constrained")
    band = None
    for key, r in results.items():
        ax.plot(r.t_s, r.mean_nees(), lw=0.8, label=key)
        band = r.nees_band()
    if band is not None:
        ax.axhspan(*band, color="0.85", zorder=0, label="95 % band")
    ax.set_yscale("log")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("average NEES (6 dof)")
    legend_right(ax)
    save(fig, figs / f"{stem}.png", dpi=110)


def _plot_ratios(hist, figs: Path) -> None:
    import matplotlib.pyplot as plt

    from experiments.plotting import legend_below, save

    fig, axes = plt.subplots(1, 2, figsize=(9, 4.0), sharex=True, layout="constrained")
    for key, r in hist.items():
        for k in range(2):
            axes[k].plot(r.t_s, np.median(r.inertia_ratios_est[:, :, k], 0), lw=0.9, label=key)
    for k, name in enumerate(("J_yy/J_xx", "J_zz/J_xx")):
        axes[k].axhline(RATIOS_TRUE[k], color="k", ls="--", lw=0.8, label="true ratio")
        axes[k].set_title(f"{name} (median of runs)", fontsize=9)
        axes[k].set_xlabel("time [s]")
    legend_below(fig, ncol=3)
    save(fig, figs / "inertia_ratios.png", dpi=110)


# ----------------------------------------------------------------------------- driver


def run_studies(selected: Sequence[str], *, trials: int, seed: int, fig_dir: Path | None,
                on_study: Callable[[str, dict[str, Any]], None] | None = None) -> dict[str, Any]:
    """Run the selected studies in the order of :data:`STUDIES`; returns the JSON-able summary.

    Parameters
    ----------
    selected : sequence of str
        Names from :data:`STUDIES` (``thresholds`` reuses the runs of ``expbc``).
    trials : int
        Monte Carlo runs per case (>= 2).
    seed : int
        Parent seed (one stream per trial is spawned).
    fig_dir : Path, optional
        Where PNG figures go (an existing folder); none when ``None``.
    on_study : callable, optional
        ``on_study(name, result)`` after each study (the command prints its table).

    Returns
    -------
    dict
        ``{"trials", "seed", "criterion", <study>: result, ...}``.

    Raises
    ------
    ValueError
        ``trials`` < 2 or an unknown study name.
    """
    if trials < 2:
        raise ValueError(f"trials: need at least 2, got {trials}")
    for name in selected:
        if name not in STUDIES:
            raise ValueError(f"selected: unknown study {name!r}; known: {', '.join(STUDIES)}")
    summary: dict[str, Any] = {"trials": trials, "seed": seed, "criterion": CRITERION_TEXT}

    def done(name: str, result: dict[str, Any]) -> None:
        summary[name] = result
        if on_study is not None:
            on_study(name, result)

    expbc_results = None
    if "expbc" in selected or "thresholds" in selected:
        expbc, expbc_results = _study_expbc(trials, seed, fig_dir)
        done("expbc", expbc)
    if "thresholds" in selected:
        done("thresholds", _study_thresholds(expbc_results))
    if "increments" in selected:
        done("increments", _study_increments(trials, seed, fig_dir))
    if "ratios" in selected:
        done("ratios", _study_ratios(trials, seed, fig_dir))
    if "robust" in selected:
        done("robust", _study_robust(trials, seed))
    return summary
