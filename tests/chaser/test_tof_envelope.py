"""Tests of the TOF pose bound (chaser.tof.bound) and of the pipeline off its 700 mm operating point."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from attitude.euler import matrix_from_euler
from attitude.matrix import rotation_angle
from chaser.tof import ExtractionSettings, estimate_tof_pose, extract_markers, weighted_svd_pose
from chaser.tof.bound import (
    measurement_model,
    ml_pose_refinement,
    sr4000_marker_noise,
    tof_pose_bound,
)
from vision.tof import (
    CooperativeTarget,
    default_marker_plate,
    points_from_pixel_range,
    render_tof_frame,
    sr4000,
)

CAM = sr4000()
PLATE = default_marker_plate()
MODEL = PLATE.markers_C


def _R(pyr_deg):
    p, y, r = np.radians(pyr_deg)
    return matrix_from_euler([y, p, r], "321")


def test_bound_with_isotropic_point_noise_equals_the_closed_form_of_a_planar_point_set():
    # sigma_px chosen so that the lateral noise equals the range noise at each marker: the 3-D point
    # covariance is then sigma^2 I only to first order at the image centre, so use a far plate
    R, r = np.eye(3), np.array([0.0, 0.0, 50.0])
    sigma_m = 0.001
    rho = np.linalg.norm(MODEL @ R.T + r, axis=1)
    b = tof_pose_bound(R, r, MODEL, CAM, sigma_m * CAM.fx_px / rho, sigma_m)
    # closed form for p = R q + r with isotropic noise: J_rr = n I / s^2, J_tt = sum(|q|^2 I - q q^T) / s^2
    # with q about the plate origin (the point sets' centroid is not at the origin, so use the Schur complement)
    Rq = MODEL @ R.T
    n = len(MODEL)
    skew = np.array([[[0, -q[2], q[1]], [q[2], 0, -q[0]], [-q[1], q[0], 0]] for q in Rq])
    H = np.concatenate([-skew, np.broadcast_to(np.eye(3), (n, 3, 3))], axis=2)
    J = np.einsum("nki,nkj->ij", H, H) / sigma_m**2
    P = np.linalg.inv(J)
    assert b.attitude_sigma_rad == pytest.approx(np.sqrt(np.trace(P[:3, :3])), rel=2e-3)
    assert b.position_sigma_m == pytest.approx(np.sqrt(np.trace(P[3:, 3:])), rel=2e-3)


def test_bound_matches_a_monte_carlo_of_the_ml_pose_and_lower_bounds_the_weighted_svd():
    R, r = _R([12.0, -8.0, 20.0]), np.array([0.0, 0.0, 1.0])
    noise = sr4000_marker_noise(CAM, PLATE, R, r)
    b = tof_pose_bound(R, r, MODEL, CAM, noise.sigma_px, noise.sigma_range_m)
    z, _ = measurement_model(R, r, MODEL, CAM)
    rng = np.random.default_rng(19)
    err_ml, err_svd = [], []
    for _ in range(400):
        zn = z + rng.standard_normal(z.shape) * np.column_stack([noise.sigma_px, noise.sigma_px, noise.sigma_range_m])
        p = points_from_pixel_range(zn[:, 0], zn[:, 1], zn[:, 2], CAM)
        fit = weighted_svd_pose(MODEL, p, 1.0 / noise.sigma_range_m**2)
        err_svd.append(rotation_angle(fit.R_SC @ R.T))
        R_ml, _ = ml_pose_refinement(fit.R_SC, fit.r_CS_S, MODEL, zn[:, :2], zn[:, 2], CAM, noise.sigma_px,
                                     noise.sigma_range_m)
        err_ml.append(rotation_angle(R_ml @ R.T))
    rms_ml, rms_svd = np.sqrt(np.mean(np.square(err_ml))), np.sqrt(np.mean(np.square(err_svd)))
    # 400 trials of a chi distribution with 3 dof: the RMS is within 10 % of its expectation
    assert rms_ml == pytest.approx(b.attitude_sigma_rad, rel=0.10)
    assert rms_svd > 2.0 * b.attitude_sigma_rad           # isotropic weights ignore the precise pixels


def test_predicted_marker_noise_matches_the_scatter_of_the_extracted_key_points_at_1_m():
    # the bound's noise model against what the renderer produces: plane ranges and fitted dot centres
    R, r = _R([12.0, -8.0, 20.0]), np.array([0.0, 0.0, 1.0])
    target = CooperativeTarget(plate=PLATE)
    rng = np.random.default_rng(4)
    rho, uv = np.full((12, 6), np.nan), np.full((12, 6, 2), np.nan)
    for i in range(12):
        res = estimate_tof_pose(render_tof_frame(CAM, target, R, r, rng=rng), CAM, PLATE)
        for k, lab in enumerate(res.labels):
            if lab >= 0:
                rho[i, lab] = res.detections.range_m[k]
                uv[i, lab] = res.detections.uv_px[k]
    pred = sr4000_marker_noise(CAM, PLATE, R, r)
    ratio = np.nanstd(rho, axis=0, ddof=1) / pred.sigma_range_m
    assert np.all((ratio > 0.5) & (ratio < 1.8)), ratio    # 12 frames: chi spread of one std is about 20 %
    uv_ratio = np.nanstd(uv - np.nanmean(uv, axis=0), axis=(0, 2), ddof=1) / pred.sigma_px
    assert np.all((uv_ratio > 0.6) & (uv_ratio < 1.6)), uv_ratio   # the fitted centres scatter as their bound


def test_tilted_plate_at_1_m_is_found_in_every_frame_of_a_30_deg_sweep():
    # the issue-19 case: [12, -8, 20] deg at 1.0 m, each angle offset by -30 ... +30 deg; before the dark-hole
    # candidates, grazing body faces took the darkest-N_max budget and 13-17 % of these frames were lost
    target = CooperativeTarget(plate=PLATE)
    rng = np.random.default_rng(7)
    errs = []
    for axis in range(3):
        for offset in (-30.0, -15.0, 15.0, 30.0):
            pyr = np.array([12.0, -8.0, 20.0])
            pyr[axis] += offset
            R = _R(pyr)
            res = estimate_tof_pose(render_tof_frame(CAM, target, R, [0.0, 0.0, 1.0], rng=rng), CAM, PLATE)
            assert res.ok, (pyr, res.failure_reason)
            assert res.n_matched == 6
            errs.append(np.degrees(rotation_angle(res.R_SC @ R.T)))
    assert np.sqrt(np.mean(np.square(errs))) < 0.15


def test_default_pipeline_at_1_m_reaches_its_cramer_rao_bound_over_a_30_deg_sweep():
    # issue 19: at 1.0 m, +-30 deg about [12, -8, 20] deg, every frame found and the RMS attitude error within
    # 1.5x the bound (measured over 108 frames: 0.94x, docs/tof.md). The key points are the dot-model fits, the
    # pose their ML pose; the paper's weighted SVD alone and the ML pose on contrast-weighted centroids (biased
    # by 0.01-0.05 px) stay far above it
    target = CooperativeTarget(plate=PLATE)
    rng = np.random.default_rng(11)
    err, err_svd, err_centroid, bound = [], [], [], []
    for axis in range(3):
        for offset in (-30.0, 0.0, 30.0):
            pyr = np.array([12.0, -8.0, 20.0])
            pyr[axis] += offset
            R, r = _R(pyr), np.array([0.0, 0.0, 1.0])
            noise = sr4000_marker_noise(CAM, PLATE, R, r)
            b = tof_pose_bound(R, r, MODEL, CAM, noise.sigma_px, noise.sigma_range_m).attitude_sigma_rad
            frame = render_tof_frame(CAM, target, R, r, rng=rng)
            res = estimate_tof_pose(frame, CAM, PLATE)
            assert res.ok and res.n_matched == 6, (pyr, res.failure_reason)
            bound.append(b)
            err.append(rotation_angle(res.R_SC @ R.T))
            err_svd.append(rotation_angle(estimate_tof_pose(frame, CAM, PLATE, pose_estimator="svd").R_SC @ R.T))
            cen = estimate_tof_pose(frame, CAM, PLATE, extraction=ExtractionSettings(centre_estimator="centroid"))
            err_centroid.append(rotation_angle(cen.R_SC @ R.T))
    rms_bound = np.sqrt(np.mean(np.square(bound)))
    ratio = np.sqrt(np.mean(np.square(err))) / rms_bound
    assert 0.6 < ratio < 1.5, ratio                         # 9 frames: the RMS of 27 squared normals within about 30 %
    assert np.sqrt(np.mean(np.square(err_svd))) > 4.0 * rms_bound
    assert np.sqrt(np.mean(np.square(err_centroid))) > 4.0 * rms_bound


def test_noise_free_frame_gives_the_pose_exactly():
    R, r = _R([12.0, -8.0, 20.0]), np.array([0.0, 0.0, 1.0])
    frame = render_tof_frame(CAM, CooperativeTarget(plate=PLATE), R, r, noise=False)
    res = estimate_tof_pose(frame, CAM, PLATE)
    assert res.detections.centre_fitted.all()
    assert np.degrees(rotation_angle(res.R_SC @ R.T)) < 5e-4
    assert np.linalg.norm(res.r_CS_S - r) < 1e-5


def test_dot_edges_shaded_by_coverage_move_the_centroid_smoothly_with_the_pose():
    # point-sampled edges quantise a dot's centroid in steps of about 0.01 px; coverage shading does not
    target = CooperativeTarget(plate=PLATE)
    shifts = np.linspace(0.0, 2e-4, 9)                      # 0 .. 0.05 px at 1 m
    centroid = ExtractionSettings(centre_estimator="centroid")
    u = {}
    for edge in ("coverage", "point"):
        u[edge] = np.array([extract_markers(render_tof_frame(CAM, target, np.eye(3), [dx, 0.0, 1.0], noise=False,
                                                             dot_edge=edge), CAM, PLATE, settings=centroid).uv_px[:, 0].mean()
                            for dx in shifts])
    expected = u["coverage"][0] + CAM.fx_px * shifts
    assert np.max(np.abs(u["coverage"] - expected)) < 2e-3
    assert np.max(np.abs(u["point"] - (u["point"][0] + CAM.fx_px * shifts))) > 2e-3


@pytest.mark.parametrize(("distance_m", "reason"), [(0.3, "plate saturated"), (3.0, "below the confidence threshold")])
def test_frames_lost_at_the_envelope_edges_say_why(distance_m, reason):
    target = CooperativeTarget(plate=PLATE)
    res = estimate_tof_pose(render_tof_frame(CAM, target, np.eye(3), [0.0, 0.0, distance_m], rng=1), CAM, PLATE)
    assert not res.ok
    assert reason in res.failure_reason


def test_bound_rejects_bad_noise_and_a_plate_behind_the_camera():
    with pytest.raises(ValueError, match="sigma"):
        tof_pose_bound(np.eye(3), [0, 0, 1.0], MODEL, CAM, 0.0, 1e-3)
    with pytest.raises(ValueError, match="behind"):
        tof_pose_bound(Rotation.from_euler("x", 180, degrees=True).as_matrix(), [0, 0, -1.0], MODEL, CAM, 0.01, 1e-3)
