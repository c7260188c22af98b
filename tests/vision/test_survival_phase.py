"""Cross-view match survival against the Sun phase and the surface material (vision.calibration,
vision.geometric_calibrated; issue 16)."""

import copy
import dataclasses
import json

import numpy as np
import pytest

from tests.vision.conftest import two_camera_poses
from vision.calibration import SiftCalibration, calibration_path
from vision.camera import PinholeCamera
from vision.geometric import observe_epochs, surface_features
from vision.geometric_calibrated import calibrated_feature_count, pair_phase_deg

CAM = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)


@pytest.fixture(scope="module")
def data():
    return json.loads(calibration_path().read_text(encoding="utf-8"))


def _with_phase_counts(data: dict, correct_per_phase, matchable_per_phase) -> dict:
    """fy1 with phase counts spread evenly over its ranges and angles (R, A, P), and without the joint
    counts (which would give the factors instead)."""
    d = copy.deepcopy(data)
    cv = d["targets"]["fy1"]["cross_view"]
    cv.pop("joint_expected", None)
    cv.pop("joint_correct", None)
    R, A = np.asarray(cv["survival"], dtype=float).shape
    cv["phase_correct"] = np.broadcast_to(np.asarray(correct_per_phase, float) / (R * A), (R, A, 6)).tolist()
    cv["phase_matchable"] = np.broadcast_to(np.asarray(matchable_per_phase, float) / (R * A), (R, A, 6)).tolist()
    return d


def test_phase_factor_is_correct_matches_over_those_the_table_expects(data):
    """g_p = Σ correct_p / Σ matchable_p · S(range, angle); a bin expecting fewer than 20 takes its
    neighbour's; the factor's mean over the calibration's matchable keypoints is 1 when no bin is filled."""
    S = np.asarray(data["targets"]["fy1"]["cross_view"]["survival"], dtype=float)
    matchable = np.array([400.0, 2000.0, 3000.0, 1500.0, 30.0, 0.0])
    correct = np.array([200.0, 600.0, 700.0, 300.0, 3.0, 0.0])
    cal = SiftCalibration.from_dict(_with_phase_counts(data, correct, matchable), "fy1")
    expected = matchable * S.mean()              # spread evenly over the (range, angle) cells
    g = correct / np.where(expected > 0, expected, 1.0)
    assert expected[4] < 20 <= expected[3]       # the last two bins take bin 3's factor
    want = np.concatenate([g[:4], [g[3], g[3]]])
    np.testing.assert_allclose(cal.pair_survival_phase_factor, want, rtol=1e-12)
    ok = expected >= 20
    assert np.sum(cal.pair_survival_phase_factor[ok] * expected[ok]) == pytest.approx(correct[ok].sum())


_COUNTS = ("phase_correct", "phase_matchable", "phase_redetected", "material_correct", "material_matchable",
           "joint_expected", "joint_correct")


def _without_counts(data: dict) -> dict:
    d = copy.deepcopy(data)
    for t in d["targets"].values():
        for k in _COUNTS:
            t["cross_view"].pop(k, None)
    return d


def test_a_file_without_phase_or_material_counts_has_no_such_dependence(data):
    cal = SiftCalibration.from_dict(_without_counts(data), "fy1")
    assert cal.pair_survival_phase_factor is None and cal.pair_survival_material_factor is None
    fp, ang, ph = np.array([0.02, 0.05]), np.array([10.0, 20.0]), np.array([15.0, 120.0])
    np.testing.assert_array_equal(cal.pair_survival_at(fp, ang, ph, np.array([0, 2])), cal.pair_survival_at(fp, ang))


