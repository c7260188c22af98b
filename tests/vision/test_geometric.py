"""Geometric observation mode: projection, noise, visibility by ray casting, false matches."""

import numpy as np
import pytest

from attitude.quaternion import matrix_from_quat, quat_normalize
from tests.vision.conftest import SUN_SIDE_H, facing_attitude, two_camera_poses
from vision.camera import PinholeCamera, look_at
from vision.features import epipolar_distance_px, fundamental_from_poses
from vision.geometric import observe, observe_epochs, surface_features
from vision.observation import REASON_OUTSIDE_FOV, Observation
from vision.render import cast_body_points

CAM = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)


def _three_cameras(d=50.0, gamma_deg=10.0):
    """003 §3.6: three cameras on a cone around +x with pairwise axis angle gamma."""
    phi = np.arcsin(2 / np.sqrt(3) * np.sin(np.radians(gamma_deg) / 2))
    eyes = [d * np.array([np.cos(phi), np.sin(phi) * np.cos(a), np.sin(phi) * np.sin(a)])
            for a in 2 * np.pi * np.arange(3) / 3]
    return np.stack([look_at(e, np.zeros(3)) for e in eyes])


def test_noise_free_tracks_are_exact_projections_of_their_true_body_points(fy1):
    T = _three_cameras()
    q = facing_attitude([1.0, 0.0, 0.0], 20.0)
    obs = observe(CAM, T, fy1, q, SUN_SIDE_H, rng=0, pixel_sigma_px=0.0, false_match_fraction=0.0)
    assert isinstance(obs, Observation) and obs.ok and obs.n_tracks > 50
    X_H = obs.X_T_true @ matrix_from_quat(q).T
    for i in range(3):
        uv, _ = CAM.project_world(X_H, T[i])
        s = obs.seen[:, i]
        np.testing.assert_allclose(obs.uv_px[s, i], uv[s], atol=1e-9)
    assert np.all(obs.seen.sum(axis=1) >= 2) and np.all(obs.feature_id >= 0)
    feats = surface_features(fy1)
    np.testing.assert_allclose(feats.X_T[obs.feature_id], obs.X_T_true)


def test_every_geometric_observation_is_the_first_surface_hit_through_its_pixel(fy1):
    """Occlusion: the ray through each reported pixel hits the feature itself (independent cast)."""
    T = two_camera_poses(50.0)
    q = facing_attitude([1.0, 1.0, 0.0])           # wings at 45 deg: the bus hides part of one wing
    obs = observe(CAM, T, fy1, q, SUN_SIDE_H, rng=0, pixel_sigma_px=0.0, false_match_fraction=0.0)
    assert obs.n_tracks > 20
    for i in range(2):
        s = obs.seen[:, i]
        X, _ = cast_body_points(CAM, T[i], fy1, q, obs.uv_px[s, i])
        d = np.linalg.norm(X - obs.X_T_true[s], axis=1)
        assert np.all(d < 2e-3)


def test_hidden_and_unlit_features_are_not_reported(fy1):
    T = two_camera_poses(50.0)
    q = facing_attitude([1.0, 0.0, 0.0])
    # with the Sun behind the target, every surface the cameras see is unlit
    obs = observe(CAM, T, fy1, q, [-1.0, 0.0, 0.0], rng=0)
    assert obs.n_tracks == 0 and obs.failure_reason == "too few matches"
    # features on the far side of the bus (-x face) are never seen from +x
    lit = observe(CAM, T, fy1, q, SUN_SIDE_H, rng=0, false_match_fraction=0.0)
    X = lit.X_T_true
    assert lit.n_tracks > 50
    assert np.sum((X[:, 0] < -0.70) & (np.abs(X[:, 1]) < 0.71)) == 0


def test_pixel_noise_has_the_requested_standard_deviation(fy1):
    T = _three_cameras()
    q = facing_attitude([1.0, 0.0, 0.0], 20.0)
    clean = observe(CAM, T, fy1, q, SUN_SIDE_H, rng=1, pixel_sigma_px=0.0, false_match_fraction=0.0)
    noisy = observe(CAM, T, fy1, q, SUN_SIDE_H, rng=1, pixel_sigma_px=0.7, false_match_fraction=0.0)
    np.testing.assert_array_equal(clean.feature_id, noisy.feature_id)
    r = (noisy.uv_px - clean.uv_px)[noisy.seen]
    n = r.size
    assert n > 300
    assert r.std() == pytest.approx(0.7, rel=4 / np.sqrt(2 * n))
    assert abs(r.mean()) < 4 * 0.7 / np.sqrt(n)


