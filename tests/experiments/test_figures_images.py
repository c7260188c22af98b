"""Image comparison of the main figure types against committed baselines (matplotlib's own tool).

Each figure is drawn from a dataset of :mod:`tests.experiments.figures_data` in a fixed style
(matplotlib defaults, no hinting, 60 dpi) and compared with ``baseline_images/<name>.png`` by
:func:`matplotlib.testing.compare.compare_images` at ``TOL_RMS`` (RMS of the 0–255 pixel
difference).  Redrawing on the same machine gives RMS 0; a few RMS leaves room for another FreeType
build's text.  ``test_the_tolerance_catches_a_changed_colour_range`` shows that the tolerance is
tight enough to fail on the defects the figures were fixed for.

To regenerate the baselines after an intended change::

    COOBS_UPDATE_BASELINES=1 .venv/bin/python -m pytest tests/experiments/test_figures_images.py
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.testing.compare import compare_images  # noqa: E402

from experiments.plotting import plot_time_series, save  # noqa: E402
from tests.experiments.figures_data import closed_loop_run, error_map_sweep, fixed_style, tof_run  # noqa: E402

BASELINES = Path(__file__).parent / "baseline_images"
#: largest RMS difference (0–255 scale) accepted against a baseline
TOL_RMS = 3.0
UPDATE = os.environ.get("COOBS_UPDATE_BASELINES") == "1"


def _check(actual: Path, name: str) -> None:
    expected = BASELINES / f"{name}.png"
    if UPDATE:
        BASELINES.mkdir(exist_ok=True)
        shutil.copyfile(actual, expected)
    assert expected.is_file(), f"no baseline {expected}; run with COOBS_UPDATE_BASELINES=1"
    msg = compare_images(str(expected), str(actual), tol=TOL_RMS)
    assert msg is None, msg


def test_error_map_matches_its_baseline(tmp_path):
    from experiments.scenarios.formation.figures import error_map_figures

    with fixed_style():
        (path,) = error_map_figures(error_map_sweep(), tmp_path)
    _check(path, "error_maps")


def test_convergence_map_matches_its_baseline(tmp_path):
    from experiments.scenarios.formation.figures import convergence_map_figures

    ds = error_map_sweep()
    with fixed_style():
        (path,) = convergence_map_figures(ds, tmp_path, frac=ds["filter_fraction_converged"],
                                          tmed=ds["filter_median_convergence_time_s"], name="convergence_maps",
                                          title="EKF convergence")
    _check(path, "convergence_maps")


@pytest.fixture(scope="module")
def closed_loop_figures(tmp_path_factory):
    from experiments.scenarios.formation.figures import closed_loop_figures

    out = tmp_path_factory.mktemp("closed_loop")
    with fixed_style():
        paths = closed_loop_figures(closed_loop_run(), out)
    return {p.stem: p for p in paths}


@pytest.mark.parametrize("name", ["errors", "errors_axes", "reconstructed_cloud"])
def test_closed_loop_figure_matches_its_baseline(closed_loop_figures, name):
    _check(closed_loop_figures[name], f"closed_loop_{name}")


@pytest.mark.parametrize("name", ["tof_static", "tof_sweep"])
def test_tof_figure_matches_its_baseline(tmp_path, name):
    from experiments.scenarios.tof.figures import plot

    with fixed_style():
        paths = {p.stem: p for p in plot(tof_run(), tmp_path)}
    _check(paths[name], name)


def test_time_series_matches_its_baseline(tmp_path):
    t = np.linspace(0.0, 60.0, 121)
    series = np.stack([2.0 * np.exp(-t / 10.0) + 0.05, 1.0 * np.exp(-t / 20.0) + 0.02])
    with fixed_style():
        fig, ax = plt.subplots(figsize=(6.0, 3.0), layout="constrained")
        plot_time_series(t, series, ax=ax, labels=["EKF", "MEKF"], threshold=0.1, logy=True,
                         threshold_label="convergence threshold", ylabel="attitude error [deg]")
        path = save(fig, tmp_path / "time_series.png")
    _check(path, "time_series")


def test_the_tolerance_catches_a_changed_colour_range(tmp_path):
    """The old defect, a map whose colours saturate at a different value, fails the comparison."""
    from experiments.scenarios.formation import figures

    if UPDATE:
        pytest.skip("baselines are being regenerated")
    with fixed_style(), pytest.MonkeyPatch.context() as mp:
        mp.setattr(figures, "ERROR_MAP_RANGE_DEG", (0.0, 3.4))
        (path,) = figures.error_map_figures(error_map_sweep(), tmp_path)
    msg = compare_images(str(BASELINES / "error_maps.png"), str(path), tol=TOL_RMS)
    assert msg is not None and "did not match" in msg
