"""Tests of the orthogonal cylindrical-imaging camera (paper 004 eq 1–4, spot detection)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from vision.cylindrical import (
    CylindricalCamera,
    angles_from_points,
    brightest_spot_centres,
    detect_spots,
    measure_spot_centres,
    render_line_signals,
)

CAM = CylindricalCamera()
IDEAL = replace(CAM, k1=(0.0, 0.0), k2=(0.0, 0.0), bow=(0.0, 0.0), line_tilt_rad=(0.0, 0.0))
# practically noise-free sensor (read noise 0, huge well) for bias checks
QUIET = replace(CAM, read_noise_dn=0.0, electrons_per_dn=1e12)


def test_angles_from_points_is_eq_1_2_and_nan_behind_camera():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, (100, 3))
    X[:, 2] = rng.uniform(0.5, 5, 100)
    ab = angles_from_points(X)
    np.testing.assert_allclose(np.tan(ab[:, 0]), X[:, 0] / X[:, 2], rtol=1e-13)
    np.testing.assert_allclose(np.tan(ab[:, 1]), X[:, 1] / X[:, 2], rtol=1e-13)
    assert np.all(np.isnan(angles_from_points([[0.1, 0.2, -1.0], [0.0, 0.0, 0.0]])))


def test_undistorted_channels_are_tangent_maps():
    ab = np.array([[0.1, -0.2], [-0.25, 0.05], [0.0, 0.0]])
    uv = IDEAL.pixels_from_angles(ab)
    np.testing.assert_allclose(uv[:, 0], IDEAL.principal_px[0] + IDEAL.focal_px * np.tan(ab[:, 0]), rtol=1e-14)
    np.testing.assert_allclose(uv[:, 1], IDEAL.principal_px[1] + IDEAL.focal_px * np.tan(ab[:, 1]), rtol=1e-14)


def test_default_distortion_is_strong_and_couples_the_channels():
    # more than 10 px somewhere in the field on both CCDs (004 calibrates non-parametrically for this)
    g = np.stack(np.meshgrid(np.linspace(-0.26, 0.26, 5), np.linspace(-0.26, 0.26, 5)), -1).reshape(-1, 2)
    d = CAM.pixels_from_angles(g) - IDEAL.pixels_from_angles(g)
    assert np.all(np.nanmax(np.abs(d), axis=0) > 10.0)
    # u depends on beta (bow and line tilt): not separable into u(alpha), v(beta)
    u_a = CAM.pixels_from_angles([[0.2, 0.0], [0.2, 0.2]])[:, 0]
    assert abs(u_a[1] - u_a[0]) > 5.0


def test_sources_outside_the_ccd_are_nan():
    half_a, _ = CAM.half_field_rad()
    uv = CAM.pixels_from_angles([[half_a + 0.05, 0.0], [0.0, -(half_a + 0.05)], [np.nan, 0.0]])
    assert np.all(np.isnan(uv))


def test_background_noise_matches_read_and_shot_noise():
    sig = render_line_signals(CAM, np.full((1, 2), np.nan), rng=1)
    expected = np.sqrt(CAM.read_noise_dn**2 + CAM.background_dn / CAM.electrons_per_dn + 1.0 / 12.0)
    measured = np.std(sig)
    assert abs(measured / expected - 1.0) < 0.05
    assert abs(np.mean(sig) - CAM.background_dn) < 0.1


@pytest.mark.parametrize(("method", "max_bias_px"), [("threshold_centroid", 0.015), ("gaussian3", 1e-4)])
def test_noise_free_spot_centre_bias(method, max_bias_px):
    # pixel-integrated Gaussian without noise: only the estimator's pixel-phase bias remains; the
    # 50 % grey-threshold centroid has the familiar ~0.01 px "pixel locking", the 3-point log-parabola
    # is exact for a Gaussian up to the pixel integration
    uv = np.stack([np.linspace(1000, 1001, 41), np.linspace(5000.3, 5001.3, 41)], -1)
    c = measure_spot_centres(QUIET, uv, rng=2, n_scans=10**6, method=method)
    assert np.max(np.abs(c - uv)) < max_bias_px


def test_threshold_centroid_noise_and_averaging():
    rng = np.random.default_rng(3)
    uv = rng.uniform(200, 7800, (1500, 2))
    noise_free = measure_spot_centres(QUIET, uv, rng=2, n_scans=10**6)
    one = measure_spot_centres(CAM, uv, rng=4) - noise_free
    avg = measure_spot_centres(CAM, uv, rng=5, n_scans=25) - noise_free
    # zero-mean, about 0.02 px per scan at SNR ~ 100, and averaging 25 scans gains sqrt(25) = 5
    # (3000 samples: the std ratio is within ±10 % of 5 with > 99.9 % probability)
    assert abs(np.mean(one)) < 2e-3
    assert 0.01 < np.std(one) < 0.03
    assert 4.5 < np.std(one) / np.std(avg) < 5.5
    assert np.max(np.abs(one)) < 0.12


def test_detect_spots_separates_distinct_spots_and_flags_merged_ones():
    sig = render_line_signals(CAM, [[2000.0, 100.0], [2030.4, 110.0], [6000.0, 3000.0], [6002.5, 3030.0]],
                              rng=6)
    spots = detect_spots(sig[0])
    nominal = 2.3548 * CAM.spot_sigma_px
    assert len(spots) == 3
    np.testing.assert_allclose(spots.position_px[:2], [2000.0, 2030.4], atol=0.1)
    # the pair 2.5 px apart is one wide spot near the middle
    assert abs(spots.position_px[2] - 6001.25) < 0.3
    assert spots.fwhm_px[2] > 1.2 * nominal
    assert np.all(np.abs(spots.fwhm_px[:2] / nominal - 1.0) < 0.15)
    spots_v = detect_spots(sig[1])
    np.testing.assert_allclose(spots_v.position_px, [100.0, 110.0, 3000.0, 3030.0], atol=0.1)


def test_brightest_spot_centres_nan_without_a_spot():
    sig = render_line_signals(CAM, np.full((3, 1, 2), np.nan), rng=7)
    assert np.all(np.isnan(brightest_spot_centres(sig)))


def test_bad_inputs_raise_value_errors_naming_the_parameter():
    with pytest.raises(ValueError, match="method"):
        detect_spots(np.zeros(100), method="fit")
    with pytest.raises(ValueError, match="threshold_fraction"):
        detect_spots(np.zeros(100), threshold_fraction=1.5)
    with pytest.raises(ValueError, match="n_pixels"):
        CylindricalCamera(n_pixels=10)
    with pytest.raises(ValueError, match="peak_dn"):
        CylindricalCamera(peak_dn=5000.0)
    with pytest.raises(ValueError, match="k1"):
        CylindricalCamera(k1=(0.1, 0.2, 0.3))
    with pytest.raises(ValueError, match="alpha_beta_rad"):
        CAM.pixels_from_angles(np.zeros(3))
    with pytest.raises(ValueError, match="X_C"):
        angles_from_points(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="n_scans"):
        render_line_signals(CAM, [[1.0, 2.0]], n_scans=0)
