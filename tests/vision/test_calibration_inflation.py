"""The measured σ² inflation of triangulated tracks and of increments (vision.calibration, issue 16)."""

import copy
import json

import numpy as np
import pytest

from formation.geometry import symmetric_views
from vision.calibration import (
    TRACK_CLASSES,
    SiftCalibration,
    calibration_path,
    load_calibration,
    track_class,
)
from vision.camera import PinholeCamera
from vision.observation import Observation


@pytest.fixture(scope="module")
def data():
    return json.loads(calibration_path().read_text(encoding="utf-8"))


def _with_table(data: dict) -> dict:
    d = copy.deepcopy(data)
    t = d["targets"]["fy1"]
    t["triangulation_nees"] = {
        "angle_deg": [10.0, 20.0], "classes": list(TRACK_CLASSES),
        # (range, angle, class); one class missing at 80 m takes the others' mean there
        "sigma2_inflation": [[[1.2, 1.0, 1.8], [1.6, 1.4, 2.2]], [[0.6, 0.7, None], [0.8, 0.9, None]]],
        "increment_sigma2_inflation": [[[1.0, 0.9, 1.5], [1.0, 0.9, 1.5]], [[0.5, 0.5, 0.5], [0.5, 0.5, 0.5]]],
    }
    return d


def _observation(n_cameras: int, seen: np.ndarray, distance_m: float = 40.0, angle_deg: float = 10.0) -> Observation:
    cam = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)
    T = symmetric_views(n_cameras, distance_m, angle_deg).T_CW
    M = len(seen)
    uv = np.where(seen[..., None], np.full((M, n_cameras, 2), 500.0), np.nan)
    return Observation(uv_px=uv, descriptors=np.ones((M, 4), np.float32) / 2, K=np.broadcast_to(cam.K, (n_cameras, 3, 3)).copy(),
                       T_CW=T, image_size=(1024, 1024), pixel_sigma_px=0.2, feature_id=np.arange(M),
                       X_T_true=np.zeros((M, 3)), keypoint_size_px=np.where(seen, 2.0, np.nan))


def test_a_file_without_the_table_gives_no_inflation(data):
    d = copy.deepcopy(data)
    for t in d["targets"].values():
        t.pop("triangulation_nees", None)
    cal = SiftCalibration.from_dict(d, "fy1")
    obs = _observation(3, np.array([[True, True, True], [True, False, True]]))
    np.testing.assert_array_equal(cal.track_sigma_px(obs), cal.track_sigma_px(obs, inflate=False))
    np.testing.assert_array_equal(cal.track_sigma_px(obs, increment=True), cal.track_sigma_px(obs, inflate=False))


def test_track_class_and_angle_pick_the_inflation(data):
    cal = SiftCalibration.from_dict(_with_table(data), "fy1")
    assert track_class(np.array([2, 3, 2]), 3).tolist() == [2, 1, 2]
    assert track_class(np.array([2]), 2).tolist() == [0]
    assert track_class(np.array([4, 3, 2]), 5).tolist() == [1, 1, 2]   # more cameras: the 3-camera classes
    obs3 = _observation(3, np.array([[True, True, True], [True, False, True]]), angle_deg=10.0)
    base = cal.track_sigma_px(obs3, inflate=False)
    ratio2 = (cal.track_sigma_px(obs3) / base) ** 2
    np.testing.assert_allclose(ratio2[0], 1.0, rtol=1e-9)              # "3 of 3" at 10°, 40 m
    np.testing.assert_allclose(ratio2[1, [0, 2]], 1.8, rtol=1e-9)      # "2 of 3"
    np.testing.assert_allclose((cal.track_sigma_px(obs3, increment=True) / base)[1, [0, 2]] ** 2, 1.5, rtol=1e-9)
    obs2 = _observation(2, np.array([[True, True]]), angle_deg=15.0)   # halfway between 10° and 20°
    np.testing.assert_allclose((cal.track_sigma_px(obs2) / cal.track_sigma_px(obs2, inflate=False)) ** 2, 1.4,
                               rtol=1e-6)
    # 80 m: "2 of 3" was not measured and takes the mean of the other classes at that angle
    np.testing.assert_allclose(cal.sigma_inflation(cal.footprint_m_per_px[1], 10.0, 2), 0.65, rtol=1e-9)
    # beyond the calibrated footprints and angles the nearest value is held
    np.testing.assert_allclose(cal.sigma_inflation(10 * cal.footprint_m_per_px[1], 40.0, 0), 0.8, rtol=1e-9)