def test_material_factor_is_correct_matches_over_those_the_table_expects(data):
    """Per material: Σ correct / Σ matchable · S(range, angle); 1 for a material expected to have fewer than 20."""
    d = _without_counts(data)
    cv = d["targets"]["fy1"]["cross_view"]
    S = np.asarray(cv["survival"], dtype=float)
    R, A = S.shape
    P = len(d["targets"]["fy1"]["materials"])
    matchable = np.zeros((R, A, P))
    correct = np.zeros((R, A, P))
    matchable[..., 0], correct[..., 0] = 1000.0, 50.0
    matchable[..., 1], correct[..., 1] = 2000.0, 900.0
    matchable[..., 2], correct[..., 2] = 10.0, 10.0          # too few: factor 1
    cv["material_matchable"], cv["material_correct"] = matchable.tolist(), correct.tolist()
    cal = SiftCalibration.from_dict(d, "fy1")
    expected = np.sum(matchable * S[:, :, None], axis=(0, 1))
    want = np.ones(P)
    want[:2] = correct.sum(axis=(0, 1))[:2] / expected[:2]
    np.testing.assert_allclose(cal.pair_survival_material_factor, want, rtol=1e-12)
    fp, ang = 0.03, 20.0
    assert cal.pair_survival_at(fp, ang, material=1) == pytest.approx(
        min(1.0, float(cal.pair_survival_at(fp, ang)) * want[1]), rel=1e-12)


def test_phase_factor_is_linear_between_bin_centres_and_held_beyond(data):
    cal = SiftCalibration.from_dict(_with_phase_counts(data, [100, 300, 500, 200, 100, 50],
                                                       [1000, 1000, 1000, 1000, 1000, 1000]), "fy1")
    g = cal.pair_survival_phase_factor
    np.testing.assert_allclose(cal.survival_phase_factor_at([0.0, 15.0, 45.0, 60.0, 170.0]),
                               [g[0], g[0], g[1], 0.5 * (g[1] + g[2]), g[5]], rtol=1e-12)
    fp, ang = 0.03, 10.0
    assert cal.pair_survival_at(fp, ang, 60.0) == pytest.approx(
        min(1.0, float(cal.pair_survival_at(fp, ang)) * 0.5 * (g[1] + g[2])), rel=1e-12)


@pytest.mark.parametrize("angle_deg", [10.0, 20.0])
def test_pair_phase_of_two_cameras_about_x(angle_deg):
    """Cameras at ±angle/2 about +x (x-y plane of H): the pair's mean line of sight is +x, so a Sun
    30° from +x towards +z has pair phase 30° and own phases arccos(cos(angle/2)·cos 30°); the Sun
    along +z: 90° for every pair and camera."""
    T = two_camera_poses(40.0, angle_deg)[None]
    a, h = np.radians(30.0), np.radians(angle_deg / 2)
    ph = pair_phase_deg(T, np.array([[np.cos(a), 0.0, np.sin(a)]]))[0]
    assert ph[0, 1] == pytest.approx(30.0, abs=1e-9) and ph[1, 0] == pytest.approx(30.0, abs=1e-9)
    own = np.degrees(np.arccos(np.cos(h) * np.cos(a)))
    np.testing.assert_allclose(np.diag(ph), [own, own], atol=1e-9)
    np.testing.assert_allclose(pair_phase_deg(T, np.array([[0.0, 0.0, 2.0]]))[0], 90.0, atol=1e-9)


def _tracks(fy1, data, factor, seed=4) -> int:
    """Tracks of one epoch (two cameras, 40 m, 10°) with a phase factor of ``factor`` in every bin."""
    from vision import calibration as vc

    d = _with_phase_counts(data, np.full(6, 1000.0), np.full(6, 1000.0))
    cal = vc.SiftCalibration.from_dict(d, "fy1")
    cal = vc.SiftCalibration(**{**cal.__dict__, "pair_survival_phase_factor": np.full(6, float(factor)),
                                "pair_survival_material_factor": np.ones(len(fy1.materials))})
    T = two_camera_poses(40.0, 10.0)
    feats = surface_features(fy1, n_features=calibrated_feature_count(CAM, fy1, T, cal), surface="outer")
    q = np.array([[0.3, -0.2, 0.5, 0.78]]) / np.linalg.norm([0.3, -0.2, 0.5, 0.78])
    obs = observe_epochs(CAM, T[None], fy1, q, np.array([[0.2, 0.1, 1.0]]), rng=seed, features=feats,
                         noise_model="calibrated", calibration=cal)[0]
    return int(np.sum(obs.feature_id >= 0))


