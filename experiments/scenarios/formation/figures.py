"""Figures of the formation scenario (003), drawn from stored results with the primitives of
:mod:`experiments.plotting`: error and convergence maps, EKF runs, one Experiment A cell, the closed loop.

Each ``*_figures`` function selects and reduces the stored dataset, draws, and returns the paths of
the files it wrote into ``fig_dir``, in ``format`` (``"png"``, ``"pdf"`` or ``"svg"``).  Panels that
are compared share one colour range and one colour bar, with arrows for clipped values.
"""

from __future__ import annotations

import itertools
import json
import tomllib
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

from experiments.plotting import (  # noqa: E402
    check_format,
    clipped_extend,
    figure_path,
    legend_below,
    legend_right,
    plot_cloud,
    plot_envelope,
    plot_histogram,
    plot_image_tracks,
    plot_map,
    plot_time_series,
    plot_timeline,
    save,
    shade_spans,
    shared_range,
    sweep_overview_figures,
)
from experiments.plotting.style import ECLIPSE_COLOR, ECLIPSE_HATCH, GAP_COLOR  # noqa: E402

__all__ = [
    "error_map_figures",
    "convergence_map_figures",
    "sweep_figures",
    "ekf_figures",
    "error_map_run_figures",
    "closed_loop_figures",
    "ERROR_MAP_RANGE_DEG",
]


#: colour range of 003 Figs 5–6, degrees (values above get the colour bar's arrow)
ERROR_MAP_RANGE_DEG = (0.0, 1.6)
_X_LABEL, _Y_LABEL = "distance [m]", "line-of-sight angle [deg]"


def _combos(ds: xr.Dataset, dims: Sequence[str]) -> list[dict]:
    if not dims:
        return [{}]
    vals = [ds[d].values.tolist() for d in dims]
    return [dict(zip(dims, c, strict=True)) for c in itertools.product(*vals)]


def _suffix(sel: dict) -> str:
    return "".join(f"_{k}-{v}" for k, v in sel.items()).replace(" ", "").replace("/", "-")


def error_map_figures(ds: xr.Dataset, fig_dir: Path, *, format: str = "png") -> list[Path]:
    """003 Figs 5–6: median e_Δθ over the trials per (distance, axis angle), a row per number of views,
    with the per-step RMS error and the Cramér–Rao map (median bound of one increment) beside it.

    All panels share the colour range :data:`ERROR_MAP_RANGE_DEG` (viridis) and one colour bar; values
    above it keep the top colour, the bar's arrow marks them and each cell's label gives its value.
    With ``failed_steps`` in the dataset a fourth column gives the percentage of the cell's steps
    whose registration was refused (failed, or rejected by the evidence checks): the medians beside
    it are over the surviving steps and trials only.
    """
    check_format(format)
    paths: list[Path] = []
    x, y = "distance_m", "axis_angle_deg"
    views = ds["n_views"].values.tolist() if "n_views" in ds.dims else [None]
    other = [d for d in ds["done"].dims if d not in (x, y, "n_views")]
    e = ds["e_dtheta_deg"].median("trial", skipna=True)
    step = ds["step_rms_deg"].median("trial", skipna=True)
    crlb = ds["crlb_deg"].median("trial", skipna=True)
    refused = _refused_percent(ds) if "failed_steps" in ds else None
    ncol = 3 if refused is None else 4
    vmin, vmax = ERROR_MAP_RANGE_DEG
    for sel in _combos(ds, other):
        fig, axes = plt.subplots(len(views), ncol, figsize=(5.0 * ncol, 3.8 * len(views) + 0.4), layout="constrained",
                                 squeeze=False)
        shown = []
        for r, nv in enumerate(views):
            s = {**sel, **({"n_views": nv} if nv is not None else {})}
            tag = f"{nv} views" if nv is not None else ""
            for c, (da, what) in enumerate(((e, "e_dtheta (003 eq 33), median"),
                                            (step, "per-step RMS error, median"),
                                            (crlb, "Cramer-Rao bound per step, median"))):
                m = da.sel(s).transpose(y, x).values
                shown.append(m)
                plot_map(m, ds[x].values, ds[y].values, ax=axes[r, c], vmin=vmin, vmax=vmax, cmap="viridis",
                         xlabel=_X_LABEL, ylabel=_Y_LABEL, title=f"{tag}: {what}", annotate=True, colorbar=False)
            if refused is not None:
                plot_map(refused.sel(s).transpose(y, x).values, ds[x].values, ds[y].values, ax=axes[r, 3],
                         vmin=0.0, vmax=100.0, cmap="cividis", xlabel=_X_LABEL, ylabel=_Y_LABEL,
                         title=f"{tag}: steps refused", cbar_label="refused steps [%]", annotate=True,
                         fmt="{:.0f}")
        fig.colorbar(axes[0, 0].collections[0], ax=axes[:, :3].ravel().tolist(), label="angle error [deg]",
                     extend=clipped_extend(np.concatenate([m.ravel() for m in shown]), vmin, vmax))
        extra = ", ".join(f"{k} = {v}" for k, v in sel.items())
        fig.suptitle(f"Experiment A error maps (003 Figs 5-6){' - ' + extra if extra else ''}")
        paths.append(save(fig, figure_path(fig_dir, f"error_maps{_suffix(sel)}", format)))
    return paths


