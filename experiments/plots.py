"""Figures drawn from stored results (matplotlib, Agg).

Plot functions take ``ax=None`` (a new figure when omitted), return the axes, and compute nothing:
the figure drivers (``*_figures``) select and reduce the stored dataset, then call them.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

__all__ = [
    "plot_map",
    "plot_band",
    "sweep_overview_figures",
    "save",
]


def _axes(ax):
    if ax is None:
        _, ax = plt.subplots(figsize=(5.0, 4.0), layout="constrained")
    return ax


def _edges(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, dtype=float)
    if c.size == 1:
        return np.array([c[0] - 0.5, c[0] + 0.5])
    mid = 0.5 * (c[1:] + c[:-1])
    return np.concatenate([[c[0] - (mid[0] - c[0])], mid, [c[-1] + (c[-1] - mid[-1])]])


def plot_map(values: np.ndarray, x: np.ndarray, y: np.ndarray, *, ax=None, vmin: float | None = None,
             vmax: float | None = None, cmap: str = "viridis", xlabel: str = "", ylabel: str = "",
             title: str = "", cbar_label: str = "", annotate: bool = False, fmt: str = "{:.2f}"):
    """Colour map of ``values[len(y), len(x)]`` on cell-centred coordinates; NaN cells stay blank.

    Parameters
    ----------
    values : ndarray, shape (ny, nx)
        The map (already reduced over trials by the caller).
    x, y : ndarray
        Cell-centre coordinates along the horizontal and vertical axes.
    annotate : bool
        Write each cell's value in the cell.
    """
    ax = _axes(ax)
    v = np.ma.masked_invalid(np.asarray(values, dtype=float))
    mesh = ax.pcolormesh(_edges(x), _edges(y), v, cmap=cmap, vmin=vmin, vmax=vmax, shading="flat")
    cb = ax.figure.colorbar(mesh, ax=ax)
    cb.set_label(cbar_label)
    if annotate and v.size <= 400:
        for j, yy in enumerate(y):
            for i, xx in enumerate(x):
                if not np.ma.is_masked(v[j, i]):
                    ax.text(xx, yy, fmt.format(float(v[j, i])), ha="center", va="center", fontsize=6,
                            color="w" if vmax is not None and v[j, i] < 0.5 * (vmax + (vmin or 0)) else "k")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    return ax


def plot_band(x: np.ndarray, center: np.ndarray, lo: np.ndarray | None = None, hi: np.ndarray | None = None,
              *, ax=None, label: str = "", xlabel: str = "", ylabel: str = "", title: str = "",
              color: str | None = None):
    """A line with an optional shaded band ``[lo, hi]`` (e.g. median and interquartile range)."""
    ax = _axes(ax)
    (line,) = ax.plot(x, center, label=label, color=color)
    if lo is not None and hi is not None:
        ax.fill_between(x, lo, hi, color=line.get_color(), alpha=0.25, linewidth=0)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    if label:
        ax.legend()
    return ax


def save(fig, path: Path) -> Path:
    """Save a figure as PNG (150 dpi) and close it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return path


def _label(ds: xr.Dataset, name: str) -> str:
    var = ds[name]
    units = var.attrs.get("units", "")
    return f"{name} [{units}]" if units else name


def sweep_overview_figures(ds: xr.Dataset, fig_dir: Path, *, swept: Sequence[str] | None = None) -> list[Path]:
    """Generic sweep figures: for each metric, its trial mean over the swept parameters.

    One swept parameter: mean with the 10–90 % band over trials.  Two or more: a colour map over
    the first two, one panel per value of the third (further ones at their first value).
    """
    swept = list(swept) if swept is not None else list(ds["done"].dims)
    keys = json.loads(ds.attrs.get("swept_keys", "[]"))
    paths: list[Path] = []
    for name, var in ds.data_vars.items():
        if name in ("failure_reason", "done"):
            continue
        extra = [d for d in var.dims if d not in swept and d != "trial"]
        if extra:
            var = var.isel({d: -1 for d in extra})
        has_trial = "trial" in var.dims
        mean = var.mean("trial", skipna=True) if has_trial else var
        if len(swept) == 1:
            fig, ax = plt.subplots(figsize=(5.5, 4.0), layout="constrained")
            x = ds[swept[0]].values
            lo = var.quantile(0.1, "trial", skipna=True).values if has_trial else None
            hi = var.quantile(0.9, "trial", skipna=True).values if has_trial else None
            plot_band(x, mean.values, lo, hi, ax=ax, xlabel=keys[0] if keys else swept[0],
                      ylabel=_label(ds, name), title=f"{name}: trial mean, 10-90 % band")
        else:
            third = swept[2] if len(swept) > 2 else None
            mean = mean.isel({d: 0 for d in swept[3:]})
            panels = list(ds[third].values) if third else [None]
            fig, axes = plt.subplots(1, len(panels), figsize=(5.0 * len(panels), 4.0), layout="constrained",
                                     squeeze=False)
            finite = mean.values[np.isfinite(mean.values)]
            vmin, vmax = (float(finite.min()), float(finite.max())) if finite.size else (None, None)
            for ax, p in zip(axes[0], panels, strict=True):
                m = mean.sel({third: p}) if third else mean
                m = m.transpose(swept[1], swept[0])
                plot_map(m.values, ds[swept[0]].values, ds[swept[1]].values, ax=ax, vmin=vmin, vmax=vmax,
                         xlabel=swept[0], ylabel=swept[1], cbar_label=_label(ds, name),
                         title=f"{name} (trial mean)" + (f", {third} = {p}" if third else ""))
        paths.append(save(fig, fig_dir / f"sweep_{name}.png"))
    return paths