def test_the_shipped_file_has_the_inflation_with_its_provenance(data):
    p = data["provenance"]["triangulation_nees"]
    assert p["command"].startswith("coobs calibrate")
    assert p["spec"]["attitudes"] >= 12 and p["spec"]["angles_deg"] == [10.0, 20.0]
    for name in ("fy1", "topex"):
        t = data["targets"][name]["triangulation_nees"]
        assert np.sum(t["points"]) > 2000 and np.sum(t["increment_pairs"]) > 1000
        cal = load_calibration(name)
        assert cal.sigma2_inflation.shape == (2, 2, 3)
        assert np.all((cal.sigma2_inflation > 0.2) & (cal.sigma2_inflation < 5.0))
        # much of a keypoint's error is the same at two epochs 1° apart: an increment sees less of it
        assert np.mean(cal.increment_sigma2_inflation) < np.mean(cal.sigma2_inflation)
        # beyond the tables and the material factors the NEES keep their mean (3) but not a Gaussian's
        # median (2.08-2.37): the heavy tail the lognormal spread reproduces
        assert np.allclose(t["normalized_nees_mean"], 3.0, rtol=0.05)
        assert max(t["normalized_nees_median"]) < 1.6
        assert np.all((cal.error_log_spread > 0.5) & (cal.error_log_spread < 1.5))


def test_epoch_tables_scale_the_inflation_by_the_epochs_own_factor(data):
    """With the epoch tables, σ² = size σ² × the epoch's variance factor (vision.epoch_variance, here of
    tracks whose keypoints all sit at one pixel, so each pair's residual is that pixel's epipolar
    residual) × the inflation beyond it; without them, asking for them is refused by name."""
    from vision.epoch_variance import epoch_variance_factor

    d = _with_table(data)
    plain = SiftCalibration.from_dict(d, "fy1")
    with pytest.raises(ValueError, match="epoch"):
        plain.sigma_inflation(plain.footprint_m_per_px[0], 10.0, 0, epoch=True)
    t = d["targets"]["fy1"]["triangulation_nees"]
    t["epoch_sigma2_inflation"] = [[[2.0, 2.0, 2.0], [2.0, 2.0, 2.0]], [[2.0, 2.0, 2.0], [2.0, 2.0, 2.0]]]
    t["epoch_increment_sigma2_inflation"] = [[[0.5, 0.5, 0.5], [0.5, 0.5, 0.5]], [[0.5, 0.5, 0.5], [0.5, 0.5, 0.5]]]
    cal = SiftCalibration.from_dict(d, "fy1")
    obs = _observation(3, np.array([[True, True, True], [True, False, True]]))
    size = cal.track_sigma_px(obs, inflate=False)
    factor = epoch_variance_factor(obs.uv_px, obs.K, obs.T_CW, size)
    seen = obs.seen
    np.testing.assert_allclose((cal.track_sigma_px(obs)[seen] / size[seen]) ** 2, 2.0 * factor, rtol=1e-9)
    np.testing.assert_allclose((cal.track_sigma_px(obs, increment=True)[seen] / size[seen]) ** 2, 0.5 * factor,
                               rtol=1e-9)
    # epoch_scale=False: the average table, as before the epoch factor
    np.testing.assert_allclose(cal.track_sigma_px(obs, epoch_scale=False), plain.track_sigma_px(obs), rtol=1e-12)


def test_the_shipped_epoch_factor_explains_part_of_the_epochs_spread(data):
    """The calibration's own record: dividing each epoch's mean NEES by its factor shrinks the spread of
    their logarithm (FY-1 0.62 -> 0.37, TOPEX 0.44 -> 0.30 when made), with a positive correlation."""
    for name in ("fy1", "topex"):
        s = data["targets"][name]["triangulation_nees"]["epoch_log_nees_spread"]
        assert s["epochs"] >= 50
        assert s["over_epoch_factor"] < 0.8 * s["size_sigma"] and s["correlation"] > 0.5
        cal = load_calibration(name)
        assert cal.epoch_sigma2_inflation.shape == cal.sigma2_inflation.shape