def _refused_percent(ds: xr.Dataset) -> xr.DataArray:
    """Percentage of each cell's registration steps refused: ``Σ failed_steps / (trials × steps)``, a trial
    with a ``failure_reason`` (every step refused) counting all its steps; the steps per trial from the
    stored config and its overrides (``error_map.steps``)."""
    steps = float(ds["failed_steps"].max())  # when the stored config cannot be read: the most refused
    try:
        steps = float(_stored_setting(ds, "error_map.steps", steps))
    except (ValueError, TypeError):
        pass
    failed = ds["failed_steps"]
    if "failure_reason" in ds:  # a trial that failed outright (every step refused) stores no metrics
        failed = xr.where(ds["failure_reason"] != "", steps, failed)
    return 100.0 * failed.sum("trial", skipna=True) / (steps * failed.notnull().sum("trial"))


def convergence_map_figures(ds: xr.Dataset, fig_dir: Path, *, frac: xr.DataArray, tmed: xr.DataArray,
                            name: str, title: str, format: str = "png") -> list[Path]:
    """Fraction of converged runs and median convergence time per (distance, angle), a row per view count.

    Each column has one colour range (the fraction 0–1, the time over every map of ``tmed``) and one
    colour bar, so that the rows (2 and 3 views) and the files (other swept values) compare.
    """
    check_format(format)
    paths: list[Path] = []
    x, y = "distance_m", "axis_angle_deg"
    views = ds["n_views"].values.tolist() if "n_views" in ds.dims else [None]
    other = [d for d in ds["done"].dims if d not in (x, y, "n_views")]
    t_lo, t_hi = shared_range(tmed.values)
    for sel in _combos(ds, other):
        fig, axes = plt.subplots(len(views), 2, figsize=(10.5, 3.8 * len(views) + 0.4), layout="constrained",
                                 squeeze=False)
        for r, nv in enumerate(views):
            s = {**sel, **({"n_views": nv} if nv is not None else {})}
            tag = f"{nv} views: " if nv is not None else ""
            plot_map(frac.sel(s).transpose(y, x).values, ds[x].values, ds[y].values, ax=axes[r, 0], vmin=0,
                     vmax=1, cmap="cividis", xlabel=_X_LABEL, ylabel=_Y_LABEL, colorbar=False,
                     title=f"{tag}fraction converged", annotate=True)
            plot_map(tmed.sel(s).transpose(y, x).values, ds[x].values, ds[y].values, ax=axes[r, 1], vmin=t_lo,
                     vmax=t_hi, cmap="viridis_r", xlabel=_X_LABEL, ylabel=_Y_LABEL, colorbar=False,
                     title=f"{tag}median convergence time", annotate=True, fmt="{:.1f}")
        fig.colorbar(axes[0, 0].collections[0], ax=axes[:, 0].tolist(), label="fraction of runs converged")
        fig.colorbar(axes[0, 1].collections[0], ax=axes[:, 1].tolist(), label="median convergence time [s]")
        extra = ", ".join(f"{k} = {v}" for k, v in sel.items())
        fig.suptitle(title + (f" - {extra}" if extra else ""))
        paths.append(save(fig, figure_path(fig_dir, f"{name}{_suffix(sel)}", format)))
    return paths


