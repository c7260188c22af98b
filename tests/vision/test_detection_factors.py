"""Joint detection density of (view, Sun) cell, material and relative brightness (vision.calibration.detection_factors)."""

import copy
import json

import numpy as np
import pytest

from vision.calibration import SiftCalibration, calibration_path
from vision.calibration.detection_factors import (
    MIN_MATERIAL_AREA_M2,
    detection_factors,
    sequential_expected_keypoints,
)
from vision.calibration.survival_factors import fit_main_effects

R, B, V, S, P = 2, 9, 5, 6, 4


def _areas(rng):
    """Area per (range, brightness, view, Sun, material) bin, m², as the renderer's pixels fill it:
    unlit surface (Sun bin 0) is exactly brightness bin 0, lit surface never."""
    a = rng.uniform(0.5, 20.0, size=(R, B, V, S, P))
    a[:, 0, :, 1:] = 0.0
    a[:, 1:, :, 0] = 0.0
    return a


def _model(dens, mat, bright, area):
    return np.einsum("rbvsp,rvs,rp,rb->rbvsp", area, dens, mat, bright)


def _truth(rng):
    return (rng.uniform(5.0, 60.0, (R, V, S)), rng.uniform(0.3, 2.0, (R, P)), rng.uniform(0.2, 2.0, (R, B)))


def test_a_noise_free_product_is_recovered_in_every_cell():
    """keypoints = area · D · M · F exactly (every class well measured): the joint fit gives back the
    keypoints of every populated cell to 1e-8 (the factors themselves only up to the shared scale)."""
    rng = np.random.default_rng(0)
    area = _areas(rng)
    kp = _model(*_truth(rng), area)
    fit = detection_factors(area, kp)
    assert fit[3].all()                                    # every cell has more than 2 m²
    np.testing.assert_allclose(_model(*fit[:3], area), kp, rtol=1e-8)


def test_the_fit_reproduces_the_material_brightness_and_cell_margins_of_poisson_counts():
    """Poisson keypoints: the model's keypoints per material, per lit brightness bin and per (view,
    Sun) cell equal the counted ones (the maximum-likelihood main-effects fit), to 1e-6."""
    rng = np.random.default_rng(1)
    area = _areas(rng)
    kp = rng.poisson(_model(*_truth(rng), area))
    lam = _model(*detection_factors(area, kp)[:3], area)
    for axes in ((1, 2, 3), (2, 3, 4)):                   # per material; per brightness bin
        np.testing.assert_allclose(lam.sum(axis=axes), kp.sum(axis=axes), rtol=1e-6)
    np.testing.assert_allclose(lam.sum(axis=(1, 4)), kp.sum(axis=(1, 4)), rtol=1e-6)


def test_joint_factors_do_not_count_the_material_of_a_cell_twice():
    """Material 0 lies mostly in the face-on Sun bin, the others in an oblique one, and only the
    material changes the density (material 0 three times the others).  The sequential factors (each
    cell's density, then the material's density over the mean, then the brightness bin's keypoints over
    what those predict) put the material's effect into the cell's density too and over-predict
    material 0 by 34 %, on the calibration's own counts; the joint fit gives every material's count
    exactly."""
    area = np.zeros((1, B, V, S, P))
    area[0, 8, :, 5, 0], area[0, 8, :, 5, 1:] = 40.0, 4.0      # face-on: mostly material 0
    area[0, 8, :, 2, 0], area[0, 8, :, 2, 1:] = 4.0, 40.0      # oblique: mostly the others
    dens = np.full((1, V, S), 10.0)
    kp = _model(dens, np.array([[3.0, 1.0, 1.0, 1.0]]), np.ones((1, B)), area)
    t = {"keypoints": kp.sum(axis=(1, 4)).tolist(), "visible_area_m2": area.sum(axis=(1, 4)).tolist(),
         "material_keypoints": kp.sum(axis=(1, 2, 3)).tolist(), "material_area_m2": area.sum(axis=(1, 2, 3)).tolist(),
         "brightness_keypoints": kp.sum(axis=(2, 3, 4)).tolist()}
    seq_cal = _calibration(t)
    t["brightness_expected_keypoints"] = sequential_expected_keypoints(seq_cal.density_per_m2, seq_cal.material_factor,
                                                                       area).tolist()
    seq = _calibration(t)
    lam_seq = _model(seq.density_per_m2, seq.material_factor, seq.detection_brightness_factor, area)
    per_material = kp.sum(axis=(1, 2, 3))[0]
    assert lam_seq.sum(axis=(1, 2, 3))[0, 0] / per_material[0] == pytest.approx(1.336, abs=0.01)
    joint = _calibration({**t, "detection_joint": {"area_m2": area.tolist(), "keypoints": kp.tolist()}})
    lam = _model(joint.density_per_m2, joint.material_factor, joint.detection_brightness_factor, area)
    np.testing.assert_allclose(lam.sum(axis=(1, 2, 3))[0], per_material, rtol=1e-8)