# ============================================================================= 003 (formation) figures

#: colour range of 003 Figs 5–6, degrees
ERROR_MAP_RANGE_DEG = (0.0, 1.6)


def plot_time_series(t: np.ndarray, series: np.ndarray, *, ax=None, labels: Sequence[str] | None = None,
                     threshold: float | None = None, symmetric_threshold: bool = False, logy: bool = False,
                     xlabel: str = "time [s]", ylabel: str = "", title: str = "", alpha: float = 1.0,
                     linewidth: float = 1.0):
    """Lines ``series[..., T]`` (one per row) against ``t``; optional threshold line(s)."""
    ax = _axes(ax)
    s = np.atleast_2d(np.asarray(series, dtype=float))
    for i, row in enumerate(s):
        ax.plot(t, row, label=None if labels is None else labels[i], alpha=alpha, linewidth=linewidth)
    if threshold is not None:
        ax.axhline(threshold, color="k", linestyle="--", linewidth=0.8)
        if symmetric_threshold:
            ax.axhline(-threshold, color="k", linestyle="--", linewidth=0.8)
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    if labels is not None:
        ax.legend(fontsize=7, ncol=min(4, len(labels)))
    return ax


def plot_timeline(t: np.ndarray, active: np.ndarray, names: Sequence[str], *, ax=None, title: str = "",
                  shade: np.ndarray | None = None, shade_label: str = ""):
    """Active-observer timeline: one row per observer, filled where ``active[T, S]``; epochs where
    ``shade[T]`` is true (e.g. Earth's shadow) are shaded grey."""
    ax = _axes(ax)
    a = np.asarray(active, dtype=bool)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    if shade is not None:
        sh = np.asarray(shade, dtype=bool)
        starts = np.flatnonzero(sh & ~np.r_[False, sh[:-1]])
        ends = np.flatnonzero(sh & ~np.r_[sh[1:], False])
        for n_span, (i, j) in enumerate(zip(starts, ends, strict=True)):
            ax.axvspan(t[i], t[j] + dt, color="0.85", zorder=0, label=shade_label if n_span == 0 else None)
        if shade_label and starts.size:
            ax.legend(loc="upper right", fontsize=7)
    for s in range(a.shape[1]):
        on = a[:, s]
        starts = np.flatnonzero(on & ~np.r_[False, on[:-1]])
        ends = np.flatnonzero(on & ~np.r_[on[1:], False])
        ax.broken_barh([(t[i], t[j] - t[i] + dt) for i, j in zip(starts, ends, strict=True)], (s - 0.4, 0.8))
    ax.set_yticks(range(a.shape[1]))
    ax.set_yticklabels(list(names))
    ax.set_xlabel("time [s]")
    ax.set_title(title or "active observers")
    return ax


def plot_image_tracks(image: np.ndarray, uv_px: np.ndarray, correct: np.ndarray | None = None, *, ax=None,
                      title: str = ""):
    """An image with its track positions (green: correct per ground truth, red: false match)."""
    ax = _axes(ax)
    ax.imshow(image, cmap="gray", vmin=0, vmax=255)
    uv = np.asarray(uv_px, dtype=float)
    ok = np.isfinite(uv).all(-1)
    c = np.ones(len(uv), bool) if correct is None else np.asarray(correct, bool)
    ax.scatter(uv[ok & c, 0], uv[ok & c, 1], s=4, c="lime", linewidths=0)
    ax.scatter(uv[ok & ~c, 0], uv[ok & ~c, 1], s=6, c="red", linewidths=0)
    if ok.any():
        pad = 40
        ax.set_xlim(max(uv[ok, 0].min() - pad, 0), min(uv[ok, 0].max() + pad, image.shape[1]))
        ax.set_ylim(min(uv[ok, 1].max() + pad, image.shape[0]), max(uv[ok, 1].min() - pad, 0))
    ax.set_axis_off()
    ax.set_title(title, fontsize=8)
    return ax


def plot_cloud(X: np.ndarray, *, ax=None, title: str = "", color=None):
    """3-D scatter of a point cloud ``X (N, 3)`` (metres), equal axes."""
    if ax is None:
        fig = plt.figure(figsize=(5.0, 4.5), layout="constrained")
        ax = fig.add_subplot(projection="3d")
    X = np.asarray(X, dtype=float)
    ax.scatter(X[:, 0], X[:, 1], X[:, 2], s=2, c=color if color is not None else X[:, 2], cmap="viridis")
    span = np.nanmax(np.ptp(X, axis=0)) if len(X) else 1.0
    mid = np.nanmean(X, axis=0) if len(X) else np.zeros(3)
    for set_lim, m in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), mid, strict=True):
        set_lim(m - span / 2, m + span / 2)
    ax.set_xlabel("x_H [m]")
    ax.set_ylabel("y_H [m]")
    ax.set_zlabel("z_H [m]")
    ax.set_title(title)
    return ax


def plot_histogram(values: np.ndarray, *, ax=None, bins: int = 30, label: str = "", xlabel: str = "",
                   vline: float | None = None, vline_label: str = ""):
    """Histogram of finite ``values`` with an optional reference line."""
    ax = _axes(ax)
    v = np.asarray(values, dtype=float)
    ax.hist(v[np.isfinite(v)], bins=bins, alpha=0.6, label=label)
    if vline is not None and np.isfinite(vline):
        ax.axvline(vline, color="k", linestyle="--", label=vline_label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("trials")
    ax.legend(fontsize=7)
    return ax


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

    The attitude error is the rotation angle (SEEDS_SPEC §3.7): 003 eq (36) on 3-2-1 Euler angles
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
