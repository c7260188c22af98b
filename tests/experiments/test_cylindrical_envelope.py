"""The envelope sweep of cylindrical_004: accuracy and availability maps with the Cramér–Rao bound."""

import numpy as np
import pytest

import coobs
from experiments.config import load_config
from experiments.sweep import cell_seed_sequences

CONFIG = "experiments/configs/004_cylindrical_envelope.toml"
SMALL = {  # a coarse calibration and a small position grid: the test runs in seconds
    "calibration.alpha_step_deg": 1.0,
    "calibration.rail_step_mm": 60.0,
    "envelope.depths_m": [2.0, 3.5, 6.0],
    "envelope.offsets_m": [0.0, 2.0],
    "attitude.poses_deg": [[-22.0581, 59.199, 6.0103], [19.3189, 88.67, -22.1653]],
}


@pytest.fixture(scope="module")
def cell_output():
    module, cfg = load_config(CONFIG, SMALL)
    cell = module.sweep_cell(cfg)
    return cell, cell.fn(cfg, cell_seed_sequences(cfg.sweep.seed, {}, 12))


def test_envelope_cell_returns_every_metric_with_its_shape(cell_output):
    cell, out = cell_output
    for name in cell.metrics:
        assert np.shape(out[name]) == cell.metric_shape(name, 12), name
    assert list(out["failure_reason"]) == [""] * 12


def test_envelope_availability_follows_the_fields_of_view(cell_output):
    _, out = cell_output
    avail = out["available"].mean(0)  # (depth, offset)
    # the 0.7 m LED triangle 2 m ahead falls outside both ±15.6° fields; on the axes' crossing (3.5 m) all is seen;
    # 2 m off the middle at 3.5 m, outside camera 1's field
    assert avail[0, 0] < 0.5 and avail[1, 0] == 1.0 and avail[1, 1] == 0.0
    assert np.isnan(out["point_crlb_mm"][1, 1]) and np.isnan(out["rotation_error_deg"][:, 1, 1]).all()


def test_envelope_noise_scatter_is_the_cramer_rao_bound_and_calibration_adds_the_rest(cell_output):
    _, out = cell_output
    seen = np.isfinite(out["point_crlb_mm"])
    # the spot noise alone (scatter about the mean over 12 trials) sits at the bound: within 0.7-1.3
    ratio = out["point_scatter_mm"][seen] / out["point_crlb_mm"][seen]
    assert np.all((ratio > 0.7) & (ratio < 1.3)), ratio
    rot = np.sqrt(np.mean(out["rotation_scatter_deg"] ** 2) / np.mean(out["rotation_crlb_deg"] ** 2, axis=-1))
    assert np.all((rot[np.isfinite(rot)] > 0.7) & (rot[np.isfinite(rot)] < 1.3))
    # the total error is larger than the bound: the one calibration of the cell biases every fix
    total = np.median(out["point_error_rms_mm"], 0)[seen]
    assert np.all(total > 2 * out["point_crlb_mm"][seen])
    # the bound grows with depth (ρ² for the depth axis): 6 m worse than 3.5 m
    assert out["point_crlb_mm"][2, 0] > 2 * out["point_crlb_mm"][1, 0]


def test_envelope_euler_error_is_the_rotation_error_amplified_near_the_gimbal_lock(cell_output):
    _, out = cell_output
    yaw = out["yaw_crlb_deg"][1, 0]  # pose 1 at roll 59°, pose 2 at roll 88.67°
    rot = out["rotation_crlb_deg"][1, 0]
    assert yaw[1] / rot[1] > 10 * yaw[0] / rot[0]
    assert out["roll_crlb_deg"][1, 0, 1] < rot[1]  # roll itself is not amplified
    # and the measured scatter shows the same amplification
    assert out["yaw_scatter_deg"][1, 0, 1] > 10 * out["rotation_scatter_deg"][1, 0, 1]


def test_envelope_sweep_runs_and_draws_its_maps(tmp_path):
    ds = coobs.sweep(CONFIG, out=tmp_path / "sw", overrides={**SMALL, "sweep.trials": 2,
                                                             "sweep.grid": {"rig.baseline_m": [2.0]}},
                     workers=1, processes=False, progress=False)
    assert ds.attrs["cell"] == "envelope" and bool(ds["done"].all())
    paths = coobs.plot(tmp_path / "sw")
    names = {p.name for p in paths}
    assert {"envelope_point_error.png", "envelope_rotation_error.png", "envelope_euler_yaw.png",
            "envelope_rotation_over_bound.png", "envelope_availability.png"} <= names
