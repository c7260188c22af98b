"""Figures of a ``tof_000`` run, drawn from its stored dataset only."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from experiments.scenarios.tof.experiment import COLUMNS

__all__ = ["plot"]


def _column_label(column: str) -> str:
    """``"x_mm"`` → ``"x [mm]"``, ``"pitch_deg"`` → ``"pitch [deg]"``."""
    name, unit = column.rsplit("_", 1)
    return f"{name} [{unit}]"


def plot(dataset: xr.Dataset, fig_dir: Path, *, format: str = "png") -> list[Path]:
    """Static repeatability traces, sweep errors and matching success rates, from the dataset.

    ``format``: ``"png"``, ``"pdf"`` or ``"svg"``.  Legends sit below the panels, never over data.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from experiments.plotting import check_format, figure_path, legend_below, save

    check_format(format)
    fig_dir = Path(fig_dir)
    out: list[Path] = []
    if "example_amplitude_dn" in dataset:
        fig, axes = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
        im = axes[0].imshow(dataset["example_amplitude_dn"], cmap="gray")
        fig.colorbar(im, ax=axes[0], label="amplitude [DN]")
        im = axes[1].imshow(dataset["example_range_m"], cmap="viridis")
        fig.colorbar(im, ax=axes[1], label="radial range [m]")
        uv = dataset["example_keypoint_uv_px"].values
        for k, (u, v) in enumerate(uv):
            lab = int(dataset["example_keypoint_label"].values[k])
            axes[0].plot(u, v, "r+", ms=10)
            axes[0].annotate(str(lab) if lab >= 0 else "null", (u, v), xytext=(7, -9), textcoords="offset points",
                             color="gold", fontsize=9, fontweight="bold")
        for ax in axes:
            ax.set_xlabel("u [px]")
            ax.set_ylabel("v [px]")
        axes[0].set_title("amplitude, key points and MRF labels (frame 0)")
        axes[1].set_title("range image (blank: no return / low confidence)")
        out.append(save(fig, figure_path(fig_dir, "tof_frame", format), dpi=110))

    fig, axes = plt.subplots(2, 3, figsize=(12, 6.4), sharex=True, layout="constrained")
    for ax, c in zip(axes.ravel(), COLUMNS, strict=True):
        for est in dataset["estimator"].values:
            ax.plot(dataset["frame"], dataset[c].sel(estimator=est), ".", ms=3, label=f"range estimator: {est}")
        ax.set_ylabel(_column_label(c))
        ax.set_xlabel("frame")
    fig.suptitle("000 Table 1 reproduction: static target, repeated frames")
    legend_below(fig)
    out.append(save(fig, figure_path(fig_dir, "tof_static", format), dpi=110))

    if "sweep_attitude_error_deg" in dataset:
        fig, axes = plt.subplots(1, 2, figsize=(11, 4.4), layout="constrained")
        for est in dataset["estimator"].values:
            for axis in dataset["sweep_axis"].values:
                sel = dict(estimator=est, sweep_axis=axis)
                for ax, var in zip(axes, ("sweep_attitude_error_deg", "sweep_position_error_mm"), strict=True):
                    rms = np.sqrt((dataset[var].sel(sel) ** 2).mean("sweep_frame"))
                    ax.plot(dataset["sweep_angle_deg"], rms, "o-" if est == "plane" else "s--", label=f"{axis}, {est}")
        axes[0].set_ylabel("RMS attitude error [deg]")
        axes[1].set_ylabel("RMS position error [mm]")
        for ax in axes:
            ax.set_xlabel("offset of one Euler angle [deg]")
            ax.set_yscale("log")
        legend_below(fig, ncol=3)
        out.append(save(fig, figure_path(fig_dir, "tof_sweep", format), dpi=110))

    if "labels_correct" in dataset:
        cases, matchers = dataset["case"].values, dataset["matcher"].values
        fig, axes = plt.subplots(1, 2, figsize=(12, 4.4), sharey=True, layout="constrained")
        w = 0.8 / len(matchers)
        colors = matplotlib.colormaps["viridis"](np.linspace(0.15, 0.85, len(matchers)))
        for ax, var in zip(axes, ("labels_correct", "labels_correct_verified"), strict=True):
            rate = dataset[var].mean("trial")
            for k, m in enumerate(matchers):
                ax.bar(np.arange(len(cases)) + k * w, 100 * rate.sel(matcher=m), w, label=f"matcher: {m}",
                       color=colors[k])
            ax.set_xticks(np.arange(len(cases)) + 0.4 - w / 2, [str(c).replace("_", "\n") for c in cases], fontsize=7)
            ax.set_title(var.replace("_", " "))
        axes[0].set_ylabel(f"trials with all labels correct [%], n = {dataset.sizes['trial']}")
        legend_below(fig, handles=axes[0].get_legend_handles_labels()[0],
                     labels=axes[0].get_legend_handles_labels()[1])
        out.append(save(fig, figure_path(fig_dir, "tof_matching", format), dpi=110))
    return out