def test_the_geometric_mode_matches_pairs_at_the_phase_scaled_survival(fy1, data):
    """Factors of 1 (phase and material) give the tracks of a file without the counts, bit for bit; a
    phase factor of 0 gives none; 2 gives more (the survival is scaled, not the detections)."""
    cal0 = SiftCalibration.from_dict(_without_counts(data), "fy1")
    T = two_camera_poses(40.0, 10.0)
    feats = surface_features(fy1, n_features=calibrated_feature_count(CAM, fy1, T, cal0), surface="outer")
    q = np.array([[0.3, -0.2, 0.5, 0.78]]) / np.linalg.norm([0.3, -0.2, 0.5, 0.78])
    base = observe_epochs(CAM, T[None], fy1, q, np.array([[0.2, 0.1, 1.0]]), rng=4, features=feats,
                          noise_model="calibrated", calibration=cal0)[0]
    one = _tracks(fy1, data, 1.0)
    assert one == int(np.sum(base.feature_id >= 0)) > 10
    assert _tracks(fy1, data, 0.0) == 0
    assert _tracks(fy1, data, 2.0) > 1.3 * one


def test_the_shipped_calibration_measures_survival_falling_with_the_sun_phase_and_the_view_angle(data):
    """The shipped file (96 attitudes per target and range) has the joint counts.  Fitted jointly, the
    survival factor of the 30-60 deg phase bin is above that of the 120-150 deg bin for both targets
    (the Sun behind the target leaves less texture to match; TOPEX 3.4x, FY-1 1.4x), and keypoints seen
    at grazing view (view angle over 75 deg) survive at under a fifth of the table's rate, face-on ones
    above it, rising bin by bin.  The product of the four factors gives back every phase bin's and
    view bin's correct matches (within 2 %: the classes with too few matches take factor 1 after the fit)."""
    for name, phase_ratio in (("fy1", 1.3), ("topex", 3.0)):
        cal = SiftCalibration.from_dict(data, name)
        g, v = cal.pair_survival_phase_factor, cal.pair_survival_view_factor
        assert g[1] > phase_ratio * g[4]
        assert v[0] < 0.2 < 1.0 < v[-1] and np.all(np.diff(v) > 0)
        cv = data["targets"][name]["cross_view"]
        expected = np.asarray(cv["joint_expected"], dtype=float)          # (phase, material, brightness, view)
        correct = np.asarray(cv["joint_correct"], dtype=float)
        f = [g, cal.pair_survival_material_factor, cal.pair_survival_brightness_factor, v]
        model = expected * np.einsum("p,m,b,v->pmbv", *f)
        for axis in (0, 3):
            other = tuple(a for a in range(4) if a != axis)
            own = expected.sum(axis=other) >= 20
            np.testing.assert_allclose(model.sum(axis=other)[own], correct.sum(axis=other)[own], rtol=0.02)
        assert cal.pair_survival_material_factor.shape == (len(data["targets"][name]["materials"]),)


def test_view_factors_of_one_change_nothing_and_of_zero_leave_no_track(fy1, data):
    """The geometric mode scales each pair's survival by the geometric mean of its two views' view-angle
    factors: factors of 1 give the tracks without the factor, bit for bit; 0 gives none."""
    cal = SiftCalibration.from_dict(data, "fy1")
    T = two_camera_poses(40.0, 10.0)
    feats = surface_features(fy1, n_features=calibrated_feature_count(CAM, fy1, T, cal), surface="outer")
    q = np.array([[0.3, -0.2, 0.5, 0.78]]) / np.linalg.norm([0.3, -0.2, 0.5, 0.78])

    def tracks(view_factor):
        c = dataclasses.replace(cal, pair_survival_view_factor=view_factor)
        obs = observe_epochs(CAM, T[None], fy1, q, np.array([[0.2, 0.1, 1.0]]), rng=4, features=feats,
                             noise_model="calibrated", calibration=c)[0]
        return obs.feature_id

    none = tracks(None)
    assert len(none) > 10
    np.testing.assert_array_equal(tracks(np.ones(5)), none)
    assert np.sum(tracks(np.zeros(5)) >= 0) == 0
    assert cal.survival_view_factor_at(np.array([0.1, -0.1, 0.3, 0.99])).tolist() == \
        [cal.pair_survival_view_factor[i] for i in (0, 0, 1, 4)]
