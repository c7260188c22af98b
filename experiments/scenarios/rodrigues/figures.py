"""Figures of a ``rodrigues_001`` run, drawn from its stored dataset only."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

__all__ = ["plot"]


def plot(dataset: xr.Dataset, fig_dir: Path, *, format: str = "png") -> list[Path]:
    """Figures like 001 Figs 1–2 (position and attitude errors), the comparison and the switching.

    ``format``: ``"png"``, ``"pdf"`` or ``"svg"``.  Legends sit below the panels, never over data.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from experiments.plotting import check_format, figure_path, legend_below, save

    check_format(format)

    ds = dataset
    t = ds["time_s"].values
    fail_ns = t[ds["ok"].sel(solver="non_switching").values == 0]
    t_fail = fail_ns[0] if fail_ns.size else None
    paths = []

    def _series(ax, y_sw, y_ns, ylabel):
        ax.plot(t, y_ns, color="tab:orange", lw=0.8, label="non-switching (set 0)")
        ax.plot(t, y_sw, color="tab:blue", lw=0.6, label="switching")
        if t_fail is not None:
            ax.axvline(t_fail, color="k", ls="--", lw=0.8, label="non-switching solver fails")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        return ax

    # Fig 1: position error in the chaser Hill frame (paper X = along-track = line of sight)
    fig, axes = plt.subplots(3, 1, figsize=(7.0, 7.0), sharex=True, layout="constrained")
    for ax, a, lab in zip(axes, ("along_track", "radial", "cross_track"),
                          ("along-track / LOS (paper X) [m]", "radial [m]", "cross-track [m]"), strict=True):
        e = ds["position_error_H"].sel(hill_axis=a)
        _series(ax, e.sel(solver="switching").values, e.sel(solver="non_switching").values, lab)
    legend_below(fig, ncol=3)
    axes[0].set_title("001 Fig 1: position error, chaser Hill frame"
                      + (f"; non-switching fails at {t_fail:.0f} s" if t_fail is not None else ""), fontsize=10)
    axes[-1].set_xlabel("time [s]")
    paths.append(save(fig, figure_path(fig_dir, "fig1_position_error", format)))

    # Fig 2: attitude error, 3-2-1 Euler angles of R_CT
    fig, axes = plt.subplots(3, 1, figsize=(7.0, 7.0), sharex=True, layout="constrained")
    for ax, e in zip(axes, ("yaw", "pitch", "roll"), strict=True):
        v = ds["attitude_error_euler"].sel(euler=e)
        _series(ax, v.sel(solver="switching").values, v.sel(solver="non_switching").values, f"{e} [deg]")
    legend_below(fig, ncol=3)
    axes[0].set_title("001 Fig 2: attitude error, 3-2-1 Euler angles of R_CT (the two solvers agree until"
                      " the failure)", fontsize=10)
    axes[-1].set_xlabel("time [s]")
    paths.append(save(fig, figure_path(fig_dir, "fig2_attitude_error", format)))

    # Fig 3: the relative rotation angle and the active Gibbs parameter set
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7.0, 4.5), sharex=True, layout="constrained")
    a1.plot(t, ds["relative_angle_deg"].values, color="k", lw=0.8)
    a1.axhline(180.0, color="grey", ls=":")
    if np.isfinite(ds.attrs.get("crossing_time_s", np.nan)):
        a1.axvline(ds.attrs["crossing_time_s"], color="tab:red", ls="--", lw=0.8,
                   label=f"180° at {ds.attrs['crossing_time_s']:.2f} s")
        a1.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    a1.set_ylabel("angle of R_CT [deg]")
    a2.step(t, ds["gibbs_set"].sel(variant="switching").values, where="post", lw=0.8)
    a2.set_yticks([0, 1, 2, 3])
    a2.set_ylabel("Gibbs set i")
    a2.set_xlabel("time [s]")
    paths.append(save(fig, figure_path(fig_dir, "fig3_rotation_and_switching", format)))

    # Fig 4: accuracy and time of the solvers on the same frames
    solvers = [s for s in ds["solver"].values if not np.all(ds["failure_reason"].sel(solver=s).values == "disabled")]
    fig, axes = plt.subplots(1, 4, figsize=(13.0, 3.6), layout="constrained")
    metrics = [("position_error_los_m", "along LOS RMS [m]"), ("position_error_across_m", "across LOS RMS [m]")]
    for ax, (name, lab) in zip(axes[:2], metrics, strict=True):
        vals = [float(np.sqrt(np.nanmean(ds[name].sel(solver=s).values ** 2))) for s in solvers]
        ax.bar(range(len(solvers)), vals)
        ax.set_ylabel(lab)
    att = [float(np.sqrt(np.nanmean(ds["attitude_error_C"].sel(solver=s).values ** 2, axis=0)).max()) for s in solvers]
    axes[2].bar(range(len(solvers)), att)
    axes[2].set_ylabel("attitude RMS, worst camera axis [deg]")
    tm = [float(np.nanmedian(ds["solve_time_s"].sel(solver=s).values) * 1e6) for s in solvers]
    axes[3].bar(range(len(solvers)), tm)
    axes[3].set_yscale("log")
    axes[3].set_ylabel("median time per solve [µs]")
    for ax in axes:
        ax.set_xticks(range(len(solvers)), solvers, rotation=30, ha="right", fontsize=8)
        ax.grid(axis="y", alpha=0.3)
    paths.append(save(fig, figure_path(fig_dir, "fig4_solver_comparison", format)))
    return paths
