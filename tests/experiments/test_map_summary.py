"""The summary of one Experiment A sweep (experiments.studies.map_summary)."""

import numpy as np
import pytest
import xarray as xr

from experiments.studies.map_summary import main, summary

DIST, ANG, VIEWS, TRIALS = [30.0, 40.0, 80.0, 100.0], [5, 10, 15], [2, 3], 4


def _store() -> xr.Dataset:
    """e_Δθ = distance / 100 deg with 2 views and half that with 3, except 3 views at 100 m (worse);
    bound = e / 2, step RMS = e; tracks = 100 / distance; 2 of the 4 trials of every 100 m cell
    refused outright (NaN), the others with 5 of 10 steps refused; every other trial: 1 step refused."""
    shape = (len(DIST), len(ANG), len(VIEWS), TRIALS)
    d = np.array(DIST)[:, None, None, None] * np.ones(shape)
    e = d / 100.0 * np.where(np.array(VIEWS)[None, None, :, None] == 3, 0.5, 1.0)
    e[3, :, 1] = 2.0
    failed = np.ones(shape)
    failed[3] = 5.0
    failed[3, ..., :2] = np.nan
    dims = ("distance_m", "axis_angle_deg", "n_views", "trial")
    data = {"e_dtheta_deg": e, "step_rms_deg": e, "crlb_deg": e / 2, "n_tracks": 100.0 / d, "failed_steps": failed}
    for k in ("e_dtheta_deg", "step_rms_deg", "crlb_deg", "n_tracks"):
        data[k] = np.where(np.isnan(failed), np.nan, data[k])
    coords = {"distance_m": DIST, "axis_angle_deg": ANG, "n_views": VIEWS, "trial": np.arange(TRIALS)}
    return xr.Dataset({k: (dims, v) for k, v in data.items()}, coords=coords)


def test_summary_of_a_store_with_known_cells():
    s = summary(_store())
    two, three = s["per_views"][2], s["per_views"][3]
    assert two["e_dtheta_deg"] == pytest.approx((0.3, 0.6, 1.0))                 # median of 0.3, 0.4, 0.8, 1.0
    assert three["e_dtheta_deg"] == pytest.approx((0.15, 0.3, 2.0))
    assert two["step_over_crlb"] == pytest.approx((2.0, 2.0, 2.0))
    assert two["tracks"] == pytest.approx((1.0, (1.25 + 2.5) / 2, 100.0 / 30.0), rel=1e-12)
    # refused: 10 % of the steps closer in; at 100 m 2 trials x 10 + 2 x 5 of 40 steps = 75 %
    assert two["refused_percent_by_distance"] == [10.0, 10.0, 10.0, 75.0]
    assert two["refused_percent"] == pytest.approx((10.0, 10.0, 75.0))
    assert two["trials_every_step_refused"] == pytest.approx((0.0, 0.0, 2.0))
    assert s["three_better_than_two"] == {"e": 9, "step": 9, "crlb": 9}          # all but the 3 cells at 100 m
    assert s["three_views_within_0_2_deg"] == 6                                   # 30 and 40 m
    assert s["window_e_dtheta_deg"][2] == pytest.approx((0.4, 0.8))              # 40-80 m, 10-15 deg
    assert s["cells"] == 12


def test_a_folder_without_a_store_is_refused_with_exit_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as ex:
        main([str(tmp_path)])
    assert ex.value.code == 2
    assert "runs: no sweep store at" in capsys.readouterr().err
