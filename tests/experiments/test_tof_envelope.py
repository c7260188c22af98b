"""Tests of the tof_000 envelope sweep cell (experiments.scenarios.tof.envelope)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from experiments.config import load_config
from experiments.scenarios.tof import sweep_cell
from experiments.scenarios.tof.envelope import envelope_cell, reason_class

CONFIG = Path(__file__).resolve().parents[2] / "experiments" / "configs" / "000_tof_envelope.toml"


def test_envelope_cell_reports_errors_against_the_bound_in_range_and_saturation_near():
    _, cfg = load_config(CONFIG, overrides={"target.distance_m": 1.0, "target.off_boresight_deg": 30.0})
    assert sweep_cell(cfg).name == "envelope"
    out = envelope_cell(cfg, np.random.SeedSequence(5).spawn(2))
    assert list(out["failure_reason"]) == ["", ""]
    assert np.all(out["attitude_error_deg"] < 0.3) and np.all(out["position_error_mm"] < 1.0)
    assert np.all((out["bound_attitude_deg"] > 1e-3) & (out["bound_attitude_deg"] < out["attitude_error_deg"] * 20))
    _, near = load_config(CONFIG, overrides={"target.distance_m": 0.3})
    out = envelope_cell(near, np.random.SeedSequence(5).spawn(1))
    assert reason_class(out["failure_reason"][0]) == "saturation"
    assert np.isnan(out["attitude_error_deg"][0])


def test_failure_reasons_map_to_their_classes():
    assert reason_class("") == ""
    assert reason_class("too few markers detected (2 < 3): plate saturated (9 px above the full well)") == "saturation"
    assert reason_class("markers below the confidence threshold (11 px inside the plate under 60 DN)") \
        == "markers below confidence"
    assert reason_class("no marker candidates") == "too few markers"
    assert reason_class("wrong match (attitude error 9.0 deg > 5 deg)") == "wrong match"
