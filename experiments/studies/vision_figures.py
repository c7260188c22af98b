"""Docs figures of ``vision``: rendered views from several cameras with their cross-view matches.

Plot functions take ``ax``/``axes=None`` (a new figure when omitted), return the axes, and compute
nothing. :func:`three_view_data` renders the issue-5 scene (FY-1-like target at 50 m, three 1024-px
20° cameras on the 003 §3.6 cone with pairwise axis angle 10°, Sun from the side) and matches it;
:func:`draw_vision_figures` writes the docs figure::

    coobs figures vision --out docs/figures
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
from matplotlib.patches import ConnectionPatch  # noqa: E402

from experiments.plotting import figure_path, save  # noqa: E402

__all__ = ["ThreeViewData", "plot_matched_views", "plot_view", "three_view_data", "three_view_figure",
           "draw_vision_figures"]


@dataclass(frozen=True)
class ThreeViewData:
    """Rendered images, their regions of interest, and the observation matched across them."""

    images: list
    rois: list
    observation: object
    distance_m: float
    angle_deg: float


def three_view_data(*, distance_m: float = 50.0, angle_deg: float = 10.0, seed: int = 0,
                    spin_deg: float = 30.0) -> ThreeViewData:
    """Render and match the three-camera scene (the study behind the figure)."""
    from attitude.quaternion import quat_from_axis_angle, quat_from_matrix, quat_multiply
    from vision.camera import PinholeCamera, look_at
    from vision.rendered import observe_renders, render_views
    from vision.target import fy1_target

    cam = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)
    phi = np.arcsin(2 / np.sqrt(3) * np.sin(np.radians(angle_deg) / 2))       # 003 §3.6
    eyes = [distance_m * np.array([np.cos(phi), np.sin(phi) * np.cos(a), np.sin(phi) * np.sin(a)])
            for a in 2 * np.pi * np.arange(3) / 3]
    T = np.stack([look_at(e, np.zeros(3)) for e in eyes])
    b = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)           # bisector of cameras (+x) and Sun (+z)
    R = np.column_stack([b, [0.0, 1.0, 0.0], np.cross(b, [0.0, 1.0, 0.0])])
    q = quat_multiply(quat_from_axis_angle(b, np.radians(spin_deg)), quat_from_matrix(R))
    target = fy1_target(seed=seed)
    renders = render_views(cam, T, target, q, np.array([0.0, 0.0, 1.0]), rng=seed)
    obs = observe_renders(renders, target, q)
    return ThreeViewData([r.image for r in renders], [r.roi for r in renders], obs, distance_m,
                         angle_deg)


def plot_view(image: np.ndarray, *, roi: tuple[int, int, int, int] | None = None, ax: Axes | None = None,
              title: str | None = None) -> Axes:
    """Show one grey image (optionally cropped to ``roi = (x0, y0, x1, y1)``) in pixel coordinates."""
    if ax is None:
        _, ax = plt.subplots(figsize=(4.0, 4.0), layout="constrained")
    x0, y0, x1, y1 = roi if roi is not None else (0, 0, image.shape[1], image.shape[0])
    ax.imshow(image[y0:y1, x0:x1], cmap="gray", vmin=0, vmax=np.iinfo(image.dtype).max,
              extent=(x0 - 0.5, x1 - 0.5, y1 - 0.5, y0 - 0.5), interpolation="nearest")
    ax.set_xlabel("u [px]")
    ax.set_ylabel("v [px]")
    if title:
        ax.set_title(title, fontsize=9)
    return ax


def plot_matched_views(images: Sequence[np.ndarray], uv_px: np.ndarray, feature_id: np.ndarray, *,
                       rois: Sequence[tuple[int, int, int, int]] | None = None,
                       axes: Sequence[Axes] | None = None, max_lines: int = 60,
                       titles: Sequence[str] | None = None, rng_seed: int = 0) -> list[Axes]:
    """Views side by side with the tracks' keypoints and lines joining each track across views.

    Parameters
    ----------
    images : sequence of (H, W) arrays
        The n views.
    uv_px : ndarray, shape (M, n, 2)
        Track pixel coordinates (NaN where absent), e.g. ``Observation.uv_px``.
    feature_id : ndarray, shape (M,)
        Ground-truth ids: >= 0 correct (green), -1 false (red).
    rois : sequence of (x0, y0, x1, y1), optional
        Crop of each view.
    axes : sequence of n Axes, optional
    max_lines : int
        Draw lines for at most this many tracks (a fixed random subset; all keypoints are drawn).
    """
    n = len(images)
    if axes is None:
        fig, axes = plt.subplots(1, n, figsize=(4.2 * n, 4.4), layout="constrained")
    axes = list(np.atleast_1d(axes))
    fig = axes[0].figure
    for i, ax in enumerate(axes):
        plot_view(images[i], roi=None if rois is None else rois[i], ax=ax,
                  title=None if titles is None else titles[i])
    uv = np.asarray(uv_px, dtype=float)
    ok = np.asarray(feature_id) >= 0
    for i, ax in enumerate(axes):
        s = np.isfinite(uv[:, i, 0])
        ax.plot(uv[s & ok, i, 0], uv[s & ok, i, 1], "o", ms=2.5, mfc="none", mec="lime", mew=0.6)
        ax.plot(uv[s & ~ok, i, 0], uv[s & ~ok, i, 1], "x", ms=3.5, color="red", mew=0.8)
    order = np.random.default_rng(rng_seed).permutation(len(uv))[:max_lines]
    for m in order:
        seen = np.nonzero(np.isfinite(uv[m, :, 0]))[0]
        for a, b in zip(seen[:-1], seen[1:], strict=True):
            fig.add_artist(ConnectionPatch(xyA=uv[m, a], coordsA=axes[a].transData,
                                           xyB=uv[m, b], coordsB=axes[b].transData,
                                           color="lime" if ok[m] else "red", lw=0.5, alpha=0.7))
    return axes


def three_view_figure(data: ThreeViewData) -> Figure:
    """The docs figure from :func:`three_view_data`."""
    obs = data.observation
    n_ok = int(np.sum(obs.feature_id >= 0))
    fig, axes = plt.subplots(1, 3, figsize=(13.0, 4.8), layout="constrained")
    titles = [f"camera {i + 1}: {int(np.isfinite(obs.uv_px[:, i, 0]).sum())} track points"
              for i in range(3)]
    plot_matched_views(data.images, obs.uv_px, obs.feature_id, rois=data.rois, axes=axes,
                       titles=titles)
    fig.suptitle(f"FY-1-like target at {data.distance_m:.0f} m, three cameras {data.angle_deg:.0f}° "
                 f"apart: {obs.n_tracks} tracks, {n_ok} correct by per-pixel truth "
                 "(green; red: false; lines: 60 random tracks)", fontsize=10)
    return fig


def draw_vision_figures(out_dir: Path, *, format: str = "png") -> list[Path]:
    """Render and match the three-view scene and write its docs figure, ``out_dir/vision_three_views.<format>``
    (``format``: ``"png"``, ``"pdf"`` or ``"svg"``)."""
    path = figure_path(Path(out_dir), "vision_three_views", format)
    return [save(three_view_figure(three_view_data()), path, dpi=110)]