def _calibration(detection: dict) -> SiftCalibration:
    """The shipped FY-1 calibration with its detection counts replaced by ``detection`` (one range)."""
    t = copy.deepcopy(json.loads(calibration_path().read_text())["targets"]["fy1"])
    for k in ("brightness_expected_keypoints", "detection_joint"):
        t.pop(k, None)
    t.update(detection)
    n = len(np.asarray(detection["keypoints"]))
    for k in ("ranges_m", "footprint_m_per_px", "track_size_px_quantiles_by_range", "sigma_px_by_range"):
        t[k] = t[k][:n]
    return SiftCalibration.from_dict({"targets": {"fy1": t}}, "fy1")


def test_a_material_seen_too_little_keeps_the_mean_density():
    """A material seen on less than MIN_MATERIAL_AREA_M2 with no keypoint gets no factor of its own:
    its density stays within 10 % of the mean of the others (a free factor would be 0)."""
    rng = np.random.default_rng(2)
    area = _areas(rng)
    area[..., 3] *= 0.5 * MIN_MATERIAL_AREA_M2 / area[..., 3].sum(axis=(1, 2, 3))[:, None, None, None]
    truth = _truth(rng)
    truth[1][:] = 1.0
    kp = rng.poisson(_model(*truth, area))
    kp[..., 3] = 0
    _, mat, _, _ = detection_factors(area, kp)
    assert np.all(mat[:, 3] > 0.9 * mat[:, :3].mean(axis=1))


def test_fixed_classes_keep_their_factor_and_free_ones_match_their_margins():
    """fit_main_effects(fixed=...): a fixed class stays at the free classes' scale (its factor 1 before
    the shared scale is moved), and the free classes of that axis still reproduce their margins."""
    rng = np.random.default_rng(3)
    expected = rng.uniform(1.0, 30.0, size=(5, 6, 7))
    observed = rng.poisson(expected * 1.7)
    fixed = [np.array([True, False, False, False, False]), np.zeros(6, bool), np.zeros(7, bool)]
    f = fit_main_effects(expected, observed, fixed=fixed)
    model = expected * f[0][:, None, None] * f[1][None, :, None] * f[2][None, None, :]
    np.testing.assert_allclose(model.sum(axis=(1, 2))[1:], observed.sum(axis=(1, 2))[1:], rtol=1e-8)
    np.testing.assert_allclose(model.sum(axis=(0, 2)), observed.sum(axis=(0, 2)), rtol=1e-8)


def test_mismatched_tables_are_refused_with_one_line():
    with pytest.raises(ValueError, match=r"^area_m2 and keypoints must both be \(R, B, V, S, P\), got \(2, 3\) and \(2, 3, 1\)$"):
        detection_factors(np.ones((2, 3)), np.ones((2, 3, 1)))


def test_the_shipped_calibration_reproduces_its_detection_margins():
    """On the shipped file (both targets, both ranges): the joint density reproduces the counted
    keypoints of every (view, Sun) cell measured, and of every material seen on at least
    MIN_MATERIAL_AREA_M2 with at least 99 % of its keypoints in measured cells (a sparse cell's density
    is the product of its margins, not fitted), within 1 %."""
    data = json.loads(calibration_path().read_text())
    for name in ("fy1", "topex"):
        t = data["targets"][name]
        area = np.asarray(t["detection_joint"]["area_m2"])
        kp = np.asarray(t["detection_joint"]["keypoints"], dtype=float)
        cal = SiftCalibration.from_dict(data, name)
        lam = _model(cal.density_per_m2, cal.material_factor, cal.detection_brightness_factor, area)
        in_measured = np.einsum("rbvsp,rvs->rp", kp, cal.measured_cell.astype(float))
        seen = (area.sum(axis=(1, 2, 3)) >= MIN_MATERIAL_AREA_M2) & (in_measured >= 0.99 * kp.sum(axis=(1, 2, 3)))
        assert seen.sum() >= 0.6 * seen.size
        np.testing.assert_allclose(lam.sum(axis=(1, 2, 3))[seen], kp.sum(axis=(1, 2, 3))[seen], rtol=0.01)
        cells = cal.measured_cell
        np.testing.assert_allclose(lam.sum(axis=(1, 4))[cells], kp.sum(axis=(1, 4))[cells], rtol=0.01)