def sweep_figures(ds: xr.Dataset, fig_dir: Path, *, format: str = "png") -> list[Path]:
    """Figures of a formation sweep: error maps, convergence maps, or the generic overview."""
    cell = ds.attrs.get("cell", "")
    grid = set(ds["done"].dims)
    paths: list[Path] = []
    if cell == "error_map" and {"distance_m", "axis_angle_deg"} <= grid:
        paths += error_map_figures(ds, fig_dir, format=format)
        if np.isfinite(ds["filter_fraction_converged"].values).any():
            paths += convergence_map_figures(
                ds, fig_dir, frac=ds["filter_fraction_converged"], tmed=ds["filter_median_convergence_time_s"],
                name="convergence_maps_filter", format=format,
                title="EKF convergence driven by each cell's measured registration error (003 Figs 11-12 approach)")
        return paths
    if cell == "closed_loop" and {"distance_m", "axis_angle_deg"} <= grid:
        frac = ds["converged"].mean("trial", skipna=True)
        tmed = ds["convergence_time_s"].median("trial", skipna=True)
        return convergence_map_figures(ds, fig_dir, frac=frac, tmed=tmed, name="convergence_maps_closed_loop",
                                       title=f"Closed loop end to end (observation - registration - {_sweep_estimator(ds)})",
                                       format=format)
    return sweep_overview_figures(ds, fig_dir, format=format)


def _sweep_estimator(ds: xr.Dataset) -> str:
    """The estimator a closed-loop sweep ran, from its stored config and ``--set`` overrides ("estimator" when swept)."""
    if "estimator.filter" in str(ds.attrs.get("swept_keys", "")):
        return "estimator"
    try:
        name = str(_stored_setting(ds, "estimator.filter", "ekf"))
    except ValueError:
        return "estimator"
    return name.upper() if name in ("ekf", "mekf") else name


def _stored_setting(ds: xr.Dataset, key: str, default):
    """The value of ``key`` (``"table.name"``) a sweep ran with: its stored config after its ``--set``
    overrides, ``default`` where neither sets it (``ValueError`` when they cannot be parsed)."""
    table, name = key.split(".", 1)
    value = tomllib.loads(str(ds.attrs.get("config_toml", ""))).get(table, {}).get(name, default)
    return json.loads(str(ds.attrs.get("overrides", "") or "{}")).get(key, value)


def ekf_figures(ds: xr.Dataset, fig_dir: Path, *, format: str = "png") -> list[Path]:
    """003 Figs 7–12 from an ``ekf`` study: component errors of one run (Figs 7–8) and ``typical_runs``
    runs of the attitude and rate errors per case (Figs 9–12).

    The attitude error is the rotation angle (flag P003-14, docs/papers.md#p003-14): 003 eq (36) on 3-2-1 Euler angles
    is kept in the dataset (``euler_error_deg``) but blows up near pitch ±90° (gimbal lock).
    """
    check_format(format)
    paths: list[Path] = []
    t = ds["time_s"].values
    th_a = float(ds.attrs.get("threshold_attitude_deg", np.nan))
    th_r = float(ds.attrs.get("threshold_rate_deg_s", np.nan))
    ntyp = int(ds.attrs.get("typical_runs", 10))
    for i, case in enumerate(ds["case"].values.tolist()):
        c = ds.sel(case=case)
        fig, axes = plt.subplots(1, 2, figsize=(12.0, 3.8), layout="constrained")
        plot_time_series(t, c["quat_error"].isel(run=0).values.T, ax=axes[0], labels=["q0", "q1", "q2", "q3"],
                         ylabel="quaternion error", title=f"{case}: quaternion error of run 0")
        axes[0].set_ylim(-0.02, 0.02)
        plot_time_series(t, c["rate_error_components_deg_s"].isel(run=0).values.T, ax=axes[1],
                         labels=["x", "y", "z"], threshold=th_r, symmetric_threshold=True,
                         threshold_label="convergence threshold",
                         ylabel="rate error [deg/s]", title=f"{case}: rate error of run 0")
        axes[1].set_ylim(-10 * th_r, 10 * th_r)
        paths.append(save(fig, figure_path(fig_dir, f"ekf_single_run_{i}_{_slug(case)}", format)))
        fig, axes = plt.subplots(1, 2, figsize=(12.0, 3.8), layout="constrained")
        n = min(ntyp, c.sizes["run"])
        conv = float(c["converged"].mean())
        plot_time_series(t, c["attitude_error_deg"].isel(run=slice(0, n)).values, ax=axes[0], threshold=th_a,
                         logy=True, ylabel="attitude error (rotation angle) [deg]", alpha=0.8, linewidth=0.8,
                         threshold_label="convergence threshold", legend=False,
                         title=f"{case}: {n} runs, {conv:.0%} of {c.sizes['run']} converged")
        plot_time_series(t, c["rate_error_deg_s"].isel(run=slice(0, n)).values, ax=axes[1], threshold=th_r,
                         logy=True, ylabel="rate error e_omega (003 eq 37) [deg/s]", alpha=0.8, linewidth=0.8,
                         threshold_label="convergence threshold", legend=False, title=f"{case}: rate error")
        if np.isfinite(th_a) or np.isfinite(th_r):
            legend_below(fig)
        paths.append(save(fig, figure_path(fig_dir, f"ekf_runs_{i}_{_slug(case)}", format)))
    return paths


