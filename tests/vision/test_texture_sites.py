"""Texture keypoint sites (vision.texture_sites) and the calibrated geometric mode drawn from them."""

import numpy as np
import pytest

from vision.calibrated_detection import detections
from vision.calibration import load_calibration
from vision.camera import PinholeCamera, look_at
from vision.geometric import surface_features
from vision.geometric_calibrated import filler_feature_count
from vision.target import Material
from vision.target.builder import MeshBuilder
from vision.texture_sites import footprint_level, site_features, texture_image, texture_sites

CAM = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)
FP_40M = 40.0 / CAM.K[0, 0]                       # m/px at 40 m


def _plate(thickness_m=0.02, side_m=2.0, seed=3):
    """A square plate (one MLI material on every face) in the body y-z plane."""
    b = MeshBuilder()
    b.add_box((0, 0, 0), (thickness_m, side_m, side_m), 0, "mli")
    return b.build(name="plate", materials=(Material("mli", "mli", 0.7),), texel_m=0.005, seed=seed,
                   description="test plate")


@pytest.fixture(scope="module")
def plate():
    return _plate()


def _bary(target, tid, X):
    """Barycentric (b1, b2) of body points ``X`` on triangles ``tid`` (Open3D's convention), least squares."""
    p = target.vertices_T[target.triangles[tid]]
    A = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]], axis=-1)      # (N, 3, 2)
    rhs = np.einsum("nki,nk->ni", A, X - p[:, 0])
    return np.linalg.solve(np.einsum("nki,nkj->nij", A, A), rhs[..., None])[..., 0]


def _blob_contrast(target, fp, tid, X, sigma_px=1.2):
    """|difference of Gaussians| (σ and 1.6 σ, px) of the texture image at footprint ``fp`` at surface points."""
    import cv2

    img, scale = texture_image(target, fp)
    f = img.astype(np.float32)
    dog = np.abs(cv2.GaussianBlur(f, (0, 0), sigma_px) - cv2.GaussianBlur(f, (0, 0), 1.6 * sigma_px))
    xy = (target.texture_coords(tid, _bary(target, tid, X)) + 0.5) * scale - 0.5
    xi = np.clip(np.round(xy).astype(int), 0, [img.shape[1] - 1, img.shape[0] - 1])
    return dog[xi[:, 1], xi[:, 0]]


def test_sites_lie_on_the_surface_where_the_texture_has_contrast(fy1):
    """Every site is on the mesh, and the texture's blob contrast (difference of Gaussians, what SIFT
    thresholds) is larger at the sites than at points spread uniformly over the outer surface."""
    import open3d as o3d

    s = texture_sites(fy1, FP_40M)
    assert len(s) > 500
    d = fy1.scene.compute_distance(o3d.core.Tensor(s.X_T.astype(np.float32))).numpy()
    assert np.max(d) < 1e-4
    uni = surface_features(fy1, n_features=2000, surface="outer", rng=1)
    c_site = _blob_contrast(fy1, s.footprint_m_per_px, s.triangle_id, s.X_T)
    c_uni = _blob_contrast(fy1, s.footprint_m_per_px, uni.triangle_id, uni.X_T)
    assert np.median(c_site) > 1.5 * np.median(c_uni)


def test_sites_are_deterministic_and_cached_per_footprint_level(plate):
    """The same target gives the same sites; a rebuilt target with the same seed too; nearby footprints
    share one level."""
    a = texture_sites(plate, FP_40M)
    assert texture_sites(plate, FP_40M * 1.02) is a
    b = texture_sites(_plate(), FP_40M)
    np.testing.assert_array_equal(a.X_T, b.X_T)
    np.testing.assert_array_equal(a.size_m, b.size_m)
    np.testing.assert_array_equal(a.descriptor_gap, b.descriptor_gap)   # FLANN neighbours, seeded
    assert footprint_level(FP_40M * 2) == pytest.approx(2 * footprint_level(FP_40M))
    f1, f2 = site_features(plate, FP_40M), site_features(plate, FP_40M)
    np.testing.assert_array_equal(f1.descriptors, f2.descriptors)


