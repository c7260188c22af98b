"""Tests of the TOF camera model (vision/tof.py) against analytic geometry and its noise model."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from attitude.euler import matrix_from_euler
from vision.tof import (
    CooperativeTarget,
    MarkerPlate,
    TofCamera,
    default_marker_plate,
    pixel_range_from_points,
    points_from_pixel_range,
    render_tof_frame,
    sr4000,
)

CAM = sr4000()


def _wall(reflectivity: float = 0.99, size_m: float = 3.0) -> CooperativeTarget:
    """A large uniform plate (markers hidden) with no body: a flat wall."""
    plate = MarkerPlate(markers_xy_m=[(0.0, 0.0), (0.1, 0.0), (0.0, 0.1)], width_m=size_m, height_m=size_m,
                        plate_reflectivity=reflectivity)
    return CooperativeTarget(plate=plate, body_size_m=(0, 0, 0), hidden_markers=(0, 1, 2))


@settings(max_examples=60, deadline=None)
@given(x=st.floats(-0.3, 0.3), y=st.floats(-0.3, 0.3), z=st.floats(0.2, 5.0))
def test_eq5_back_projection_inverts_projection_and_radial_range(x, y, z):
    p = np.array([x, y, z])
    u, v, d = pixel_range_from_points(p, CAM)
    assert d == pytest.approx(np.linalg.norm(p), rel=1e-12)
    np.testing.assert_allclose(points_from_pixel_range(u, v, d, CAM), p, atol=1e-12)


def test_eq5_uses_radial_range_not_z_depth():
    # a pixel 50 px right of the principal point: z0 = d / sqrt(1 + (50/250)^2)
    p = points_from_pixel_range(CAM.cx_px + 50.0, CAM.cy_px, 1.0, CAM)
    assert p[2] == pytest.approx(1.0 / np.sqrt(1.04), rel=1e-12)
    assert p[0] == pytest.approx(0.2 * p[2], rel=1e-12)


def test_sr4000_model_reproduces_datasheet_geometry_and_unambiguous_range():
    assert (CAM.width_px, CAM.height_px) == (176, 144)
    fov_h = 2 * np.degrees(np.arctan(CAM.width_px / 2 / CAM.fx_px))
    assert fov_h == pytest.approx(38.8, abs=0.05)     # undistorted 10 mm / 40 um pinhole
    assert CAM.unambiguous_range_m == pytest.approx(4.9965, abs=1e-3)   # c / (2 * 30 MHz)
    # the calibrated noise model returns the data-sheet repeatability at its reference condition
    a_ref = CAM.signal_amplitude_dn(0.99, 2.0)
    assert CAM.range_sigma_m(a_ref) == pytest.approx(0.004, rel=1e-12)


def test_noise_free_wall_ranges_back_project_to_the_plane():
    f = render_tof_frame(CAM, _wall(), np.eye(3), [0, 0, 1.0], noise=False)
    assert f.valid.all() and not f.saturated.any()
    v, u = np.indices(f.range_m.shape)
    p = points_from_pixel_range(u, v, f.range_m, CAM)
    # phasor mean of 3x3 sub-rays on a plane: z within 10 um of the wall everywhere
    np.testing.assert_allclose(p[..., 2], 1.0, atol=1e-5)


def test_wall_amplitude_follows_inverse_square_and_cosine_law():
    f1 = render_tof_frame(CAM, _wall(), np.eye(3), [0, 0, 1.0], noise=False)
    f2 = render_tof_frame(CAM, _wall(), np.eye(3), [0, 0, 2.0], noise=False)
    c = (int(CAM.cy_px), int(CAM.cx_px))
    assert f1.amplitude_dn[c] / f2.amplitude_dn[c] == pytest.approx(4.0, rel=1e-3)
    # 2000 DN for the 99 % reference at 2 m on axis (data-sheet reference condition)
    assert f2.amplitude_dn[c] == pytest.approx(2000.0, rel=1e-3)
    # principal point on a pixel centre, so that pixel's ray is the optical axis
    cam = dataclasses.replace(CAM, cx_px=88.0, cy_px=72.0)
    flat = render_tof_frame(cam, _wall(), np.eye(3), [0, 0, 2.0], noise=False)
    tilted = render_tof_frame(cam, _wall(), matrix_from_euler(np.radians([0, 60, 0]), "321"), [0, 0, 2.0],
                              noise=False)
    assert tilted.amplitude_dn[72, 88] / flat.amplitude_dn[72, 88] == pytest.approx(0.5, rel=1e-3)


def test_range_noise_at_reference_matches_datasheet_repeatability():
    """Central 11x11 pixels, 99 % target at 2 m: 4 mm (1 sigma) per the SR4000 data sheet."""
    truth = render_tof_frame(CAM, _wall(), np.eye(3), [0, 0, 2.0], noise=False, supersample=1).range_m
    c = (slice(int(CAM.cy_px) - 5, int(CAM.cy_px) + 6), slice(int(CAM.cx_px) - 5, int(CAM.cx_px) + 6))
    res = np.concatenate([(render_tof_frame(CAM, _wall(), np.eye(3), [0, 0, 2.0], rng=s, supersample=1).range_m - truth)[c].ravel()
                          for s in range(8)])
    # 968 samples: the standard deviation has a relative standard error of 2.3 %
    assert np.std(res) == pytest.approx(0.004, rel=0.08)
    assert abs(np.mean(res)) < 4 * 0.004 / np.sqrt(res.size)


def test_range_noise_grows_linearly_with_distance_in_the_shot_noise_regime():
    def sigma(dist):
        truth = render_tof_frame(CAM, _wall(), np.eye(3), [0, 0, dist], noise=False, supersample=1).range_m
        noisy = render_tof_frame(CAM, _wall(), np.eye(3), [0, 0, dist], rng=3, supersample=1).range_m
        c = (slice(50, 94), slice(60, 116))
        return np.std((noisy - truth)[c])

    # A ~ 1/d^2 and sigma ~ sqrt(A)/A = 1/sqrt(A) ~ d (read noise is 0.1 % of the variance here)
    assert sigma(2.0) / sigma(1.0) == pytest.approx(2.0, rel=0.06)


def test_range_noise_falls_with_amplitude_dark_versus_white():
    c = (slice(50, 94), slice(60, 116))
    sig = {}
    for refl in (0.05, 0.80):
        truth = render_tof_frame(CAM, _wall(reflectivity=refl), np.eye(3), [0, 0, 1.0], noise=False)
        noisy = render_tof_frame(CAM, _wall(reflectivity=refl), np.eye(3), [0, 0, 1.0], rng=4)
        sig[refl] = np.std((noisy.range_m - truth.range_m)[c])
        # the model's stated sigma = c/(4 pi f) sqrt(kappa A + read^2) / A, 2464 samples (1.4 % s.e.)
        predicted = float(np.mean(CAM.range_sigma_m(truth.amplitude_dn[c])))
        assert sig[refl] == pytest.approx(predicted, rel=0.06)
    # shot noise alone would give sqrt(0.80 / 0.05) = 4; the read noise makes the dark plate worse
    assert sig[0.05] / sig[0.80] > 4.0


def test_amplitude_noise_is_the_phasor_sigma():
    truth = render_tof_frame(CAM, _wall(), np.eye(3), [0, 0, 1.5], noise=False).amplitude_dn
    noisy = render_tof_frame(CAM, _wall(), np.eye(3), [0, 0, 1.5], rng=5).amplitude_dn
    c = (slice(40, 104), slice(50, 126))
    expected = CAM.phasor_sigma_dn(truth[c])
    assert np.std((noisy - truth)[c]) == pytest.approx(float(np.mean(expected)), rel=0.05)


def test_mixed_pixels_at_plate_edge_lie_between_plate_and_body():
    target = CooperativeTarget(standoff_m=0.10)
    f = render_tof_frame(CAM, target, np.eye(3), [0, 0, 0.7], noise=False)
    v, u = np.indices(f.range_m.shape)
    z = points_from_pixel_range(u, v, f.range_m, CAM)[..., 2]
    z_body = 0.7 + target.plate.thickness_m + target.standoff_m
    mixed = (z > 0.7 + 0.005) & (z < z_body - 0.005)
    # the plate's 300 x 240 mm outline is 2*(107+86) px long at 0.7 m: expect about one mixed
    # pixel per edge pixel, none inside the plate or on the body
    assert 150 < mixed.sum() < 800
    u_edge = CAM.cx_px + np.array([-0.15, 0.15]) / 0.7 * CAM.fx_px
    on_edge = np.min(np.abs(u[mixed][:, None] - u_edge), axis=1) <= 1.0
    v_edge = CAM.cy_px + np.array([-0.12, 0.12]) / 0.7 * CAM.fy_px
    on_edge |= np.min(np.abs(v[mixed][:, None] - v_edge), axis=1) <= 1.0
    assert on_edge.all()


def test_markers_render_dark_at_their_projected_centres():
    target = CooperativeTarget()
    f = render_tof_frame(CAM, target, np.eye(3), [0, 0, 0.7], noise=False)
    u, v, _ = pixel_range_from_points(target.plate.markers_C + [0, 0, 0.7], CAM)
    a = f.amplitude_dn[np.round(v).astype(int), np.round(u).astype(int)]
    p = target.plate.markers_C + [0, 0, 0.7]
    dist = np.linalg.norm(p, axis=1)
    black = CAM.signal_amplitude_dn(target.plate.marker_reflectivity, dist, p[:, 2] / dist)   # cos incidence
    np.testing.assert_allclose(a, black, rtol=0.005)


def test_hidden_and_spurious_dots_change_what_is_printed():
    base = CooperativeTarget()
    t = dataclasses.replace(base, hidden_markers=(2,), spurious_xy_m=[(0.0, 0.0)])
    printed = t.printed_dots_xy_m
    assert len(printed) == base.plate.n_markers
    assert not np.any(np.all(np.isclose(printed, base.plate.markers_xy_m[2]), axis=1))
    f = render_tof_frame(CAM, t, np.eye(3), [0, 0, 0.7], noise=False)
    assert f.amplitude_dn[int(round(CAM.cy_px)), int(round(CAM.cx_px))] < 1000.0     # the spurious dot


def test_close_white_plate_saturates_and_loses_range():
    f = render_tof_frame(CAM, _wall(reflectivity=0.9), np.eye(3), [0, 0, 0.4], rng=0)
    # 0.9/0.99 * 2000 * (2/0.4)^2 = 45455 DN > 30000 DN full well
    assert f.saturated.all() and not f.valid.any() and np.isnan(f.range_m).all()


def test_phase_wraps_beyond_the_unambiguous_range():
    f = render_tof_frame(CAM, _wall(size_m=12.0), np.eye(3), [0, 0, 5.5], noise=False)
    c = (int(CAM.cy_px), int(CAM.cx_px))
    assert f.range_m[c] == pytest.approx(5.5 - CAM.unambiguous_range_m, abs=1e-4)


def test_empty_view_has_no_valid_pixels():
    f = render_tof_frame(CAM, CooperativeTarget(), np.eye(3), [0, 0, -1.0], rng=0)   # target behind
    assert not f.valid.any()


def test_bad_inputs_raise_value_errors_naming_the_parameter():
    with pytest.raises(ValueError, match="fx_px"):
        TofCamera(fx_px=-1, fy_px=250, cx_px=80, cy_px=70, width_px=176, height_px=144)
    with pytest.raises(ValueError, match="markers_xy_m"):
        MarkerPlate(markers_xy_m=[(0.0, 0.0), (0.2, 0.0), (0.0, 0.1)])         # off a 0.3 m plate
    with pytest.raises(ValueError, match="hidden_markers"):
        CooperativeTarget(hidden_markers=(9,))
    with pytest.raises(ValueError, match="R_SC"):
        render_tof_frame(CAM, CooperativeTarget(), 2 * np.eye(3), [0, 0, 0.7])
    with pytest.raises(ValueError, match="r_CS_S"):
        render_tof_frame(CAM, CooperativeTarget(), np.eye(3), [0, 0])
    with pytest.raises(ValueError, match="supersample"):
        render_tof_frame(CAM, CooperativeTarget(), np.eye(3), [0, 0, 0.7], supersample=0)


def test_default_plate_has_six_markers_with_distinct_pairwise_distances():
    m = default_marker_plate().markers_C
    d = np.linalg.norm(m[:, None] - m[None], axis=-1)[np.triu_indices(6, 1)]
    assert np.diff(np.sort(d)).min() > 0.004