def test_false_match_fraction_is_respected_and_false_tracks_pass_the_epipolar_gate(fy1):
    T = two_camera_poses(50.0)
    q = facing_attitude([1.0, 0.0, 0.0], 20.0)
    f = 0.2
    obs = observe_epochs(CAM, np.broadcast_to(T, (20, 2, 4, 4)), fy1,
                         np.broadcast_to(q, (20, 4)), np.broadcast_to(SUN_SIDE_H, (20, 3)),
                         rng=3, false_match_fraction=f, pixel_sigma_px=0.5)
    bad = np.concatenate([o.feature_id < 0 for o in obs])
    n = bad.size
    assert n > 1000
    assert bad.mean() == pytest.approx(f, abs=4 * np.sqrt(f * (1 - f) / n))
    F = fundamental_from_poses(CAM.K, T[0], CAM.K, T[1])
    o = obs[0]
    b = o.feature_id < 0
    assert np.all(np.isnan(o.X_T_true[b]))
    e = epipolar_distance_px(F, o.uv_px[b, 0], o.uv_px[b, 1])
    assert np.all(e < 5 * 0.5 * np.sqrt(2))                    # on the epipolar line up to noise
    # and they are wrong: the two views disagree with any single surface point
    d_desc = np.sum(o.descriptors[b] * surface_features(fy1).descriptors[0], axis=1)
    assert np.all(np.abs(d_desc) < 0.5)


def test_fewer_features_survive_at_longer_range(fy1):
    q = facing_attitude([1.0, 0.0, 0.0], 20.0)
    n = [observe(CAM, two_camera_poses(d), fy1, q, SUN_SIDE_H, rng=0).n_tracks for d in (30, 60, 120)]
    assert n[0] > n[1] > n[2] > 0


def test_batched_epochs_equal_single_epoch_calls_without_noise(fy1):
    rng = np.random.default_rng(5)
    E = 6
    q = quat_normalize(rng.standard_normal((E, 4)))
    T = np.broadcast_to(_three_cameras(), (E, 3, 4, 4))
    sun = np.broadcast_to(SUN_SIDE_H, (E, 3))
    kw = dict(pixel_sigma_px=0.0, false_match_fraction=0.0, descriptor_noise=0.0)
    batch = observe_epochs(CAM, T, fy1, q, sun, rng=0, batch_size=4, **kw)
    for e in range(E):
        one = observe(CAM, T[e], fy1, q[e], sun[e], rng=0, **kw)
        np.testing.assert_array_equal(batch[e].feature_id, one.feature_id)
        np.testing.assert_array_equal(batch[e].uv_px, one.uv_px)
        assert batch[e].failure_reason == one.failure_reason


def test_geometric_and_rendered_observations_share_types_shapes_and_descriptor_scale(fy1_pair, fy1):
    from vision.rendered import observe_renders

    T, q, renders = fy1_pair
    r = observe_renders(renders, fy1, q)
    g = observe(CAM, T, fy1, q, SUN_SIDE_H, rng=0)
    for o in (r, g):
        assert o.uv_px.shape[1:] == (2, 2) and o.descriptors.dtype == np.float32
        assert o.descriptors.shape[1] == 128 and o.K.shape == (2, 3, 3)
        np.testing.assert_allclose(np.linalg.norm(o.descriptors, axis=1), 1.0, rtol=1e-5)
        assert o.feature_id.dtype == np.int64 and o.image_size == (1024, 1024)


def test_target_outside_every_field_of_view_is_flagged_not_raised(fy1):
    T = np.stack([look_at([50.0, 0, 0], [0, 50.0, 0]), look_at([50.0, 5, 0], [0, 55.0, 0])])
    obs = observe(CAM, T, fy1, [1, 0, 0, 0], SUN_SIDE_H, rng=0)
    assert obs.failure_reason == REASON_OUTSIDE_FOV and obs.n_tracks == 0


@pytest.mark.parametrize("kw,name", [(dict(false_match_fraction=1.0), "false_match_fraction"),
                                     (dict(pixel_sigma_px=-1.0), "pixel_sigma_px"),
                                     (dict(min_views=3), "min_views"),
                                     (dict(sun_visible_fraction=2.0), "sun_visible_fraction")])
def test_observe_rejects_bad_options_naming_them(fy1, kw, name):
    with pytest.raises(ValueError, match=name):
        observe(CAM, two_camera_poses(50.0), fy1, [1, 0, 0, 0], SUN_SIDE_H, **kw)


def test_surface_features_are_fixed_per_target_and_uniform_by_area(fy1):
    a, b = surface_features(fy1), surface_features(fy1)
    np.testing.assert_array_equal(a.X_T, b.X_T)
    big = surface_features(fy1, n_features=20000, rng=1)
    share = np.bincount(big.triangle_id, minlength=fy1.n_triangles) / 20000
    p = fy1.triangle_areas_m2 / fy1.triangle_areas_m2.sum()
    top = np.argsort(p)[-10:]
    assert np.all(np.abs(share[top] - p[top]) < 4 * np.sqrt(p[top] / 20000))