def test_material_factors_interpolate_in_footprint_and_default_to_one(data):
    """The σ² factors of a surface material: the table's value at each calibrated image scale, linear in
    log footprint between them and held beyond; 1 for a file without them and for an unknown material."""
    d = _with_table(data)
    P = len(d["targets"]["fy1"]["materials"])
    plain = SiftCalibration.from_dict(d, "fy1")
    fp = plain.footprint_m_per_px
    g, h = plain.material_noise_factors(fp, np.array([0, 1]))
    assert np.all(g == 1.0) and np.all(h == 1.0)
    f = np.arange(1, P + 1, dtype=float)
    d["targets"]["fy1"]["triangulation_nees"]["material_sigma2_factor"] = [list(f), list(2 * f)]
    d["targets"]["fy1"]["triangulation_nees"]["material_increment_sigma2_factor"] = [list(f / 2), list(f)]
    cal = SiftCalibration.from_dict(d, "fy1")
    g, h = cal.material_noise_factors(fp[:, None], np.arange(P)[None, :])
    np.testing.assert_allclose(g, [f, 2 * f])
    np.testing.assert_allclose(h, [f / 2, f])
    mid = np.sqrt(fp[0] * fp[1])                                  # halfway in log footprint
    g, _ = cal.material_noise_factors(np.array([mid, fp[0] / 3, fp[1] * 3]), np.array([2, 2, 2]))
    np.testing.assert_allclose(g, [1.5 * f[2], f[2], 2 * f[2]])
    g, h = cal.material_noise_factors(fp[0], np.array([-1, P]))
    assert np.all(g == 1.0) and np.all(h == 1.0)


def test_material_factor_is_the_nees_over_what_the_class_tables_predict():
    """Per material: summed NEES over the class table's mean times the material's points in each
    (angle, class).  Without pseudo-points the factors, weighted by the NEES the class tables predict
    for each material, average to 1; the pseudo-points at 1 pull a material seen little towards 1
    and leave one seen much nearly where it was."""
    from experiments.studies.nees_calibration import _material_factor

    rng = np.random.default_rng(3)
    A, C, P = 2, 3, 4
    counts = rng.integers(50, 400, size=(A, C, P)).astype(float)
    truth = np.array([0.5, 1.0, 2.0, 4.0])
    scale = rng.uniform(1.0, 5.0, size=(A, C))                    # the classes' own NEES levels
    sums = np.stack([counts * scale[:, :, None] * truth, counts], axis=-1)
    table = sums[..., 0].sum(axis=2) / counts.sum(axis=2)         # the class tables' mean NEES
    f = _material_factor(sums, table, 0)
    expected = np.einsum("ac,acp->p", table, counts)
    np.testing.assert_allclose(np.sum(f * expected) / np.sum(expected), 1.0, rtol=1e-12)
    # with one table value everywhere the factor is the material's mean NEES over it
    flat = np.stack([counts * truth, counts], axis=-1)
    np.testing.assert_allclose(_material_factor(flat, np.full((A, C), 1.5), 0), truth / 1.5, rtol=1e-12)
    # n points of mean NEES 1.5 x 4 with 100 pseudo-points at 1: (4 n + 100) / (n + 100)
    one = np.zeros((1, 1, 2, 2))
    one[0, 0] = [[6.0 * 20, 20], [6.0 * 20000, 20000]]            # 20 and 20 000 points at 4x the table
    np.testing.assert_allclose(_material_factor(one, np.full((1, 1), 1.5), 100),
                               [(4 * 20 + 100) / 120, (4 * 20000 + 100) / 20100], rtol=1e-12)
    assert _material_factor(np.zeros((1, 1, 1, 2)), np.ones((1, 1)), 100)[0] == 1.0   # never seen: 1


def test_error_spread_interpolates_in_footprint_and_is_zero_without_it(data):
    d = _with_table(data)
    fp = SiftCalibration.from_dict(d, "fy1").footprint_m_per_px
    assert np.all(SiftCalibration.from_dict(d, "fy1").error_spread_at(fp) == 0.0)
    d["targets"]["fy1"]["triangulation_nees"]["error_log_spread"] = [0.6, 1.0]
    cal = SiftCalibration.from_dict(d, "fy1")
    np.testing.assert_allclose(cal.error_spread_at(np.array([fp[0], np.sqrt(fp[0] * fp[1]), fp[1], 10 * fp[1]])),
                               [0.6, 0.8, 1.0, 1.0])