def _slug(s: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in str(s)).strip("_")


def error_map_run_figures(ds: xr.Dataset, fig_dir: Path, *, format: str = "png") -> list[Path]:
    """One Experiment A cell: distributions of e_Δθ and of the per-step error with the CRLB."""
    check_format(format)
    fig, axes = plt.subplots(1, 2, figsize=(10.5, 4.2), layout="constrained")
    a = ds.attrs
    plot_histogram(ds["e_dtheta_deg"].values, ax=axes[0], xlabel="e_dtheta (003 eq 33) [deg]", legend=False,
                   label=f"e_dtheta: {a.get('n_views')} views, {a.get('distance_m')} m, {a.get('axis_angle_deg')} deg")
    plot_histogram(ds["step_rms_deg"].values, ax=axes[1], xlabel="per-step RMS error [deg]", label="per-step RMS",
                   vline=float(np.nanmedian(ds["crlb_deg"].values)), vline_label="Cramer-Rao bound (median)",
                   legend=False)
    legend_below(fig)
    return [save(fig, figure_path(fig_dir, "error_map_cell", format))]


def _shade_epochs(ax, ds: xr.Dataset) -> None:
    t = ds["time_s"].values
    shade_spans(ax, t, ds["illumination"].values <= 0.0, color=ECLIPSE_COLOR, hatch=ECLIPSE_HATCH,
                label="target in Earth's shadow")
    if "measurement_ok" in ds:
        ok = np.asarray(ds["measurement_ok"].values, dtype=bool)
        shade_spans(ax, t, ~ok & (ds["illumination"].values > 0.0), color=GAP_COLOR, alpha=0.35,
                    label="no increment used (lit)")


def closed_loop_figures(ds: xr.Dataset, fig_dir: Path, *, format: str = "png") -> list[Path]:
    """Truth vs estimate (attitude, rate), errors over time with the filter's 3σ and the epochs without a
    measurement, errors per body axis with ±3σ, active observers, a frame per camera with its tracks, and
    the reconstructed cloud (coloured by triangulation σ, truth overlaid)."""
    check_format(format)
    paths: list[Path] = []
    t = ds["time_s"].values
    fig, axes = plt.subplots(2, 1, figsize=(10.0, 6.5), layout="constrained", sharex=True)
    qt, qe = ds["q_NT_true"].values, ds["q_NT_est"].values
    sign = np.sign(np.sum(qt * qe, -1, keepdims=True))
    qe = qe * np.where(sign == 0, 1, sign)
    for j, comp in enumerate(ds["quat_component"].values.tolist()):
        (line,) = axes[0].plot(t, qt[:, j], linewidth=1.0, label=f"{comp} truth")
        axes[0].plot(t, qe[:, j], "--", color=line.get_color(), linewidth=1.0, label=f"{comp} estimate")
    axes[0].set_ylabel("q_NT")
    legend_right(axes[0])
    axes[0].set_title("attitude: truth (solid) and estimate (dashed)")
    for j, ax_name in enumerate(ds["axis"].values.tolist()):
        (line,) = axes[1].plot(t, ds["omega_true_deg_s"].values[:, j], linewidth=1.0, label=f"{ax_name} truth")
        axes[1].plot(t, ds["omega_est_deg_s"].values[:, j], "--", color=line.get_color(), linewidth=1.0,
                     label=f"{ax_name} estimate")
    axes[1].set_ylabel("body rate [deg/s]")
    axes[1].set_xlabel("time [s]")
    legend_right(axes[1])
    paths.append(save(fig, figure_path(fig_dir, "truth_vs_estimate", format)))

    paths.append(save(_errors_figure(ds), figure_path(fig_dir, "errors", format)))
    if "attitude_sigma_deg" in ds and "attitude_error_T_deg" in ds:
        paths.append(save(_axis_errors_figure(ds), figure_path(fig_dir, "errors_axes", format)))

    fig, ax = plt.subplots(figsize=(10.0, 1.0 + 0.35 * ds.sizes["spacecraft"]), layout="constrained")
    plot_timeline(t, ds["active"].values, ds["spacecraft"].values.tolist(), ax=ax,
                  shade=ds["illumination"].values <= 0.0, shade_label="target in Earth's shadow")
    paths.append(save(fig, figure_path(fig_dir, "active_observers", format)))

    if "snapshot_image" in ds:
        views = ds["snapshot_view"].values.tolist()
        fig, axes = plt.subplots(1, len(views), figsize=(4.0 * len(views), 4.0), layout="constrained",
                                 squeeze=False)
        for i, v in enumerate(views):
            plot_image_tracks(ds["snapshot_image"].values[i], ds["snapshot_uv_px"].values[:, i],
                              ds["snapshot_track_correct"].values, ax=axes[0, i],
                              title=f"{ds['spacecraft'].values[v]} at t = {ds.attrs.get('snapshot_time_s', 0):g} s "
                                    "(green: correct track, red: false)")
        paths.append(save(fig, figure_path(fig_dir, "frames_with_tracks", format)))
        valid = ds["snapshot_point_valid"].values
        X = ds["snapshot_X_W_m"].values[valid]
        sigma_mm = 1e3 * ds["snapshot_sigma_m"].values[valid] if "snapshot_sigma_m" in ds else None
        truth = ds["snapshot_X_true_H_m"].values[valid] if "snapshot_X_true_H_m" in ds else None
        ax = plot_cloud(X, values=sigma_mm, values_label="triangulation σ [mm]" if sigma_mm is not None else "",
                        truth=truth, title=f"reconstructed cloud, {len(X)} points (H frame)")
        paths.append(save(ax.figure, figure_path(fig_dir, "reconstructed_cloud", format)))
    return paths


