"""Figures of the formation scenario (003), drawn from stored results with the primitives of
:mod:`experiments.plotting`: error and convergence maps, EKF runs, one Experiment A cell, the closed loop.

Each ``*_figures`` function selects and reduces the stored dataset, draws, and returns the paths of
the PNG files it wrote into ``fig_dir``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

from experiments.plotting import (  # noqa: E402
    plot_cloud,
    plot_histogram,
    plot_image_tracks,
    plot_map,
    plot_time_series,
    plot_timeline,
    save,
    sweep_overview_figures,
)

__all__ = [
    "error_map_figures",
    "convergence_map_figures",
    "sweep_figures",
    "ekf_figures",
    "error_map_run_figures",
    "closed_loop_figures",
]


#: colour range of 003 Figs 5–6, degrees
ERROR_MAP_RANGE_DEG = (0.0, 1.6)


def _combos(ds: xr.Dataset, dims: Sequence[str]) -> list[dict]:
    if not dims:
        return [{}]
    vals = [ds[d].values.tolist() for d in dims]
    import itertools

    return [dict(zip(dims, c, strict=True)) for c in itertools.product(*vals)]


def _suffix(sel: dict) -> str:
    return "".join(f"_{k}-{v}" for k, v in sel.items()).replace(" ", "").replace("/", "-")


def error_map_figures(ds: xr.Dataset, fig_dir: Path) -> list[Path]:
    """003 Figs 5–6: median e_Δθ over the trials per (distance, axis angle), a row per number of views,
    with the Cramér–Rao map (median bound of one increment) and the per-step RMS error beside it."""
    paths: list[Path] = []
    x, y = "distance_m", "axis_angle_deg"
    views = ds["n_views"].values.tolist() if "n_views" in ds.dims else [None]
    other = [d for d in ds["done"].dims if d not in (x, y, "n_views")]
    e = ds["e_dtheta_deg"].median("trial", skipna=True)
    step = ds["step_rms_deg"].median("trial", skipna=True)
    crlb = ds["crlb_deg"].median("trial", skipna=True)
    for sel in _combos(ds, other):
        fig, axes = plt.subplots(len(views), 3, figsize=(15.0, 3.8 * len(views)), layout="constrained",
                                 squeeze=False)
        for r, nv in enumerate(views):
            s = {**sel, **({"n_views": nv} if nv is not None else {})}
            tag = f"{nv} views" if nv is not None else ""
            for c, (da, what) in enumerate(((e, "e_dtheta (003 eq 33), median"),
                                            (step, "per-step RMS error, median"),
                                            (crlb, "Cramer-Rao bound per step, median"))):
                m = da.sel(s).transpose(y, x)
                plot_map(m.values, ds[x].values, ds[y].values, ax=axes[r, c], vmin=ERROR_MAP_RANGE_DEG[0],
                         vmax=ERROR_MAP_RANGE_DEG[1], cmap="jet" if c < 2 else "viridis",
                         xlabel="distance [m]", ylabel="line-of-sight angle [deg]", cbar_label="deg",
                         title=f"{tag}: {what}", annotate=True)
        extra = ", ".join(f"{k} = {v}" for k, v in sel.items())
        fig.suptitle(f"Experiment A error maps (003 Figs 5-6){' - ' + extra if extra else ''}")
        paths.append(save(fig, fig_dir / f"error_maps{_suffix(sel)}.png"))
    return paths


def convergence_map_figures(ds: xr.Dataset, fig_dir: Path, *, frac: xr.DataArray, tmed: xr.DataArray,
                            name: str, title: str) -> list[Path]:
    """Fraction of converged runs and median convergence time per (distance, angle), a row per view count."""
    paths: list[Path] = []
    x, y = "distance_m", "axis_angle_deg"
    views = ds["n_views"].values.tolist() if "n_views" in ds.dims else [None]
    other = [d for d in ds["done"].dims if d not in (x, y, "n_views")]
    for sel in _combos(ds, other):
        fig, axes = plt.subplots(len(views), 2, figsize=(10.5, 3.8 * len(views)), layout="constrained",
                                 squeeze=False)
        for r, nv in enumerate(views):
            s = {**sel, **({"n_views": nv} if nv is not None else {})}
            tag = f"{nv} views: " if nv is not None else ""
            plot_map(frac.sel(s).transpose(y, x).values, ds[x].values, ds[y].values, ax=axes[r, 0], vmin=0,
                     vmax=1, cmap="RdYlGn", xlabel="distance [m]", ylabel="line-of-sight angle [deg]",
                     cbar_label="fraction", title=f"{tag}fraction converged", annotate=True)
            plot_map(tmed.sel(s).transpose(y, x).values, ds[x].values, ds[y].values, ax=axes[r, 1],
                     cmap="viridis_r", xlabel="distance [m]", ylabel="line-of-sight angle [deg]",
                     cbar_label="s", title=f"{tag}median convergence time", annotate=True, fmt="{:.1f}")
        extra = ", ".join(f"{k} = {v}" for k, v in sel.items())
        fig.suptitle(title + (f" - {extra}" if extra else ""))
        paths.append(save(fig, fig_dir / f"{name}{_suffix(sel)}.png"))
    return paths


def sweep_figures(ds: xr.Dataset, fig_dir: Path) -> list[Path]:
    """Figures of a formation sweep: error maps, convergence maps, or the generic overview."""
    cell = ds.attrs.get("cell", "")
    grid = set(ds["done"].dims)
    paths: list[Path] = []
    if cell == "error_map" and {"distance_m", "axis_angle_deg"} <= grid:
        paths += error_map_figures(ds, fig_dir)
        if np.isfinite(ds["filter_fraction_converged"].values).any():
            paths += convergence_map_figures(
                ds, fig_dir, frac=ds["filter_fraction_converged"], tmed=ds["filter_median_convergence_time_s"],
                name="convergence_maps_filter",
                title="EKF convergence driven by each cell's measured registration error (003 Figs 11-12 approach)")
        return paths
    if cell == "closed_loop" and {"distance_m", "axis_angle_deg"} <= grid:
        frac = ds["converged"].mean("trial", skipna=True)
        tmed = ds["convergence_time_s"].median("trial", skipna=True)
        return convergence_map_figures(ds, fig_dir, frac=frac, tmed=tmed, name="convergence_maps_closed_loop",
                                       title="Closed loop end to end (observation - registration - EKF)")
    return sweep_overview_figures(ds, fig_dir)


def ekf_figures(ds: xr.Dataset, fig_dir: Path) -> list[Path]:
    """003 Figs 7–12 from an ``ekf`` study: component errors of one run (Figs 7–8) and ``typical_runs``
    runs of the attitude and rate errors per case (Figs 9–12).

    The attitude error is the rotation angle (flag P003-14, docs/papers.md#p003-14): 003 eq (36) on 3-2-1 Euler angles
    is kept in the dataset (``euler_error_deg``) but blows up near pitch ±90° (gimbal lock).
    """
    paths: list[Path] = []
    t = ds["time_s"].values
    th_a = float(ds.attrs.get("threshold_attitude_deg", np.nan))
    th_r = float(ds.attrs.get("threshold_rate_deg_s", np.nan))
    ntyp = int(ds.attrs.get("typical_runs", 10))
    for i, case in enumerate(ds["case"].values.tolist()):
        c = ds.sel(case=case)
        fig, axes = plt.subplots(1, 2, figsize=(11.0, 3.8), layout="constrained")
        plot_time_series(t, c["quat_error"].isel(run=0).values.T, ax=axes[0], labels=["q0", "q1", "q2", "q3"],
                         ylabel="quaternion error", title=f"{case}: quaternion error of run 0")
        axes[0].set_ylim(-0.02, 0.02)
        plot_time_series(t, c["rate_error_components_deg_s"].isel(run=0).values.T, ax=axes[1],
                         labels=["x", "y", "z"], threshold=th_r, symmetric_threshold=True,
                         ylabel="rate error [deg/s]", title=f"{case}: rate error of run 0")
        axes[1].set_ylim(-10 * th_r, 10 * th_r)
        paths.append(save(fig, fig_dir / f"ekf_single_run_{i}_{_slug(case)}.png"))
        fig, axes = plt.subplots(1, 2, figsize=(11.0, 3.8), layout="constrained")
        n = min(ntyp, c.sizes["run"])
        conv = float(c["converged"].mean())
        plot_time_series(t, c["attitude_error_deg"].isel(run=slice(0, n)).values, ax=axes[0], threshold=th_a,
                         logy=True, ylabel="attitude error [deg] (rotation angle)", alpha=0.8, linewidth=0.8,
                         title=f"{case}: {n} runs, {conv:.0%} of {c.sizes['run']} converged")
        plot_time_series(t, c["rate_error_deg_s"].isel(run=slice(0, n)).values, ax=axes[1], threshold=th_r,
                         logy=True, ylabel="e_omega [deg/s] (003 eq 37)", alpha=0.8, linewidth=0.8,
                         title=f"{case}: rate error")
        paths.append(save(fig, fig_dir / f"ekf_runs_{i}_{_slug(case)}.png"))
    return paths


def _slug(s: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in str(s)).strip("_")


def error_map_run_figures(ds: xr.Dataset, fig_dir: Path) -> list[Path]:
    """One Experiment A cell: distributions of e_Δθ and of the per-step error with the CRLB."""
    fig, axes = plt.subplots(1, 2, figsize=(10.5, 3.8), layout="constrained")
    a = ds.attrs
    plot_histogram(ds["e_dtheta_deg"].values, ax=axes[0], xlabel="e_dtheta [deg] (003 eq 33)",
                   label=f"{a.get('n_views')} views, {a.get('distance_m')} m, {a.get('axis_angle_deg')} deg")
    plot_histogram(ds["step_rms_deg"].values, ax=axes[1], xlabel="per-step RMS error [deg]", label="measured",
                   vline=float(np.nanmedian(ds["crlb_deg"].values)), vline_label="Cramer-Rao bound (median)")
    return [save(fig, fig_dir / "error_map_cell.png")]


def closed_loop_figures(ds: xr.Dataset, fig_dir: Path) -> list[Path]:
    """Truth vs estimate (attitude, rate), errors over time, active observers, a frame per camera with
    its tracks, and the reconstructed cloud."""
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
    axes[0].legend(fontsize=7, ncol=4)
    axes[0].set_title("attitude: truth (solid) and estimate (dashed)")
    for j, ax_name in enumerate(ds["axis"].values.tolist()):
        (line,) = axes[1].plot(t, ds["omega_true_deg_s"].values[:, j], linewidth=1.0, label=f"{ax_name} truth")
        axes[1].plot(t, ds["omega_est_deg_s"].values[:, j], "--", color=line.get_color(), linewidth=1.0,
                     label=f"{ax_name} estimate")
    axes[1].set_ylabel("body rate [deg/s]")
    axes[1].set_xlabel("time [s]")
    axes[1].legend(fontsize=7, ncol=3)
    paths.append(save(fig, fig_dir / "truth_vs_estimate.png"))

    fig, axes = plt.subplots(3, 1, figsize=(10.0, 7.5), layout="constrained", sharex=True)
    plot_time_series(t, ds["attitude_error_deg"].values, ax=axes[0], logy=True,
                     threshold=float(ds.attrs.get("threshold_attitude_deg", np.nan)),
                     ylabel="attitude error [deg]", xlabel="", title="estimation errors")
    axes[0].set_ylim(bottom=1e-4)
    plot_time_series(t, ds["rate_error_deg_s"].values, ax=axes[1], logy=True,
                     threshold=float(ds.attrs.get("threshold_rate_deg_s", np.nan)),
                     ylabel="rate error [deg/s]", xlabel="")
    plot_time_series(t, np.stack([ds["increment_error_deg"].values, ds["increment_sigma_deg"].values]),
                     ax=axes[2], logy=True, labels=["registered increment error", "sigma given to the filter"],
                     ylabel="increment [deg]")
    paths.append(save(fig, fig_dir / "errors.png"))

    fig, ax = plt.subplots(figsize=(10.0, 1.0 + 0.35 * ds.sizes["spacecraft"]), layout="constrained")
    plot_timeline(t, ds["active"].values, ds["spacecraft"].values.tolist(), ax=ax,
                  shade=ds["illumination"].values < 0.5, shade_label="target in Earth's shadow")
    paths.append(save(fig, fig_dir / "active_observers.png"))

    if "snapshot_image" in ds:
        views = ds["snapshot_view"].values.tolist()
        fig, axes = plt.subplots(1, len(views), figsize=(4.0 * len(views), 4.0), layout="constrained",
                                 squeeze=False)
        for i, v in enumerate(views):
            plot_image_tracks(ds["snapshot_image"].values[i], ds["snapshot_uv_px"].values[:, i],
                              ds["snapshot_track_correct"].values, ax=axes[0, i],
                              title=f"{ds['spacecraft'].values[v]} at t = {ds.attrs.get('snapshot_time_s', 0):g} s "
                                    "(green: correct track, red: false)")
        paths.append(save(fig, fig_dir / "frames_with_tracks.png"))
        X = ds["snapshot_X_W_m"].values[ds["snapshot_point_valid"].values]
        ax = plot_cloud(X, title=f"reconstructed cloud, {len(X)} points (H frame)")
        paths.append(save(ax.figure, fig_dir / "reconstructed_cloud.png"))
    return paths
