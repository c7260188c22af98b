"""coobs calibrate: the measurement study against the renderer's truth, and its sigma estimator."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from coobs.cli import app
from experiments.studies.rendered_calibration import _sigma_per_bin
from vision.calibration import SiftCalibration

runner = CliRunner()


def test_sigma_per_bin_recovers_known_per_bin_sigmas_from_pair_residuals():
    """Pairs of keypoints of two size bins: e² per axis = σ²(a) + σ²(b); NNLS returns the σ drawn."""
    rng = np.random.default_rng(3)
    sigma = np.array([0.1, 0.2, 0.4])
    bins = rng.integers(0, 3, size=(60000, 2))
    e = rng.normal(size=(60000, 2)) * np.sqrt(sigma[bins[:, 0]] ** 2 + sigma[bins[:, 1]] ** 2)[:, None]
    est, counts = _sigma_per_bin(bins, np.mean(e**2, axis=1), 3)
    np.testing.assert_allclose(est, sigma, rtol=0.05)  # the smallest σ² is a small difference
    assert counts.sum() == 120000


def test_quick_calibration_writes_a_readable_file_with_its_command(tmp_path):
    out = tmp_path / "cal.json"
    res = runner.invoke(app, ["calibrate", "--quick", "--attitudes", "3", "--targets", "fy1", "--ranges-m", "40",
                               "--out", str(out)])
    assert res.exit_code == 0, res.output
    data = json.loads(out.read_text())
    t = data["targets"]["fy1"]
    assert t["samples_per_range"] == [3] and data["provenance"]["spec"]["attitudes"] == 3
    assert "--quick" in data["provenance"]["command"]
    # truth-checked matches exist and their residual is sub-pixel (the truth tolerance is 2 px)
    assert t["cross_view"]["correct"][0][0] > 10
    assert 0.05 < t["pair_residual_rms_px_per_axis"] < 1.0
    cal = SiftCalibration.from_dict(data, "fy1")
    assert np.all(cal.sigma_px > 0) and 0 < cal.pair_survival[0, 0] <= 1
    # the phase and material counts split the cross-view counts (keypoints off the target have no material)
    cv = t["cross_view"]
    for k in ("matchable", "correct"):
        total = np.asarray(cv[k])
        np.testing.assert_array_equal(np.sum(cv[f"phase_{k}"], axis=-1), total)
        assert np.all(np.sum(cv[f"material_{k}"], axis=-1) <= total)
        assert np.all(np.sum(cv[f"material_{k}"], axis=-1) >= 0.9 * total)
        # each keypoint on the target has one brightness bin as it has one material
        np.testing.assert_array_equal(np.sum(cv[f"brightness_{k}"], axis=-1), np.sum(cv[f"material_{k}"], axis=-1))
    assert np.all(np.asarray(cv["phase_correct"]) <= np.asarray(cv["phase_redetected"]))
    # the joint counts split the correct matches of the target's keypoints as the material counts do, and
    # their expectation is the table's survival times the matchable keypoints (one range: one table row)
    joint_c = np.asarray(cv["joint_correct"])
    assert joint_c.shape == (6, 7, 9, 5) and joint_c.sum() == np.sum(cv["material_correct"])
    np.testing.assert_array_equal(joint_c.sum(axis=(0, 2, 3)), np.sum(cv["material_correct"], axis=(0, 1)))
    np.testing.assert_array_equal(joint_c.sum(axis=(0, 1, 3)), np.sum(cv["brightness_correct"], axis=(0, 1)))
    S = np.asarray(cal.pair_survival)
    assert np.sum(cv["joint_expected"]) == pytest.approx(float(np.sum(np.asarray(cv["material_matchable"]).sum(-1) * S)),
                                                         rel=1e-4)
    assert cal.pair_survival_phase_factor.shape == (6,) and cal.pair_survival_material_factor.shape == (7,)
    # the detection counts per relative-brightness bin: every keypoint on the target in one bin, and
    # the expectation of the density tables sums to the keypoints (the tables hold the mean)
    np.testing.assert_array_equal(np.sum(t["brightness_keypoints"], axis=-1), np.sum(t["keypoints"], axis=(1, 2)))
    assert np.sum(t["brightness_expected_keypoints"]) > 0
    assert cal.detection_brightness_factor.shape == (1, 9) and cal.pair_survival_brightness_factor.shape == (9,)
    # the triangulation σ² inflation step ran (one attitude, 10°) and says how it was made
    assert data["provenance"]["triangulation_nees"]["spec"]["attitudes"] == 1
    assert sum(map(sum, t["triangulation_nees"]["points"][0])) > 0
    assert cal.sigma2_inflation.shape == (1, 1, 3) and np.all(np.isfinite(cal.sigma2_inflation))


def test_calibrate_refuses_an_unknown_target_in_one_line():
    res = runner.invoke(app, ["calibrate", "--quick", "--targets", "fy2"])
    assert res.exit_code == 2 and "--targets" in res.output and len(res.output.strip().splitlines()) == 1


def test_calibrate_with_too_few_samples_fails_in_one_line_and_writes_nothing(tmp_path):
    """At 2 km the target is a few pixels across: no match, so no table can be filled."""
    out = tmp_path / "cal.json"
    res = runner.invoke(app, ["calibrate", "--quick", "--targets", "fy1", "--ranges-m", "2000", "--out", str(out)])
    assert res.exit_code == 2, res.output
    assert "--attitudes" in res.output and "Traceback" not in res.output and not out.exists()


def test_nees_only_adds_the_inflation_and_keeps_the_other_tables(tmp_path):
    from vision.calibration import calibration_path

    out = tmp_path / "cal.json"
    shipped = json.loads(calibration_path().read_text())
    for t in shipped["targets"].values():
        t.pop("triangulation_nees", None)
    shipped["provenance"].pop("triangulation_nees", None)
    shipped["targets"] = {"fy1": shipped["targets"]["fy1"]}
    out.write_text(json.dumps(shipped))
    res = runner.invoke(app, ["calibrate", "--nees-only", "--quick", "--out", str(out)])
    assert res.exit_code == 0, res.output
    data = json.loads(out.read_text())
    t = data["targets"]["fy1"]
    assert t["sigma_px"] == shipped["targets"]["fy1"]["sigma_px"] and t["keypoints"] == shipped["targets"]["fy1"]["keypoints"]
    p = data["provenance"]["triangulation_nees"]
    assert p["command"].startswith("coobs calibrate --nees-only --quick") and p["spec"]["attitudes"] == 1
    assert data["format_version"] == 3 and len(t["triangulation_nees"]["points"]) == len(t["ranges_m"])
    tn = t["triangulation_nees"]                 # the tables beyond each epoch's variance factor, same shape
    assert np.shape(tn["epoch_sigma2_inflation"]) == np.shape(tn["sigma2_inflation"])
    assert np.shape(tn["epoch_increment_sigma2_inflation"]) == np.shape(tn["increment_sigma2_inflation"])
    # per range and surface material: the NEES factors and the points they rest on
    shape = (len(t["ranges_m"]), len(t["materials"]))
    for key in ("material_sigma2_factor", "material_increment_sigma2_factor", "material_points",
                "material_increment_pairs"):
        assert np.shape(tn[key]) == shape, key
    assert sum(map(sum, tn["material_points"])) == sum(np.ravel(tn["points"]))
    # the spread of the errors beyond the tables, and the lognormal spread that gives it
    for key in ("normalized_nees_median", "normalized_nees_mean", "error_log_spread", "increment_error_log_spread"):
        assert len(tn[key]) == len(t["ranges_m"]), key
    assert all(0.0 <= s <= 4.0 for s in tn["error_log_spread"])


def test_track_material_is_the_material_of_the_surface_a_ray_hits():
    """Points where rays from outside hit FY-1 (what a rendered track's truth point is) get the hit
    triangle's material; NaN points get -1."""
    import open3d as o3d

    from experiments.studies.nees_calibration import track_material
    from vision.target import fy1_target

    t = fy1_target()
    rng = np.random.default_rng(0)
    d = rng.normal(size=(2000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    origin = -20.0 * d + rng.normal(scale=0.5, size=(2000, 3))  # 20 m out, aimed near the centre
    hits = t.scene.cast_rays(o3d.core.Tensor(np.c_[origin, d].astype(np.float32)))
    th = hits["t_hit"].numpy()
    hit = np.isfinite(th)
    assert hit.sum() > 500
    X = origin[hit] + th[hit, None] * d[hit]
    got = track_material(t, np.vstack([X, np.full((1, 3), np.nan)]))
    assert got[-1] == -1
    want = t.triangle_material[hits["primitive_ids"].numpy().astype(np.int64)[hit]]
    assert np.mean(got[:-1] == want) > 0.995
