"""Plot primitives: one kind of panel each, ``ax=None`` (a new figure when omitted), axes returned.

They compute nothing: figure drivers select and reduce a stored dataset, then call them.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

__all__ = [
    "axes_or_new",
    "plot_map",
    "plot_band",
    "plot_time_series",
    "plot_timeline",
    "plot_image_tracks",
    "plot_cloud",
    "plot_histogram",
    "save",
]


def axes_or_new(ax: Axes | None) -> Axes:
    """``ax``, or the axes of a new 5 × 4 in figure when ``ax`` is ``None``."""
    if ax is None:
        _, ax = plt.subplots(figsize=(5.0, 4.0), layout="constrained")
    return ax


def _edges(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, dtype=float)
    if c.size == 1:
        return np.array([c[0] - 0.5, c[0] + 0.5])
    mid = 0.5 * (c[1:] + c[:-1])
    return np.concatenate([[c[0] - (mid[0] - c[0])], mid, [c[-1] + (c[-1] - mid[-1])]])


def plot_map(values: np.ndarray, x: np.ndarray, y: np.ndarray, *, ax: Axes | None = None, vmin: float | None = None,
             vmax: float | None = None, cmap: str = "viridis", xlabel: str = "", ylabel: str = "",
             title: str = "", cbar_label: str = "", annotate: bool = False, fmt: str = "{:.2f}") -> Axes:
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
    ax = axes_or_new(ax)
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
              *, ax: Axes | None = None, label: str = "", xlabel: str = "", ylabel: str = "", title: str = "",
              color: str | None = None) -> Axes:
    """A line with an optional shaded band ``[lo, hi]`` (e.g. median and interquartile range)."""
    ax = axes_or_new(ax)
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


def save(fig: Figure, path: Path, *, dpi: int = 150) -> Path:
    """Save a figure as PNG (``dpi`` dots per inch, 150 by default) and close it; returns ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def plot_time_series(t: np.ndarray, series: np.ndarray, *, ax: Axes | None = None, labels: Sequence[str] | None = None,
                     threshold: float | None = None, symmetric_threshold: bool = False, logy: bool = False,
                     xlabel: str = "time [s]", ylabel: str = "", title: str = "", alpha: float = 1.0,
                     linewidth: float = 1.0) -> Axes:
    """Lines ``series[..., T]`` (one per row) against ``t``; optional threshold line(s)."""
    ax = axes_or_new(ax)
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


def plot_timeline(t: np.ndarray, active: np.ndarray, names: Sequence[str], *, ax: Axes | None = None, title: str = "",
                  shade: np.ndarray | None = None, shade_label: str = "") -> Axes:
    """Active-observer timeline: one row per observer, filled where ``active[T, S]``; epochs where
    ``shade[T]`` is true (e.g. Earth's shadow) are shaded grey."""
    ax = axes_or_new(ax)
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


def plot_image_tracks(image: np.ndarray, uv_px: np.ndarray, correct: np.ndarray | None = None, *, ax: Axes | None = None,
                      title: str = "") -> Axes:
    """An image with its track positions (green: correct per ground truth, red: false match)."""
    ax = axes_or_new(ax)
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


def plot_cloud(X: np.ndarray, *, ax: Axes | None = None, title: str = "", color: str | np.ndarray | None = None) -> Axes:
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


def plot_histogram(values: np.ndarray, *, ax: Axes | None = None, bins: int = 30, label: str = "", xlabel: str = "",
                   vline: float | None = None, vline_label: str = "") -> Axes:
    """Histogram of finite ``values`` with an optional reference line."""
    ax = axes_or_new(ax)
    v = np.asarray(values, dtype=float)
    ax.hist(v[np.isfinite(v)], bins=bins, alpha=0.6, label=label)
    if vline is not None and np.isfinite(vline):
        ax.axvline(vline, color="k", linestyle="--", label=vline_label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("trials")
    ax.legend(fontsize=7)
    return ax
