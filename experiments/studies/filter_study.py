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

:func:`run_studies` returns the summary and the dataset the figures are drawn from (a
:class:`experiments.results.ScenarioResult` whose dataset has ``attrs["kind"] = "filter_study"``);
``coobs filter-study`` prints the tables and writes ``OUT/result.nc`` and ``OUT/summary.json``, and
:func:`plot` draws the figures from the stored dataset (``coobs plot OUT`` redraws them).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from attitude.rigid_body import propagate_torque_free
from experiments.results import ScenarioResult
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

#: the ``kind`` attribute of the study's dataset (``coobs plot`` draws it with :func:`plot`)
KIND = "filter_study"
#: typical runs per case kept in the dataset for the figures (as 003 Figs 9–10)
TYPICAL_RUNS = 10

__all__ = ["STUDIES", "KIND", "J_KG_M2", "RATIOS_TRUE", "DT_S", "run_studies", "plot"]


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


def _study_expbc(trials, seed):
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


def _study_increments(trials, seed):
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
    return out, results


def _study_ratios(trials, seed):
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
    return out, hist


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


# ----------------------------------------------------------------------------- dataset


def _dataset(expbc: dict | None, increments: dict | None, ratios: dict | None, *, trials: int,
             seed: int) -> xr.Dataset:
    """What the figures need, from the Monte Carlo results of the studies that ran."""
    data: dict[str, Any] = {}
    coords: dict[str, Any] = {"bound": ["lower", "upper"]}
    deg, deg_s = {"units": "deg"}, {"units": "deg/s"}
    if expbc:
        first = next(iter(expbc.values()))
        n = min(TYPICAL_RUNS, first.n_trials)
        coords.update(expbc_case=list(expbc), time_s=("time_s", first.t_s, {"units": "s"}), run=np.arange(n))
        data["expbc_attitude_error_deg"] = (("expbc_case", "run", "time_s"),
                                            np.stack([np.rad2deg(r.attitude_error_rad[:n]) for r in expbc.values()]),
                                            deg)
        data["expbc_rate_error_deg_s"] = (("expbc_case", "run", "time_s"),
                                          np.stack([np.rad2deg(r.rate_error_rad_s[:n]) for r in expbc.values()]),
                                          deg_s)
        data["expbc_mean_nees"] = (("expbc_case", "time_s"), np.stack([r.mean_nees() for r in expbc.values()]),
                                   {"units": "1", "long_name": "average NEES (6 dof)"})
        data["expbc_nees_band_95"] = (("expbc_case", "bound"), [r.nees_band() for r in expbc.values()],
                                      {"units": "1"})
        data["expbc_threshold_attitude_deg"] = ("expbc_case", [r.criterion.attitude_deg for r in expbc.values()], deg)
        data["expbc_threshold_rate_deg_s"] = ("expbc_case", [r.criterion.rate_deg_s for r in expbc.values()], deg_s)
    if increments:
        first = next(iter(increments.values()))
        coords.update(increments_case=list(increments), time_s=("time_s", first.t_s, {"units": "s"}))
        data["increments_mean_nees"] = (("increments_case", "time_s"),
                                        np.stack([r.mean_nees() for r in increments.values()]),
                                        {"units": "1", "long_name": "average NEES (6 dof)"})
        data["increments_nees_band_95"] = (("increments_case", "bound"),
                                           [r.nees_band() for r in increments.values()], {"units": "1"})
    if ratios:
        first = next(iter(ratios.values()))
        coords.update(ratios_case=list(ratios), ratios_time_s=("ratios_time_s", first.t_s, {"units": "s"}),
                      ratio=["J_yy/J_xx", "J_zz/J_xx"])
        data["ratios_median_estimate"] = (("ratios_case", "ratios_time_s", "ratio"),
                                          np.stack([np.median(r.inertia_ratios_est, 0) for r in ratios.values()]),
                                          {"units": "1", "long_name": "median of the runs"})
        data["ratios_true"] = ("ratio", RATIOS_TRUE, {"units": "1"})
    return xr.Dataset(data, coords=coords, attrs={"kind": KIND, "trials": trials, "seed": seed,
                                                  "criterion": CRITERION_TEXT})


# ----------------------------------------------------------------------------- figures


def _plot_runs(ds: xr.Dataset, figs: Path, stem: str, fmt: str) -> Path:
    import matplotlib.pyplot as plt

    from experiments.plotting import legend_below, save

    keys = [str(k) for k in ds["expbc_case"].values if "spec_Q" in str(k)]
    t_s = ds["time_s"].values
    fig, axes = plt.subplots(2, len(keys), figsize=(4 * len(keys), 6.4), sharex=True, squeeze=False,
                             layout="constrained")
    for j, key in enumerate(keys):
        att = ds["expbc_attitude_error_deg"].sel(expbc_case=key).values
        rate = ds["expbc_rate_error_deg_s"].sel(expbc_case=key).values
        for i in range(att.shape[0]):  # the typical runs, as 003 Figs 9–10
            axes[0, j].semilogy(t_s, att[i], lw=0.7)
            axes[1, j].semilogy(t_s, rate[i], lw=0.7)
        axes[0, j].axhline(float(ds["expbc_threshold_attitude_deg"].sel(expbc_case=key)), color="k", ls="--",
                           lw=0.8, label="convergence threshold")
        axes[1, j].axhline(float(ds["expbc_threshold_rate_deg_s"].sel(expbc_case=key)), color="k", ls="--", lw=0.8)
        axes[0, j].set_title(key.replace(" spec_Q", ""), fontsize=9)
        axes[1, j].set_xlabel("time [s]")
    axes[0, 0].set_ylabel("attitude error [deg]")
    axes[1, 0].set_ylabel("rate error [deg/s]")
    legend_below(fig)
    return save(fig, figs / f"{stem}.{fmt}", dpi=110)