def test_no_site_on_a_face_narrower_than_its_keypoint(plate):
    """The plate's 20 mm edges hold texture keypoints in the atlas but no flat neighbourhood for them."""
    s = texture_sites(plate, FP_40M)
    on_edge = np.abs(s.normal_T[:, 0]) < 0.5                               # edge faces: normal in the y-z plane
    assert len(s) > 100
    assert not on_edge.any()
    # the big faces keep sites out to within a keypoint radius of their border
    assert np.max(np.abs(s.X_T[:, 1:])) > 0.9


def test_detected_sites_follow_the_sites_not_a_uniform_spread(fy1):
    """Over many draws, the features detected head-on on the bus top cluster where the sites are."""
    from attitude.quaternion import quat_from_axis_angle

    T = np.stack([look_at(np.array([0.0, 0.0, 40.0]), np.zeros(3), up_W=np.array([1.0, 0.0, 0.0]))])
    T = np.concatenate([T, np.stack([look_at(np.array([0.0, 6.9, 39.4]), np.zeros(3), up_W=np.array([1.0, 0.0, 0.0]))])])
    q = quat_from_axis_angle(np.array([1.0, 0.0, 0.0]), 0.0)[None]
    sun = np.array([[0.3, 0.0, 1.0]]) / np.hypot(0.3, 1.0)
    feats = site_features(fy1, FP_40M)
    top = np.flatnonzero((feats.normal_T[:, 2] > 0.99) & (feats.X_T[:, 2] > 0.59) & (feats.X_T[:, 2] < 0.61))
    counts = np.zeros(len(feats))
    for seed in range(20):
        keep, vis = detections([CAM, CAM], T[None], fy1, q, sun, np.ones(1), feats, np.random.default_rng(seed))
        counts[keep] += vis[0].any(axis=0)
    edges = np.linspace(-0.71, 0.71, 8)
    h_site, *_ = np.histogram2d(feats.X_T[top, 0], feats.X_T[top, 1], bins=[edges, edges])
    h_det, *_ = np.histogram2d(feats.X_T[top, 0], feats.X_T[top, 1], bins=[edges, edges], weights=counts[top])
    assert h_det.sum() > 200
    r = np.corrcoef(h_site.ravel(), h_det.ravel())[0, 1]
    assert r > 0.6, r


def test_draws_are_deterministic_under_a_seeded_rng(fy1):
    T = np.stack([look_at(np.array([40.0, 0.0, 0.0]), np.zeros(3)), look_at(np.array([39.4, 6.9, 0.0]), np.zeros(3))])
    q = np.array([[1.0, 0.0, 0.0, 0.0]])
    sun = np.array([[1.0, 0.0, 0.3]]) / np.hypot(1.0, 0.3)
    feats = site_features(fy1, FP_40M)
    a = detections([CAM, CAM], T[None], fy1, q, sun, np.ones(1), feats, np.random.default_rng(7))
    b = detections([CAM, CAM], T[None], fy1, q, sun, np.ones(1), feats, np.random.default_rng(7))
    c = detections([CAM, CAM], T[None], fy1, q, sun, np.ones(1), feats, np.random.default_rng(8))
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    assert not np.array_equal(a[0], c[0]) or not np.array_equal(a[1], c[1])


@pytest.mark.parametrize("distance_m", [40.0, 80.0])
def test_the_measured_density_is_honoured_on_average(plate, distance_m):
    """A lit plate seen head-on: detections per m² over many draws equal the calibration's density of the
    bin times its brightness factor (the sites first, uniform fillers for what the sites cannot carry)."""
    cal = load_calibration("fy1")
    T = np.stack([look_at(np.array([distance_m, 0.0, 0.0]), np.zeros(3))])
    q = np.array([[1.0, 0.0, 0.0, 0.0]])
    sun = np.array([[1.0, 0.0, 0.0]])
    fp = distance_m / CAM.K[0, 0]
    sites = texture_sites(plate, fp)
    n_fill = filler_feature_count(CAM, plate, T, sites, calibration=cal)
    fill = surface_features(plate, n_features=max(n_fill, 1), surface="outer") if n_fill else None
    feats = site_features(plate, fp, fillers=fill)
    front = feats.X_T[:, 0] > 0.009                                        # the face towards the camera
    n_det = []
    for seed in range(40):
        keep, vis = detections([CAM], T[None], plate, q, sun, np.ones(1), feats, np.random.default_rng(seed),
                               calibration=cal)
        n_det.append(int(np.sum(vis[0, 0] & front[keep])))
    # 2 m × 2 m face; the plate is all the camera sees, evenly lit: its brightness is the exposure's
    # reference (relative brightness 1, vision.face_brightness)
    expected = float(cal.density(fp, 1.0, cal.sun_bin(1.0, True)) * cal.brightness_factor_at(1.0, fp)) * 4.0
    assert np.mean(n_det) == pytest.approx(expected, rel=0.1)


