"""Plot primitives: one kind of panel each, ``ax=None`` (a new figure when omitted), axes returned.

They compute nothing: figure drivers select and reduce a stored dataset, then call them.
"""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402

from experiments.plotting.style import (  # noqa: E402
    ECLIPSE_COLOR,
    ECLIPSE_HATCH,
    ENVELOPE_COLOR,
    check_cmap,
    legend_right,
    readable_text_color,
    save,
    shade_spans,
)

__all__ = [
    "axes_or_new",
    "plot_map",
    "plot_band",
    "plot_time_series",
    "plot_timeline",
    "plot_image_tracks",
    "plot_cloud",
    "plot_histogram",
    "plot_envelope",
    "robust_limits",
    "clipped_extend",
    "shared_range",
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
             title: str = "", cbar_label: str = "", annotate: bool = False, fmt: str = "{:.2f}",
             extend: str | None = None, colorbar: bool = True, fontsize: float = 7.0) -> Axes:
    """Colour map of ``values[len(y), len(x)]`` on cell-centred coordinates; NaN cells stay blank.

    Parameters
    ----------
    values : ndarray, shape (ny, nx)
        The map (already reduced over trials by the caller).
    x, y : ndarray
        Cell-centre coordinates along the horizontal and vertical axes.
    vmin, vmax : float, optional
        Colour range; pass the same values to every panel that is compared with this one.
    cmap : str
        One of :data:`experiments.plotting.style.ALLOWED_CMAPS`.
    annotate : bool
        Write each cell's value in the cell (``fontsize`` pt, black or white by the cell's luminance).
    extend : {"neither", "min", "max", "both"}, optional
        Colour-bar arrows for values outside ``[vmin, vmax]``; by default from the values shown.
    colorbar : bool
        Draw this panel's colour bar (``False`` when the caller draws one shared bar).
    """
    ax = axes_or_new(ax)
    v = np.ma.masked_invalid(np.asarray(values, dtype=float))
    mesh = ax.pcolormesh(_edges(x), _edges(y), v, cmap=check_cmap(cmap), vmin=vmin, vmax=vmax, shading="flat")
    if colorbar:
        cb = ax.figure.colorbar(mesh, ax=ax, extend=extend or clipped_extend(v.compressed(), vmin, vmax))
        cb.set_label(cbar_label)
    if annotate and v.size <= 400:
        for j, yy in enumerate(y):
            for i, xx in enumerate(x):
                if not np.ma.is_masked(v[j, i]):
                    face = mesh.cmap(mesh.norm(float(v[j, i])))
                    ax.text(xx, yy, fmt.format(float(v[j, i])), ha="center", va="center", fontsize=fontsize,
                            color=readable_text_color(face))
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    return ax


