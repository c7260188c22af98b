"""The rendered against calibrated Experiment A comparison, trial by trial (experiments.studies.rendered_vs_calibrated)."""

import numpy as np
import xarray as xr

from experiments.studies.rendered_vs_calibrated import paired_table

DIST, ANG, VIEWS = [30.0, 40.0, 80.0, 100.0], [10.0, 20.0], [2, 3]


def _store(values: np.ndarray) -> xr.Dataset:
    dims = ("distance_m", "axis_angle_deg", "n_views", "trial")
    coords = {"distance_m": DIST, "axis_angle_deg": ANG, "n_views": VIEWS, "trial": np.arange(values.shape[-1])}
    return xr.Dataset({v: (dims, values) for v in ("crlb_deg", "step_rms_deg", "e_dtheta_deg", "n_tracks")},
                      coords=coords)


def test_the_ratio_is_taken_trial_by_trial_over_the_trials_both_keep():
    """The calibrated store holds 50 trials spread by a factor e^1 between them; the rendered one its
    first 10, 1.5 times the calibrated value close in and 0.8 times beyond 50 m, with two trials
    refused (NaN) in each part.  The paired median is exactly 1.5 and 0.8 over the 8 trials kept per
    cell, where the ratio of the cells' medians over all their trials would not be."""
    rng = np.random.default_rng(0)
    cal = np.exp(rng.normal(0.0, 1.0, (len(DIST), len(ANG), len(VIEWS), 50)))
    factor = np.where(np.array(DIST) <= 50.0, 1.5, 0.8)[:, None, None, None]
    ren = factor * cal[..., :10]
    ren[..., :2] = np.nan
    table = paired_table(_store(ren), _store(cal)).splitlines()
    trials = 8 * len(ANG) * len(VIEWS) * 2                 # two distances per part
    assert table[2] == f"| Cramér–Rao bound per step | 1.50 [1.50–1.50], {trials} trials | 0.80 [0.80–0.80], {trials} trials |"
    assert all("1.50 [1.50–1.50]" in row and "0.80 [0.80–0.80]" in row for row in table[2:])
    medians = np.nanmedian(ren, axis=-1) / np.median(cal, axis=-1)
    assert np.max(np.abs(medians[:2] - 1.5)) > 0.2
