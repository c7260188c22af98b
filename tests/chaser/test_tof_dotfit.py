"""Tests of the dot-model fit of the TOF key points (chaser.tof.dotfit) and of the pixel-area shading it models."""

from __future__ import annotations

import numpy as np
import pytest

from attitude.euler import matrix_from_euler
from chaser.tof import ExtractionSettings, extract_markers
from chaser.tof.bound import measurement_model
from chaser.tof.dotfit import dot_centre_fisher, dot_model_amplitude, fit_dot
from vision.tof import (
    CooperativeTarget,
    box_edge_coverage,
    default_marker_plate,
    render_tof_frame,
    sr4000,
)

CAM = sr4000()
PLATE = default_marker_plate()


def _R(pyr_deg):
    p, y, r = np.radians(pyr_deg)
    return matrix_from_euler([y, p, r], "321")


def test_box_edge_coverage_is_the_area_of_a_square_cell_cut_by_a_straight_edge():
    # independent check: a 400 x 400 grid of points in a unit square turned by phi, cut by the line at
    # signed distance x from its centre along the normal (1, 0)
    g = (np.arange(400) + 0.5) / 400 - 0.5
    gx, gy = np.meshgrid(g, g)
    rng = np.random.default_rng(3)
    for _ in range(20):
        phi, x = rng.uniform(0, np.pi), rng.uniform(-0.8, 0.8)
        px = np.cos(phi) * gx - np.sin(phi) * gy                 # coordinate of each point along the normal
        area = np.mean(px < x)
        cov = box_edge_coverage(x, abs(np.cos(phi)), abs(np.sin(phi)))
        assert cov == pytest.approx(area, abs=3e-3), (phi, x)


def test_fitted_dot_centres_are_the_projected_marker_centres_where_the_centroid_is_offset():
    # a noise-free frame shaded with 6 x 6 sub-rays per pixel (the fit integrates 4 x 4 cells): the fitted centres
    # are the projections of the markers' centres (000 eq 2) to 0.001 px; the contrast-weighted centroid is off by
    # perspective and the brightness gradient
    R, r = _R([42.0, -8.0, 20.0]), np.array([0.0, 0.0, 1.0])
    frame = render_tof_frame(CAM, CooperativeTarget(plate=PLATE), R, r, noise=False, supersample=6)
    z, _ = measurement_model(R, r, PLATE.markers_C, CAM)
    err = {}
    for est in ("fit", "centroid"):
        det = extract_markers(frame, CAM, PLATE, settings=ExtractionSettings(centre_estimator=est))
        assert det.n == 6
        err[est] = np.linalg.norm(det.uv_px[:, None, :] - z[None, :, :2], axis=2).min(axis=1)
    det = extract_markers(frame, CAM, PLATE)
    assert det.centre_fitted.all()
    assert err["fit"].max() < 1e-3
    assert err["centroid"].max() > 0.02


def test_dot_fit_reaches_the_cramer_rao_bound_of_its_centre_on_images_with_the_camera_noise():
    # images of one dot from the model integrated on 8 x 8 cells, plus the camera's Gaussian amplitude noise;
    # the fit (4 x 4 cells) scatters as its Cramer-Rao bound and is unbiased
    R, r = _R([12.0, -8.0, 20.0]), np.array([0.0, 0.0, 1.0])
    n_S, h = R[:, 2], float(R[:, 2] @ r)
    z, _ = measurement_model(R, r, PLATE.markers_C, CAM)
    uc, vc = z[0, :2]
    gv, gu = np.mgrid[int(vc) - 7:int(vc) + 8, int(uc) - 7:int(uc) + 8].astype(float)
    win = np.hypot(gu - uc, gv - vc) <= 3.6 + 2.5
    u, v = gu[win], gv[win]
    truth = np.array([uc, vc, 7000.0, 15.0, -10.0, 1.0 - PLATE.marker_reflectivity / PLATE.plate_reflectivity])
    clean = dot_model_amplitude(truth, u, v, CAM, n_S, h, PLATE.marker_radius_m, (uc, vc), sub=8)
    sigma = CAM.phasor_sigma_dn(clean)
    rng = np.random.default_rng(8)
    est = []
    for _ in range(150):
        a = clean + sigma * rng.standard_normal(clean.shape)
        fit = fit_dot(a, u, v, CAM, n_S, h, PLATE.marker_radius_m, (uc + 0.3, vc - 0.2), 6800.0)
        assert fit.ok
        est.append(fit.uv_px)
    est = np.asarray(est) - [uc, vc]
    P = dot_centre_fisher(u, v, CAM, n_S, h, PLATE.marker_radius_m, truth)
    s = np.sqrt(np.diag(P))
    assert np.std(est, axis=0) == pytest.approx(s, rel=0.15)            # 150 draws: the std within 15 %
    assert np.all(np.abs(est.mean(axis=0)) < 4 * s / np.sqrt(len(est)))


def test_a_fit_that_cannot_hold_keeps_the_centroid_with_a_wide_sigma():
    # point-sampled dot edges (the staircase of 3 x 3 sub-rays) do not look like any pixel-area image of a disc
    R, r = _R([12.0, -8.0, 20.0]), np.array([0.0, 0.0, 1.0])
    frame = render_tof_frame(CAM, CooperativeTarget(plate=PLATE), R, r, noise=False, dot_edge="point")
    det = extract_markers(frame, CAM, PLATE)
    assert det.n == 6 and not det.centre_fitted.any()
    assert np.all(det.centroid_sigma_px >= ExtractionSettings().fallback_sigma_px)


def test_extraction_settings_reject_bad_fit_options():
    with pytest.raises(ValueError, match="centre_estimator"):
        ExtractionSettings(centre_estimator="hough")
    with pytest.raises(ValueError, match="fit_cells"):
        ExtractionSettings(fit_cells=0)
