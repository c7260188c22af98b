"""The rendered mode's σ per keypoint from its SIFT size and its track (noise_model="calibrated")."""

import numpy as np
import pytest

from tests.vision.conftest import SUN_SIDE_H, facing_attitude, two_camera_poses
from vision.calibration import load_calibration
from vision.epoch_variance import epoch_variance_factor
from vision.rendered import observe, observe_renders, render_views


def test_calibrated_rendered_tracks_carry_the_sigma_of_their_keypoint_sizes(camera, fy1):
    T = two_camera_poses(50.0)
    q = facing_attitude([1.0, 0.0, 0.0], 20.0)
    renders = render_views(camera, T, fy1, q, SUN_SIDE_H, rng=0)
    fixed = observe_renders(renders, fy1, q)
    cal = observe_renders(renders, fy1, q, noise_model="calibrated")
    # same tracks, only the noise model differs
    np.testing.assert_array_equal(fixed.uv_px, cal.uv_px)
    assert fixed.track_sigma_px is None and fixed.pixel_sigma_px == 0.5
    s = cal.seen
    assert np.all(cal.keypoint_size_px[s] > 1.0) and np.all(np.isnan(cal.keypoint_size_px[~s]))
    fp = np.linalg.norm(T[:, :3, 3], axis=1) / camera.K[0, 0]                 # image scale of each view, m/px
    c = -np.einsum("nji,nj->ni", T[:, :3, :3], T[:, :3, 3])                   # camera centres
    angle = np.degrees(np.arccos(c[0] @ c[1] / np.prod(np.linalg.norm(c, axis=1))))
    calib = load_calibration("fy1")
    # the size σ at the view's image scale, times the epoch's variance factor of that σ (its epipolar
    # residuals) and the inflation measured beyond it for a two-camera track at this spread
    size_sigma = calib.sigma_for_size(cal.keypoint_size_px, fp[None, :])
    factor = epoch_variance_factor(cal.uv_px, cal.K, cal.T_CW, size_sigma)
    expected = size_sigma * np.sqrt(factor * calib.sigma_inflation(fp[None, :], angle, 0, epoch=True))
    np.testing.assert_allclose(cal.track_sigma_px[s], expected[s], rtol=1e-12)
    # without the epoch factor: the table's average inflation
    table = size_sigma * np.sqrt(calib.sigma_inflation(fp[None, :], angle, 0))
    np.testing.assert_allclose(calib.track_sigma_px(cal, epoch_scale=False)[s], table[s], rtol=1e-12)
    np.testing.assert_allclose(cal.pixel_sigma_px, np.sqrt(np.mean(cal.track_sigma_px[s] ** 2)))
    # the measured σ (0.1-0.6 px) replaces the configured 0.5 px; most tracks are small keypoints
    assert np.median(cal.track_sigma_px[s]) < 0.3


def test_unknown_noise_model_is_refused(camera, fy1):
    with pytest.raises(ValueError, match="noise_model"):
        observe(camera, two_camera_poses(50.0), fy1, facing_attitude([1.0, 0, 0]), SUN_SIDE_H, rng=0,
                noise_model="measured")
