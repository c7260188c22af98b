"""Figures of a ``cylindrical_004`` run, drawn from its stored dataset only."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

__all__ = ["plot"]


def plot(dataset: xr.Dataset, fig_dir: Path, *, format: str = "png") -> list[Path]:
    """Figures from the stored dataset: Table 1 errors, Table 2 errors, and the dynamic test.

    ``format``: ``"png"``, ``"pdf"`` or ``"svg"``.  Legends sit below the panels, never over data.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from experiments.plotting import check_format, figure_path, legend_below, save

    check_format(format)

    fig_dir = Path(fig_dir)
    fig_dir.mkdir(parents=True, exist_ok=True)
    out = []
    ds = dataset

    fig, ax = plt.subplots(figsize=(7, 4.6), layout="constrained")
    n = ds.sizes["point"]
    x = np.arange(n)
    for k, axis in enumerate(["x", "y", "z"]):
        ax.bar(x + (k - 1) * 0.25, ds["table1_error_mm"].sel(axis=axis), width=0.25, label=f"Δ{axis} (simulated)")
    if "paper_table1_error_mm" in ds:
        ax.plot(x, ds["paper_table1_error_mm"].sel(component="dxyz"), "k^", label="|Δ| paper Table 1")
        ax.plot(x, ds["table1_error_norm_mm"], "ko", mfc="none", label="|Δ| simulated")
    ax.axhline(0.5, color="r", ls=":", lw=1, label="0.5 mm claim")
    ax.set_xticks(x, [str(i + 1) for i in x])
    ax.set_xlabel("test point")
    ax.set_ylabel("error [mm]")
    ax.set_title("004 Table 1 analogue: 3-D point error")
    legend_below(fig, ncol=3)
    out.append(save(fig, figure_path(fig_dir, "table1_point_errors", format), dpi=120))

    rot = "attitude_rotation_error_deg" in ds
    fig, axes = plt.subplots(1, 3 + rot, figsize=(10 + 3.4 * rot, 4.0), layout="constrained")
    err = ds["attitude_error_deg"]
    poses = ds["pose"].values
    if rot:  # the rotation angle of R_est R_trueᵀ first: no gimbal-lock amplification
        ax = axes[0]
        e = ds["attitude_rotation_error_deg"].values
        for j, pose in enumerate(poses):
            ax.plot(np.full(e.shape[0], pose), e[:, j], ".", color="C0", alpha=0.4)
        ax.plot(poses, np.sqrt(np.mean(e**2, axis=0)), "ko", mfc="none", label="RMS over trials")
        if "attitude_rotation_bound_deg" in ds:
            ax.plot(poses, ds["attitude_rotation_bound_deg"], "s", color="C2", mfc="none",
                    label="Cramér–Rao bound (RMS)")
        ax.set_title("rotation-angle error")
        ax.set_xlabel("pose")
        ax.set_ylabel("rotation angle of R_est R_true^T [deg]")
        ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.18), fontsize=7, frameon=False)
    euler_axes = axes[rot:]
    for k, name in enumerate(["yaw", "roll", "pitch"]):
        ax = euler_axes[k]
        e = err.sel(angle=name).values
        for j, pose in enumerate(poses):
            ax.plot(np.full(e.shape[0], pose), e[:, j], ".", color="C0", alpha=0.4,
                    label="noise trials" if j == 0 else None)
        if "paper_attitude_error_deg" in ds:
            ax.plot(poses, ds["paper_attitude_error_deg"].sel(angle=name), "k^", label="paper Table 2")
        lim = {"yaw": 0.20, "roll": 0.12, "pitch": 0.23}[name]
        ax.axhline(lim, color="r", ls=":", lw=1, label="paper maximum")
        ax.axhline(-lim, color="r", ls=":", lw=1)
        ax.set_title(f"{name} error (3-1-2, eq 9-11)")
        ax.set_xlabel("pose")
    lo = min(ax.get_ylim()[0] for ax in euler_axes)
    hi = max(ax.get_ylim()[1] for ax in euler_axes)
    for ax in euler_axes:  # one range for the three Euler panels
        ax.set_ylim(lo, hi)
    euler_axes[0].set_ylabel("attitude error [deg]")
    fig.suptitle("004 Table 2 analogue")
    h, lab = euler_axes[0].get_legend_handles_labels()
    legend_below(fig, handles=h, labels=lab, ncol=3)
    out.append(save(fig, figure_path(fig_dir, "table2_attitude_errors", format), dpi=120))

    if "dyn_uv_true_px" in ds:
        fig, axes = plt.subplots(2, 1, figsize=(8, 6.4), sharex=True, layout="constrained")
        t = ds["time_s"].values
        for k, tgt in enumerate(ds["target"].values):
            axes[0].plot(t, ds["dyn_uv_true_px"].sel(target=tgt, camera=1, channel="u"), color=f"C{k}",
                         label=f"LED {tgt}")
            axes[1].plot(t, ds["dyn_track_error_mm"].sel(target=tgt), color=f"C{k}")
        bad = ds["dyn_identity_ok"].values == 0
        if np.any(bad):
            axes[1].plot(t[bad], np.zeros(bad.sum()), "rx", label="identity swap")
        axes[0].set_ylabel("camera 1, CCD1 u [px]")
        axes[0].set_title("dynamic test: spots cross, identities kept by Kalman-predicted association")
        axes[1].set_ylabel("track error [mm]")
        axes[1].set_xlabel("time [s]")
        axes[1].set_yscale("log")
        legend_below(fig, ncol=6)
        out.append(save(fig, figure_path(fig_dir, "dynamic_tracking", format), dpi=120))
    return out
