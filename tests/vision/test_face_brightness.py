"""A face's brightness relative to the auto-exposure, and the detection factor it carries
(vision.face_brightness, vision.calibration, vision.calibrated_detection; issue 16)."""

import copy
import json

import numpy as np
import pytest

from attitude.quaternion import matrix_from_quat, quat_normalize
from tests.vision.conftest import two_camera_poses
from vision.calibration import SiftCalibration, calibration_path
from vision.camera import PinholeCamera
from vision.face_brightness import (
    BRIGHTNESS_EDGES,
    EXPOSURE_PERCENTILE,
    brightness_bin,
    face_radiance,
    material_optics,
    reference_radiance,
    sample_references,
)
from vision.geometric import surface_features
from vision.geometric_calibrated import calibrated_feature_count
from vision.render import render

CAM = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)


@pytest.fixture(scope="module")
def data():
    """The shipped file without its joint detection counts: the sequential brightness factor under test
    (the joint fit, vision.calibration.detection_factors, has its own tests)."""
    d = json.loads(calibration_path().read_text(encoding="utf-8"))
    for t in d["targets"].values():
        t.pop("detection_joint")
    return d


def test_face_radiance_is_the_renderers_lambert_and_blinn_phong_terms(fy1):
    """albedo·cos_sun + k_s·(n·h)^shininess of the material where lit, 0 elsewhere."""
    albedo, ks, ns = material_optics(fy1)
    mat = np.array([0, 2, 2, 3])
    cos_s = np.array([0.5, 0.2, 0.9, 0.7])
    n_h = np.array([0.9, 0.99, -0.3, 0.5])
    lit = np.array([True, True, True, False])
    want = albedo[mat] * cos_s + ks[mat] * np.maximum(n_h, 0) ** ns[mat]
    want[3] = 0.0
    np.testing.assert_allclose(face_radiance(mat, cos_s, n_h, lit, (albedo, ks, ns)), want, rtol=1e-12)
    assert fy1.materials[2].albedo == albedo[2] and fy1.materials[2].specular == ks[2]


def test_reference_is_the_weighted_percentile_of_the_positive_radiance():
    """Unweighted: numpy's inverted-CDF percentile of the positive values; integer weights: the
    same of the values repeated that many times; nothing positive: NaN."""
    g = np.random.default_rng(3)
    L = np.where(g.random(500) < 0.3, 0.0, g.random(500))
    assert reference_radiance(L) == np.percentile(L[L > 0], EXPOSURE_PERCENTILE, method="inverted_cdf")
    w = g.integers(1, 5, size=500)
    rep = np.repeat(L, w)
    assert reference_radiance(L, w) == np.percentile(rep[rep > 0], EXPOSURE_PERCENTILE, method="inverted_cdf")
    batch = reference_radiance(np.stack([L, 2 * L, np.zeros(500)]))
    np.testing.assert_allclose(batch[:2], [reference_radiance(L), 2 * reference_radiance(L)], rtol=1e-12)
    assert np.isnan(batch[2])
    assert list(brightness_bin([0.0, np.nan, 0.05, 0.1, 0.15, 5.0])) == [0, 0, 1, 2, 3, len(BRIGHTNESS_EDGES) - 2]


def test_the_geometric_reference_is_the_rendered_images_own(fy1):
    """The reference radiance of the geometric mode (area-weighted sample of the outer surface, its
    occlusion tabulated per direction) against the same percentile over the pixels of the rendered
    image, on eight random attitudes and Sun directions at 40 m: within 5 % in at least six (over 40
    frames 80 % are, 57 % without the occlusion table)."""
    g = np.random.default_rng(11)
    T = two_camera_poses(40.0, 10.0)[0]
    f = np.sqrt(CAM.K[0, 0] * CAM.K[1, 1])
    optics = material_optics(fy1)
    rel = []
    for _ in range(8):
        q = quat_normalize(g.normal(size=4))
        sun = g.normal(size=3)
        sun /= np.linalg.norm(sun)
        r = render(CAM, T, fy1, q, sun, rng=0)
        R_HT = matrix_from_quat(q)
        s_T = R_HT.T @ sun
        v, u = np.nonzero(r.mask)
        n = fy1.triangle_normals_T[r.triangle_id[v, u]]
        R_CT = T[:3, :3] @ R_HT
        c_T = -R_CT.T @ T[:3, 3]
        to_cam = c_T - r.X_T[v, u]
        to_cam /= np.linalg.norm(to_cam, axis=1, keepdims=True)
        side = np.where(np.sum(n * to_cam, axis=1) >= 0, 1.0, -1.0)
        h = to_cam + s_T
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        cos_s = side * (n @ s_T)
        L = face_radiance(fy1.triangle_material[r.triangle_id[v, u]], cos_s, side * np.sum(n * h, axis=1),
                          cos_s > 0, optics)
        pixels = reference_radiance(L)
        geo = sample_references(R_CT[None, None], c_T[None, None], s_T[None], np.array([f]), fy1)[0, 0]
        rel.append(abs(geo / pixels - 1.0))
    assert np.sum(np.array(rel) < 0.05) >= 6, rel


def _with_factor(data: dict, factor) -> SiftCalibration:
    """fy1 with a detection brightness factor ``factor`` (per bin) from its counts."""
    d = copy.deepcopy(data)
    t = d["targets"]["fy1"]
    B = len(BRIGHTNESS_EDGES) - 1
    expected = np.full((len(t["ranges_m"]), B), 100.0)
    t["brightness_expected_keypoints"] = expected.tolist()
    t["brightness_keypoints"] = (expected * np.asarray(factor, dtype=float)).tolist()
    return SiftCalibration.from_dict(d, "fy1")


