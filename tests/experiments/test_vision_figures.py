"""The vision figure draws every track's keypoints and a line per drawn track and view pair."""

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402

from experiments.studies.vision_figures import plot_matched_views  # noqa: E402


def test_plot_matched_views_draws_keypoints_and_connection_lines():
    rng = np.random.default_rng(0)
    images = [rng.integers(0, 255, (60, 80)).astype(np.uint8) for _ in range(3)]
    uv = rng.uniform(5, 55, (10, 3, 2))
    uv[0, 2] = np.nan                                   # track 0 only in views 0 and 1
    fid = np.r_[np.arange(9), -1]
    axes = plot_matched_views(images, uv, fid, max_lines=10)
    assert len(axes) == 3
    fig = axes[0].figure
    assert len(fig.artists) == 9 * 2 + 1                # view pairs (0,1), (1,2) per track
    n_points = sum(len(line.get_xdata()) for line in axes[2].lines)
    assert n_points == 9                                 # track 0 absent in view 3
