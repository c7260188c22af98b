"""vision.render.render_batch: all views of an epoch in one call give exactly what render() gives per view."""

from __future__ import annotations

import numpy as np
import pytest

from vision.camera import PinholeCamera, look_at
from vision.render import render, render_batch
from vision.target import fy1_target

FIELDS = ("image", "radiance", "depth_z_m", "mask", "X_T", "triangle_id", "lit")


def _cone(distance_m: float, n: int = 3, gamma_deg: float = 10.0) -> np.ndarray:
    a = np.deg2rad(gamma_deg)
    eyes = [distance_m * np.array([np.cos(a * (k - 1)), np.sin(a * (k - 1)), 0.1 * k]) for k in range(n)]
    return np.stack([look_at(e, np.zeros(3)) for e in eyes])


@pytest.mark.parametrize("distance_m", [40.0, 80.0])
def test_batch_equals_render_view_by_view_bit_for_bit(distance_m):
    """Every output array (image, radiance, depth, mask, body points, triangle ids, lit), the ROI, the
    exposure and the reason are identical, for random attitudes and a view that cannot see the
    target (pointed away), with one independent noise stream per view."""
    cam = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)
    target = fy1_target(seed=0)
    rng = np.random.default_rng(5)
    sun = np.array([1.0, -0.5, 0.6])
    T = _cone(distance_m)
    away = look_at(np.array([distance_m, 0.0, 0.0]), np.array([2 * distance_m, 0.0, 0.0]))
    T = np.concatenate([T, away[None]])
    cams = [cam] * len(T)
    for _ in range(2):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        seeds = np.random.SeedSequence(int(rng.integers(1 << 30))).spawn(len(T))
        ref = [render(cam, t, target, q, sun, rng=np.random.default_rng(s)) for t, s in zip(T, seeds, strict=True)]
        got = render_batch(cams, T, target, q, sun, rngs=[np.random.default_rng(s) for s in seeds])
        assert [g.failure_reason for g in got] == [r.failure_reason for r in ref]
        assert ref[-1].failure_reason and not ref[0].failure_reason
        for g, r in zip(got, ref, strict=True):
            assert g.roi == r.roi
            np.testing.assert_equal(g.exposure_s, r.exposure_s)
            for f in FIELDS:
                np.testing.assert_array_equal(getattr(g, f), getattr(r, f), err_msg=f)


def test_batch_in_earth_shadow_and_without_roi_matches_render():
    cam = PinholeCamera.from_fov(256, 256, fov_x_deg=20.0)
    target = fy1_target(seed=0)
    T = _cone(40.0, n=2)
    q = np.array([0.9, 0.1, -0.3, 0.2]) / np.linalg.norm([0.9, 0.1, -0.3, 0.2])
    for kw in ({"sun_visible_fraction": 0.0}, {"roi": False}, {"shadows": False, "specular": False, "ambient": 0.1}):
        ref = [render(cam, t, target, q, [0.0, 0.0, 1.0], rng=k, **kw) for k, t in enumerate(T)]
        got = render_batch([cam, cam], T, target, q, [0.0, 0.0, 1.0], rngs=[0, 1], **kw)
        for g, r in zip(got, ref, strict=True):
            assert g.failure_reason == r.failure_reason
            for f in FIELDS:
                np.testing.assert_array_equal(getattr(g, f), getattr(r, f), err_msg=f"{kw} {f}")


def test_batch_rejects_mismatched_view_counts():
    cam = PinholeCamera.from_fov(64, 64, fov_x_deg=20.0)
    with pytest.raises(ValueError, match="per view"):
        render_batch([cam], _cone(40.0, n=2), fy1_target(seed=0), [1.0, 0, 0, 0], [0, 0, 1.0], rngs=[0, 1])


