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