def _plot_nees(ds: xr.Dataset, study: str, keys: list[str], figs: Path, stem: str, fmt: str) -> Path:
    import matplotlib.pyplot as plt

    from experiments.plotting import legend_right, save

    fig, ax = plt.subplots(figsize=(8, 4), layout="constrained")
    band = None
    t_s = ds["time_s"].values
    for key in keys:
        ax.plot(t_s, ds[f"{study}_mean_nees"].sel({f"{study}_case": key}).values, lw=0.8, label=key)
        band = tuple(float(b) for b in ds[f"{study}_nees_band_95"].sel({f"{study}_case": key}).values)
    if band is not None:
        ax.axhspan(*band, color="0.85", zorder=0, label="95 % band")
    ax.set_yscale("log")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("average NEES (6 dof)")
    legend_right(ax)
    return save(fig, figs / f"{stem}.{fmt}", dpi=110)


def _plot_ratios(ds: xr.Dataset, figs: Path, fmt: str) -> Path:
    import matplotlib.pyplot as plt

    from experiments.plotting import legend_below, save

    fig, axes = plt.subplots(1, 2, figsize=(9, 4.0), sharex=True, layout="constrained")
    t_s = ds["ratios_time_s"].values
    for key in ds["ratios_case"].values:
        for k in range(2):
            axes[k].plot(t_s, ds["ratios_median_estimate"].sel(ratios_case=key).values[:, k], lw=0.9, label=str(key))
    for k, name in enumerate(ds["ratio"].values):
        axes[k].axhline(float(ds["ratios_true"].values[k]), color="k", ls="--", lw=0.8, label="true ratio")
        axes[k].set_title(f"{name} (median of runs)", fontsize=9)
        axes[k].set_xlabel("time [s]")
    legend_below(fig, ncol=3)
    return save(fig, figs / f"inertia_ratios.{fmt}", dpi=110)


def plot(dataset: xr.Dataset, fig_dir: Path, *, format: str = "png") -> list[Path]:
    """Draw the figures of a stored filter study (the dataset of :func:`run_studies`).

    Parameters
    ----------
    dataset : xarray.Dataset
        The study's dataset, or it read back from ``result.nc``; a study that did not run has no
        variables and draws no figure.
    fig_dir : Path
        An existing folder for the figures.
    format : str
        ``"png"``, ``"pdf"`` or ``"svg"``.

    Returns
    -------
    list of Path
        ``expbc``, ``expbc_nees`` (Experiments B/C: typical runs, average NEES), ``increments_nees``
        and ``inertia_ratios``, those whose study ran.
    """
    figs = Path(fig_dir)
    written = []
    if "expbc_attitude_error_deg" in dataset:
        written.append(_plot_runs(dataset, figs, "expbc", format))
        written.append(_plot_nees(dataset, "expbc", [str(k) for k in dataset["expbc_case"].values], figs,
                                  "expbc_nees", format))
    if "increments_mean_nees" in dataset:
        keys = [str(k) for k in dataset["increments_case"].values if "chained" not in str(k)]
        written.append(_plot_nees(dataset, "increments", keys, figs, "increments_nees", format))
    if "ratios_median_estimate" in dataset:
        written.append(_plot_ratios(dataset, figs, format))
    return written


# ----------------------------------------------------------------------------- driver


def run_studies(selected: Sequence[str], *, trials: int, seed: int,
                on_study: Callable[[str, dict[str, Any]], None] | None = None) -> ScenarioResult:
    """Run the selected studies in the order of :data:`STUDIES`.

    Parameters
    ----------
    selected : sequence of str
        Names from :data:`STUDIES` (``thresholds`` reuses the runs of ``expbc``).
    trials : int
        Monte Carlo runs per case (>= 2).
    seed : int
        Parent seed (one stream per trial is spawned).
    on_study : callable, optional
        ``on_study(name, result)`` after each study (the command prints its table).

    Returns
    -------
    ScenarioResult
        ``summary``: ``{"trials", "seed", "criterion", <study>: result, ...}`` (JSON-able);
        ``dataset``: what :func:`plot` draws (typical runs, average NEES and its band, the median
        inertia-ratio estimates), ``attrs["kind"] = "filter_study"``.

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

    expbc_results = increment_results = ratio_results = None
    if "expbc" in selected or "thresholds" in selected:
        expbc, expbc_results = _study_expbc(trials, seed)
        done("expbc", expbc)
    if "thresholds" in selected:
        done("thresholds", _study_thresholds(expbc_results))
    if "increments" in selected:
        increments, increment_results = _study_increments(trials, seed)
        done("increments", increments)
    if "ratios" in selected:
        ratios, ratio_results = _study_ratios(trials, seed)
        done("ratios", ratios)
    if "robust" in selected:
        done("robust", _study_robust(trials, seed))
    dataset = _dataset(expbc_results, increment_results, ratio_results, trials=trials, seed=seed)
    return ScenarioResult(dataset=dataset, summary=summary)