def test_rendered_mode_fast_path_gives_the_same_tracks_as_view_by_view():
    """render_views(batched=True) and detect_views(threads=2) change nothing in the observation: the
    same images, keypoints and tracks as view-by-view rendering and sequential detection."""
    from vision.rendered import detect_views, observe_renders, render_views

    cam = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)
    target = fy1_target(seed=0)
    T = _cone(80.0)
    q = np.array([0.8, 0.3, -0.4, 0.3]) / np.linalg.norm([0.8, 0.3, -0.4, 0.3])
    sun = np.array([1.0, -0.5, 0.6])
    old = render_views(cam, T, target, q, sun, rng=3, batched=False)
    new = render_views(cam, T, target, q, sun, rng=3)
    for a, b in zip(old, new, strict=True):
        np.testing.assert_array_equal(a.image, b.image)
    k1 = detect_views(old)
    k2 = detect_views(new, threads=2)
    for a, b in zip(k1, k2, strict=True):
        np.testing.assert_array_equal(a.uv_px, b.uv_px)
        np.testing.assert_array_equal(a.descriptors, b.descriptors)
    o1, o2 = observe_renders(old, target, q), observe_renders(new, target, q, threads=2)
    assert o1.n_tracks > 10
    np.testing.assert_array_equal(o1.uv_px, o2.uv_px)
    np.testing.assert_array_equal(o1.feature_id, o2.feature_id)


@pytest.mark.parametrize("distance_m", [40.0, 80.0])
def test_noise_free_new_path_gives_todays_images_keypoints_and_tracks(distance_m):
    """The new path (render_batch, ROI-sized arrays, the "pixel" noise stream) against today's
    (render view by view, the "tiles" stream) on a noise-free sensor: the same images, hence the
    same keypoints and tracks (with noise the draws differ and only the law is the same:
    tests/vision/test_pixel_noise.py)."""
    from vision.rendered import detect_views, observe_renders, render_views
    from vision.sensor import SensorModel

    cam = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)
    target = fy1_target(seed=0)
    T = _cone(distance_m)
    q = np.array([0.7, -0.2, 0.5, 0.4]) / np.linalg.norm([0.7, -0.2, 0.5, 0.4])
    sun = np.array([1.0, -0.5, 0.6])
    today = render_views(cam, T, target, q, sun, rng=3, batched=False,
                         sensor=SensorModel(shot_noise=False, read_noise_e=0.0, noise_stream="tiles"))
    new = render_views(cam, T, target, q, sun, rng=4, sensor=SensorModel(shot_noise=False, read_noise_e=0.0))
    for a, b in zip(today, new, strict=True):
        assert a.roi == b.roi
        np.testing.assert_array_equal(a.image_roi, b.image_roi)
    for a, b in zip(detect_views(today), detect_views(new), strict=True):
        np.testing.assert_array_equal(a.uv_px, b.uv_px)
        np.testing.assert_array_equal(a.descriptors, b.descriptors)
    o1, o2 = observe_renders(today, target, q), observe_renders(new, target, q)
    assert o1.n_tracks > 10
    np.testing.assert_array_equal(o1.uv_px, o2.uv_px)
    np.testing.assert_array_equal(o1.feature_id, o2.feature_id)


def test_detection_over_the_roi_equals_detection_in_the_full_image():
    """detect_views works on the ROI arrays; the full-image detector with the full-image foreground
    mask (the path before) finds the same keypoints."""
    from vision.features import detect
    from vision.rendered import detect_views, foreground_mask, render_views

    cam = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)
    q = np.array([0.8, 0.3, -0.4, 0.3]) / np.linalg.norm([0.8, 0.3, -0.4, 0.3])
    renders = render_views(cam, _cone(60.0), fy1_target(seed=0), q, [1.0, -0.5, 0.6], rng=8)
    for r, k in zip(renders, detect_views(renders), strict=True):
        ref = detect(r.image, roi=r.roi, mask=foreground_mask(r.image))
        assert len(ref) > 20
        np.testing.assert_array_equal(k.uv_px, ref.uv_px)
        np.testing.assert_array_equal(k.descriptors, ref.descriptors)