def test_a_feature_keeps_the_measured_share_of_its_error_between_epochs(fy1):
    """The pixel errors of a feature in one view at consecutive epochs correlate as the calibration's
    σ² inflations say: (triangulation − increment inflation) / triangulation inflation."""
    from attitude.quaternion import (
        matrix_from_quat,
        quat_from_rotvec,
        quat_multiply,
        quat_normalize,
    )
    from tests.vision.geometric_three_cameras import three_cameras
    from vision.calibration import track_class
    from vision.geometric import observe_epochs

    cal = load_calibration("fy1")
    T = three_cameras(40.0, 10.0)
    E = 16
    dq = quat_from_rotvec(np.radians(0.5) * np.ones(3) / np.sqrt(3))
    q = [quat_normalize(np.array([0.3, -0.5, 0.7, 0.4]))]
    for _ in range(E - 1):
        q.append(quat_normalize(quat_multiply(dq, q[-1])))
    feats = site_features(fy1, FP_40M)
    obs = observe_epochs(CAM, np.broadcast_to(T, (E, *T.shape)), fy1, np.array(q), np.broadcast_to(
        np.array([1.0, -0.5, 0.6]) / np.linalg.norm([1.0, -0.5, 0.6]), (E, 3)), rng=5, features=feats,
        noise_model="calibrated")
    res = []
    for o, qk in zip(obs, q, strict=True):
        good = o.feature_id >= 0
        X_H = o.X_T_true[good] @ matrix_from_quat(qk).T
        r = np.full((good.sum(), 3, 2), np.nan)
        for i in range(3):
            uv, _ = CAM.project_world(X_H, T[i])
            r[:, i] = (o.uv_px[good][:, i] - uv) / o.track_sigma_px[good][:, i, None]
        res.append(dict(zip(o.feature_id[good], r, strict=True)))
    a, b = [], []
    for r0, r1 in zip(res[:-1], res[1:], strict=True):
        for f in set(r0) & set(r1):
            ok = np.isfinite(r0[f]).all(axis=1) & np.isfinite(r1[f]).all(axis=1)
            a.append(r0[f][ok].ravel())
            b.append(r1[f][ok].ravel())
    a, b = np.concatenate(a), np.concatenate(b)
    assert a.size > 1000
    fp = 40.0 / CAM.K[0, 0]
    cls = track_class(np.array([2, 3]), 3)
    kept = [1.0 - cal.sigma_inflation(fp, 10.0, c, increment=True) / cal.sigma_inflation(fp, 10.0, c) for c in cls]
    assert np.corrcoef(a, b)[0, 1] == pytest.approx(float(np.mean(kept)), abs=0.1)


@pytest.mark.parametrize("survival", [0.05, 0.3, 0.7])
def test_pair_survival_keeps_each_materials_mean_and_spreads_by_the_descriptor_gap(fy1, survival):
    """The survival passed in already carries the material's factor: over the sites of each material the
    mean of the per-site survival is that value (to 1e-3: the tabulated scale), and within a material
    a site with a larger descriptor gap (a more distinctive blob) survives more often."""
    sites = texture_sites(fy1, footprint_level(40.0 / CAM.K[0, 0]))
    for m in np.unique(sites.material):
        idx = np.flatnonzero(sites.material == m)
        s = sites.pair_survival(survival, idx)
        assert s.mean() == pytest.approx(survival, abs=1e-3)
        order = np.argsort(sites.descriptor_gap[idx])
        assert np.all(np.diff(s[order]) >= -1e-12)