def test_the_factor_is_keypoints_over_those_the_tables_expect(data):
    """Per range and bin: keypoints / expected; where a range expects fewer than 20, the factor pooled
    over the ranges, and 1 where that too is short; between the ranges linear in log footprint; no
    counts: no factor."""
    d = copy.deepcopy(data)
    t = d["targets"]["fy1"]
    B = len(BRIGHTNESS_EDGES) - 1
    kp = np.stack([np.arange(B) * 10.0, np.arange(B) * 20.0])
    exp = np.full((2, B), 50.0)
    exp[:, 1] = 5.0                                 # 10 expected in all: factor 1
    exp[0, 2] = 12.0                                # short at the first range only: the pooled factor
    t["brightness_keypoints"], t["brightness_expected_keypoints"] = kp.tolist(), exp.tolist()
    cal = SiftCalibration.from_dict(d, "fy1")
    want = kp / exp
    want[:, 1] = 1.0
    want[0, 2] = kp[:, 2].sum() / exp[:, 2].sum()
    np.testing.assert_allclose(cal.detection_brightness_factor, want, rtol=1e-12)
    fp0, fp1 = cal.footprint_m_per_px
    b = np.full(3, 0.5)                             # the bin 0.4-0.56
    i = int(brightness_bin(0.5))
    mid = np.sqrt(fp0 * fp1)                        # halfway in log footprint
    np.testing.assert_allclose(cal.brightness_factor_at(b, np.array([fp0 / 2, mid, 2 * fp1])),
                               [want[0, i], 0.5 * (want[0, i] + want[1, i]), want[1, i]], rtol=1e-12)
    for k in ("brightness_keypoints", "brightness_expected_keypoints"):
        t.pop(k)
    cal = SiftCalibration.from_dict(d, "fy1")
    assert cal.detection_brightness_factor is None and cal.max_brightness_factor == 1.0
    np.testing.assert_array_equal(cal.brightness_factor_at([0.0, 0.3], 0.02), [1.0, 1.0])


def _detections(fy1, cal) -> np.ndarray:
    """Detections (E, n, N) of one epoch of two cameras at 40 m, 10°."""
    from vision.calibrated_detection import detections

    T = two_camera_poses(40.0, 10.0)
    feats = surface_features(fy1, n_features=calibrated_feature_count(CAM, fy1, T, cal), surface="outer")
    q = np.array([[0.3, -0.2, 0.5, 0.78]]) / np.linalg.norm([0.3, -0.2, 0.5, 0.78])
    keep, vis = detections([CAM, CAM], T[None], fy1, q, np.array([[0.2, 0.1, 1.0]]), np.ones(1), feats,
                           np.random.default_rng(4), calibration=cal)
    return keep, vis, feats


def test_the_geometric_mode_detects_at_the_brightness_scaled_density(fy1, data):
    """Factors of 1 give the detections of a file without the counts, bit for bit; 0 on every lit bin
    leaves only features that are not lit; 2 on every bin detects more."""
    d = copy.deepcopy(data)
    for k in ("brightness_keypoints", "brightness_expected_keypoints"):
        d["targets"]["fy1"].pop(k, None)
    base = _detections(fy1, SiftCalibration.from_dict(d, "fy1"))
    B = len(BRIGHTNESS_EDGES) - 1
    one = _detections(fy1, _with_factor(data, np.ones(B)))
    np.testing.assert_array_equal(one[0][np.any(one[1], axis=(0, 1))], base[0][np.any(base[1], axis=(0, 1))])
    n1 = int(one[1].sum())
    assert n1 > 100
    dark = _detections(fy1, _with_factor(data, np.r_[1.0, np.zeros(B - 1)]))
    assert 0 < int(dark[1].sum()) < 0.2 * n1
    assert int(_detections(fy1, _with_factor(data, np.full(B, 2.0)))[1].sum()) > 1.3 * n1


def test_the_occlusion_table_is_the_view_from_a_far_camera(fy1):
    """Each entry of the exposure sample's occlusion table equals the target's own occlusion of the
    segment from the point (off its surface on the side facing the direction) to a camera 1 km away
    along that direction, cast independently; and the table hides a share of the points that the
    closed bus must hide (between 20 % and 80 % of points hidden per direction, on average)."""
    import open3d as o3d

    from vision.face_brightness import _sample_optics

    P = _sample_optics(fy1)
    D, V = P["directions"].astype(float), P["visible"]
    X, nrm = P["X"].astype(float), P["normal"].astype(float)
    g = np.random.default_rng(0)
    gi, mi = g.integers(0, len(D), 400), g.integers(0, len(X), 400)
    side = np.where(np.sum(D[gi] * nrm[mi], axis=1) >= 0, 1.0, -1.0)
    org = X[mi] + max(1e-3, 1e-4 * fy1.radius_m) * side[:, None] * nrm[mi]
    rays = np.concatenate([org, 1000.0 * D[gi] - org], axis=1).astype(np.float32)
    hidden = fy1.scene.test_occlusions(o3d.core.Tensor(rays), tnear=0.0, tfar=1.0).numpy().astype(bool)
    assert np.mean(hidden == (V[gi, mi] == 0)) >= 0.99
    assert 0.2 < 1.0 - V.mean() < 0.8
