"""End-to-end test of the ``tof_000`` scenario kind (paper 000) on a reduced config."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from experiments.config import ConfigError, load_config

CONFIG = Path(__file__).resolve().parents[2] / "experiments" / "configs" / "000_tof_700mm.toml"


def test_tof_000_reduced_run_gives_table1_statistics_sweep_and_matching_rates(tmp_path):
    module, cfg = load_config(CONFIG, {
        "static.frames": 4, "sweep.axes": ["pitch"], "sweep.angles_deg": [30.0], "sweep.frames_per_angle": 1,
        "matching.trials": 40, "matching.cases": ["one_missing"], "matching.matchers": ["mrf", "hungarian"],
    })
    calls = []
    res = module.run(cfg, progress=lambda d, t: calls.append((d, t)))
    ds, summary = res.dataset, res.summary
    assert calls[-1][0] == calls[-1][1] == 4 + 1 + 1
    t1 = summary["table1_plane"]
    # Table 1 layout: mean/max/min/range of x, y, z (mm) and pitch, yaw, roll (deg); range = max - min
    np.testing.assert_allclose(np.subtract(t1["max"], t1["min"]), t1["range"])
    assert t1["mean"][2] == pytest.approx(700.0, abs=2.0)
    assert summary["rms_attitude_error_deg_plane"] <= 0.14
    assert summary["rms_position_error_mm_plane"] <= 2.0
    assert float(ds["sweep_attitude_error_deg"].max()) < 0.5
    assert summary["matching_success_rate"]["one_missing"]["mrf"]["raw"] == 1.0
    assert ds["x_mm"].attrs["units"] == "mm" and ds["pitch_deg"].attrs["units"] == "deg"
    figs = module.plot(ds, tmp_path)
    assert [f.name for f in figs] == ["tof_frame.png", "tof_static.png", "tof_sweep.png", "tof_matching.png"]
    assert all(f.stat().st_size > 0 for f in figs)


@pytest.mark.parametrize("key, value, needle", [
    ("target.distance_m", 0.2, "target.distance_m"),
    ("target.attitude_deg", [0.0, 89.0, 0.0], "target.attitude_deg"),
    ("pipeline.range_estimators", [], "pipeline.range_estimators"),
    ("camera.lens", "wide", "camera.lens"),
])
def test_tof_000_bad_config_is_a_one_line_error_naming_the_key(key, value, needle):
    with pytest.raises(ConfigError, match=needle.replace(".", r"\.")):
        load_config(CONFIG, {key: value})