def _errors_figure(ds: xr.Dataset):
    """Attitude and rate error (log) with the filter's 3σ bound, thresholds, and the increments; eclipse
    and epochs without an increment shaded; one legend below."""
    t = ds["time_s"].values
    fig, axes = plt.subplots(3, 1, figsize=(10.0, 8.0), layout="constrained", sharex=True)
    floor = 1e-4
    for ax, err, sig, th, ylab in (
            (axes[0], "attitude_error_deg", "attitude_sigma_deg", "threshold_attitude_deg", "attitude error [deg]"),
            (axes[1], "rate_error_deg_s", "rate_sigma_deg_s", "threshold_rate_deg_s", "rate error [deg/s]")):
        _shade_epochs(ax, ds)
        if sig in ds:
            bound = 3.0 * np.sqrt(np.sum(ds[sig].values ** 2, axis=-1))
            plot_envelope(t, np.maximum(bound, floor), ax=ax, floor=floor,
                          label="smoother 3σ bound (iSAM2 marginals)" if ds.attrs.get("filter") == "smoother"
                          else "filter 3σ bound, 3·sqrt(trace P)")
        plot_time_series(t, ds[err].values, ax=ax, logy=True, threshold=float(ds.attrs.get(th, np.nan)),
                         threshold_label="convergence threshold", ylabel=ylab, xlabel="", legend=False,
                         labels=["error (estimate vs truth)"], colors=["#440154"])
        ax.set_ylim(bottom=floor)
    axes[0].set_title("estimation errors")
    _shade_epochs(axes[2], ds)
    plot_time_series(t, np.stack([ds["increment_error_deg"].values, ds["increment_sigma_deg"].values]),
                     ax=axes[2], logy=True, labels=["registered increment error", "increment σ given to the filter"],
                     ylabel="increment [deg]", legend=False, colors=["#3b528b", "#e16462"])
    legend_below(fig, ncol=3)
    return fig


def _axis_errors_figure(ds: xr.Dataset):
    """Signed attitude and rate error per body axis inside the filter's ±3σ; shading as in the errors figure."""
    t = ds["time_s"].values
    fig, axes = plt.subplots(2, 3, figsize=(12.0, 5.8), layout="constrained", sharex=True)
    for r, (err, sig, unit, what) in enumerate((("attitude_error_T_deg", "attitude_sigma_deg", "deg", "attitude"),
                                                ("rate_error_T_deg_s", "rate_sigma_deg_s", "deg/s", "rate"))):
        for c, name in enumerate(ds["axis"].values.tolist()):
            ax = axes[r, c]
            _shade_epochs(ax, ds)
            bound = 3.0 * ds[sig].values[:, c]
            plot_envelope(t, bound, ax=ax, label="filter ±3σ")
            ax.plot(t, ds[err].values[:, c], color="#440154", linewidth=0.9, label="error (estimate vs truth)")
            fin = np.abs(ds[err].values[:, c])
            fin = fin[np.isfinite(fin)]
            lim = 1.5 * float(np.percentile(fin, 98)) if fin.size else 1.0
            ax.set_ylim(-lim, lim)
            ax.set_ylabel(f"{what} error, {name}_T [{unit}]")
            if r == 1:
                ax.set_xlabel("time [s]")
    fig.suptitle("errors per body axis and the filter's ±3σ (tangent covariance)")
    legend_below(fig, ncol=4)
    return fig
