"""Docs figures of ``orbits``: CW error growth against separation and time, relative trajectories.

Plot functions take ``ax=None`` (a new figure when omitted), return the axes, and compute
nothing.  :func:`cw_error_growth_data` computes the study (through :func:`orbits.cw.cw_error`)
and :func:`cw_error_growth_figure` draws it; :func:`draw_orbit_figures` writes the docs figure::

    coobs figures orbits --out docs/figures
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from experiments.plotting import axes_or_new, figure_path, legend_right, save  # noqa: E402

__all__ = [
    "CwErrorGrowth",
    "cw_error_growth_data",
    "plot_cw_error_vs_time",
    "plot_cw_error_vs_separation",
    "plot_relative_trajectory",
    "cw_error_growth_figure",
    "draw_orbit_figures",
]


@dataclass(frozen=True)
class CwErrorGrowth:
    """CW-vs-two-body error study (see :func:`cw_error_growth_data`).

    Attributes
    ----------
    a_m : float
        Chief circular orbit radius (m).
    t_orbits : ndarray, shape (T,)
        Epochs in chief orbits.
    semi_major_m : ndarray, shape (S,)
        Along-track semi-axis of the natural-motion circumnavigation (m).
    error_m : ndarray, shape (S, T)
        Worst CW position error over the phases (m) at each epoch.
    """

    a_m: float
    t_orbits: np.ndarray
    semi_major_m: np.ndarray
    error_m: np.ndarray


def cw_error_growth_data(*, a_m: float = 6721.2e3, semi_major_m: Sequence[float] = (10, 25, 50, 100, 250, 500, 1000),
                         orbits: float = 5.0, epochs: int = 501, phases: int = 12,
                         cross_track_ratio: float = 1.0) -> CwErrorGrowth:
    """CW position error against Kepler truth for natural-motion circumnavigations.

    Each size gets ``phases`` in-plane phases, cross-track amplitude ``cross_track_ratio`` ×
    the along-track semi-axis (phase 90° apart); the error is the worst over phases.
    """
    from orbits import cw

    n = float(cw.mean_motion(a_m))
    t = np.linspace(0.0, orbits * 2 * np.pi / n, epochs)
    sizes = np.asarray(semi_major_m, dtype=float)
    ph = np.linspace(0.0, 2 * np.pi, phases, endpoint=False)
    x0 = cw.natural_motion_circumnavigation(sizes[:, None], n=n, phase_rad=ph[None, :],
                                            cross_track_amplitude_m=cross_track_ratio * sizes[:, None],
                                            cross_track_phase_rad=np.pi / 2)
    err = cw.cw_error(x0, t, a_m=a_m).position_error_m.max(axis=1)
    return CwErrorGrowth(a_m, t * n / (2 * np.pi), sizes, err)


def plot_cw_error_vs_time(t_orbits: np.ndarray, semi_major_m: np.ndarray, error_m: np.ndarray, *,
                          ax: Axes | None = None, threshold_m: float | None = None) -> Axes:
    """Lines of CW position error (m, log scale) against time (chief orbits), one per size."""
    ax = axes_or_new(ax)
    cmap = plt.get_cmap("viridis")
    for k, s in enumerate(semi_major_m):
        ax.semilogy(t_orbits[1:], error_m[k, 1:], color=cmap(k / max(len(semi_major_m) - 1, 1)),
                    label=f"{s:g} m")
    if threshold_m is not None:
        ax.axhline(threshold_m, color="k", ls="--", lw=0.8, label=f"{100 * threshold_m:g} cm")
    ax.set_xlabel("time [orbits]")
    ax.set_ylabel("CW position error [m]")
    legend_right(ax, title="NMC semi-axis")
    ax.grid(True, which="both", alpha=0.3)
    return ax


def plot_cw_error_vs_separation(semi_major_m: np.ndarray, errors_m: Sequence[np.ndarray], labels: Sequence[str], *,
                                ax: Axes | None = None, threshold_m: float | None = None) -> Axes:
    """Log-log CW position error against relative-orbit size; ``errors_m[j]`` is one curve."""
    ax = axes_or_new(ax)
    for e, lab in zip(errors_m, labels, strict=True):
        ax.loglog(semi_major_m, e, "o-", ms=3, label=lab)
    if threshold_m is not None:
        ax.axhline(threshold_m, color="k", ls="--", lw=0.8, label=f"{100 * threshold_m:g} cm")
    ax.set_xlabel("NMC along-track semi-axis [m]")
    ax.set_ylabel("max CW position error [m]")
    legend_right(ax)
    ax.grid(True, which="both", alpha=0.3)
    return ax


def plot_relative_trajectory(r_H: np.ndarray, *, ax: Axes | None = None, axes: tuple[int, int] = (1, 0),
                             label: str | None = None) -> Axes:
    """Relative trajectory in H projected on two axes (default along-track y vs radial x), m."""
    ax = axes_or_new(ax)
    names = ("x radial [m]", "y along-track [m]", "z cross-track [m]")
    ax.plot(r_H[..., axes[0]], r_H[..., axes[1]], label=label)
    ax.set_xlabel(names[axes[0]])
    ax.set_ylabel(names[axes[1]])
    ax.set_aspect("equal", adjustable="datalim")
    return ax


def cw_error_growth_figure(data: CwErrorGrowth, *, threshold_m: float = 0.02) -> Figure:
    """Two panels: error vs time per size, and error vs size after 1, 2 and 5 orbits."""
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12.0, 4.0), layout="constrained")
    plot_cw_error_vs_time(data.t_orbits, data.semi_major_m, data.error_m, ax=a1, threshold_m=threshold_m)
    picks = [o for o in (1.0, 2.0, 5.0) if o <= data.t_orbits[-1] + 1e-9]
    idx = [int(np.argmin(np.abs(data.t_orbits - o))) for o in picks]
    plot_cw_error_vs_separation(data.semi_major_m, [data.error_m[:, i] for i in idx],
                                [f"after {o:g} orbit(s)" for o in picks], ax=a2, threshold_m=threshold_m)
    fig.suptitle(f"CW vs two-body, circular chief a = {data.a_m / 1e3:.1f} km, "
                 "natural-motion circumnavigations (cross-track = along-track semi-axis)", fontsize=9)
    return fig


def draw_orbit_figures(out_dir: Path, *, format: str = "png") -> list[Path]:
    """Compute the CW error-growth study and write its docs figure, ``out_dir/cw_error_growth.<format>``
    (``format``: ``"png"``, ``"pdf"`` or ``"svg"``)."""
    path = figure_path(Path(out_dir), "cw_error_growth", format)
    return [save(cw_error_growth_figure(cw_error_growth_data()), path, dpi=120)]