def clipped_extend(values: np.ndarray, vmin: float | None, vmax: float | None) -> str:
    """The colour-bar ``extend`` that shows which finite ``values`` fall outside ``[vmin, vmax]``."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    below = vmin is not None and v.size > 0 and bool(np.any(v < vmin))
    above = vmax is not None and v.size > 0 and bool(np.any(v > vmax))
    return {(False, False): "neither", (True, False): "min", (False, True): "max", (True, True): "both"}[below, above]


def shared_range(*maps: np.ndarray, lo: float | None = None, hi: float | None = None) -> tuple[float, float]:
    """One colour range ``(vmin, vmax)`` for panels that are compared: the finite extremes of all
    ``maps``, with ``lo``/``hi`` imposed where given ((0, 1) when nothing is finite)."""
    finite = np.concatenate([np.asarray(m, dtype=float).ravel() for m in maps]) if maps else np.zeros(0)
    finite = finite[np.isfinite(finite)]
    vmin = lo if lo is not None else (float(finite.min()) if finite.size else 0.0)
    vmax = hi if hi is not None else (float(finite.max()) if finite.size else 1.0)
    if not vmax > vmin:
        vmax = vmin + (abs(vmin) or 1.0) * 1e-3
    return vmin, vmax


def plot_band(x: np.ndarray, center: np.ndarray, lo: np.ndarray | None = None, hi: np.ndarray | None = None,
              *, ax: Axes | None = None, label: str = "", xlabel: str = "", ylabel: str = "", title: str = "",
              color: str | None = None) -> Axes:
    """A line with an optional shaded band ``[lo, hi]`` (e.g. median and interquartile range).

    A labelled line gets a legend outside the axes, on the right.
    """
    ax = axes_or_new(ax)
    (line,) = ax.plot(x, center, label=label, color=color)
    if lo is not None and hi is not None:
        ax.fill_between(x, lo, hi, color=line.get_color(), alpha=0.25, linewidth=0)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    if label:
        legend_right(ax)
    return ax


def plot_time_series(t: np.ndarray, series: np.ndarray, *, ax: Axes | None = None, labels: Sequence[str] | None = None,
                     threshold: float | None = None, symmetric_threshold: bool = False, logy: bool = False,
                     xlabel: str = "time [s]", ylabel: str = "", title: str = "", alpha: float = 1.0,
                     linewidth: float = 1.0, threshold_label: str = "threshold", legend: bool = True,
                     colors: Sequence[str] | None = None) -> Axes:
    """Lines ``series[..., T]`` (one per row) against ``t``; optional threshold line(s).

    The threshold is labelled ``threshold_label``; with ``labels`` (or a finite threshold) and
    ``legend`` the legend goes outside the axes, on the right (pass ``legend=False`` when the
    caller draws one legend for the figure, :func:`experiments.plotting.style.legend_below`).
    """
    ax = axes_or_new(ax)
    s = np.atleast_2d(np.asarray(series, dtype=float))
    for i, row in enumerate(s):
        ax.plot(t, row, label=None if labels is None else labels[i], alpha=alpha, linewidth=linewidth,
                color=None if colors is None else colors[i % len(colors)])
    has_threshold = threshold is not None and np.isfinite(threshold)
    if has_threshold:
        ax.axhline(threshold, color="k", linestyle="--", linewidth=0.8, label=threshold_label)
        if symmetric_threshold:
            ax.axhline(-threshold, color="k", linestyle="--", linewidth=0.8)
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    if legend and (labels is not None or has_threshold):
        legend_right(ax)
    return ax


def plot_envelope(t: np.ndarray, upper: np.ndarray, lower: np.ndarray | None = None, *, ax: Axes | None = None,
                  label: str = "±3σ (filter covariance)", floor: float | None = None) -> Axes:
    """Shade ``[lower, upper]`` against ``t`` (e.g. the filter's ±3σ), behind the lines.

    ``lower`` defaults to ``-upper``; on a log axis pass ``floor`` (the band then spans
    ``[floor, upper]``, the bound of a non-negative error).
    """
    ax = axes_or_new(ax)
    up = np.asarray(upper, dtype=float)
    lo = np.full_like(up, floor) if floor is not None else (-up if lower is None else np.asarray(lower, dtype=float))
    ax.fill_between(t, lo, up, color=ENVELOPE_COLOR, alpha=0.3, linewidth=0, zorder=0.5, label=label)
    ax.plot(t, up, color=ENVELOPE_COLOR, linewidth=0.6, alpha=0.8, zorder=0.6)
    return ax


def plot_timeline(t: np.ndarray, active: np.ndarray, names: Sequence[str], *, ax: Axes | None = None, title: str = "",
                  shade: np.ndarray | None = None, shade_label: str = "") -> Axes:
    """Active-observer timeline: one row per observer, filled where ``active[T, S]``; epochs where
    ``shade[T]`` is true (e.g. Earth's shadow) are shaded grey, named in a legend outside the axes."""
    ax = axes_or_new(ax)
    a = np.asarray(active, dtype=bool)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    if shade is not None and shade_spans(ax, t, shade, color=ECLIPSE_COLOR, hatch=ECLIPSE_HATCH,
                                                label=shade_label) and shade_label:
        legend_right(ax)
    for s in range(a.shape[1]):
        on = a[:, s]
        starts = np.flatnonzero(on & ~np.r_[False, on[:-1]])
        ends = np.flatnonzero(on & ~np.r_[on[1:], False])
        ax.broken_barh([(t[i], t[j] - t[i] + dt) for i, j in zip(starts, ends, strict=True)], (s - 0.4, 0.8),
                       facecolors="#31688e")
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


def robust_limits(X: np.ndarray, *, percentile: float = 2.0, margin: float = 0.1) -> tuple[np.ndarray, float]:
    """Centre ``(3,)`` and half-width of a cube holding the ``percentile``–``(100 − percentile)`` %
    range of the finite points of ``X (N, 3)`` on every axis, widened by ``margin``: a few outliers
    do not set the axes."""
    X = np.asarray(X, dtype=float).reshape(-1, 3)
    X = X[np.isfinite(X).all(-1)]
    if not len(X):
        return np.zeros(3), 1.0
    lo, hi = np.percentile(X, [percentile, 100.0 - percentile], axis=0)
    half = 0.5 * float(np.max(hi - lo)) * (1.0 + margin)
    return 0.5 * (lo + hi), half if half > 0 else 1.0


def plot_cloud(X: np.ndarray, *, ax: Axes | None = None, title: str = "", values: np.ndarray | None = None,
               values_label: str = "", truth: np.ndarray | None = None, cmap: str = "viridis",
               percentile: float = 2.0) -> Axes:
    """3-D scatter of a point cloud ``X (N, 3)`` (metres, H frame), equal axes, robust limits.

    Parameters
    ----------
    values : ndarray (N,), optional
        Colour of each point (e.g. triangulation σ in mm), with a colour bar labelled
        ``values_label``; default: the z coordinate (``"z_H [m]"``).
    truth : ndarray (N, 3), optional
        The true points, drawn as small black crosses (legend outside the axes).
    percentile : float
        Axis limits hold the ``percentile``–``(100 − percentile)`` % range on each axis (:func:`robust_limits`);
        points beyond are clipped from view and counted in the legend.
    """
    if ax is None:
        fig = plt.figure(figsize=(6.0, 4.8), layout="constrained")
        ax = fig.add_subplot(projection="3d")
    X = np.asarray(X, dtype=float).reshape(-1, 3)
    c = X[:, 2] if values is None else np.asarray(values, dtype=float)
    mid, half = robust_limits(X if truth is None else np.concatenate([X, np.asarray(truth).reshape(-1, 3)]),
                              percentile=percentile)
    inside = np.all(np.abs(X - mid) <= half, axis=-1)
    finite_c = np.isfinite(c)
    vmin, vmax = (np.percentile(c[finite_c & inside], [1, 99]) if np.any(finite_c & inside) else (0.0, 1.0))
    sc = ax.scatter(X[inside, 0], X[inside, 1], X[inside, 2], s=3, c=c[inside], cmap=check_cmap(cmap),
                    vmin=vmin, vmax=vmax, depthshade=False,
                    label=f"reconstructed ({int((~inside).sum())} outside the axes)")
    if truth is not None:
        Y = np.asarray(truth, dtype=float).reshape(-1, 3)
        Y = Y[np.isfinite(Y).all(-1) & np.all(np.abs(Y - mid) <= half, axis=-1)]
        ax.scatter(Y[:, 0], Y[:, 1], Y[:, 2], s=6, marker="x", c="k", linewidths=0.5, depthshade=False,
                   label="truth")
    ext = "max" if np.any(c[finite_c] > vmax) else "neither"
    cb = ax.figure.colorbar(sc, ax=ax, shrink=0.7, pad=0.1, extend=ext)
    cb.set_label(values_label or "z_H [m]")
    for set_lim, m in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), mid, strict=True):
        set_lim(m - half, m + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    ax.set_xlabel("x_H [m]")
    ax.set_ylabel("y_H [m]")
    ax.set_zlabel("z_H [m]")
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, 1.0), fontsize=7, frameon=False)
    ax.set_title(title)
    return ax


def plot_histogram(values: np.ndarray, *, ax: Axes | None = None, bins: int = 30, label: str = "", xlabel: str = "",
                   vline: float | None = None, vline_label: str = "", legend: bool = True) -> Axes:
    """Histogram of finite ``values`` with an optional reference line; legend outside the axes."""
    ax = axes_or_new(ax)
    v = np.asarray(values, dtype=float)
    ax.hist(v[np.isfinite(v)], bins=bins, alpha=0.75, color="#31688e", label=label)
    if vline is not None and np.isfinite(vline):
        ax.axvline(vline, color="k", linestyle="--", label=vline_label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("trials")
    if legend:
        legend_right(ax)
    return ax
