"""Tests of the orthogonal cylindrical imaging pose system (paper 004)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from attitude.euler import matrix_from_euler
from attitude.gibbs import shuster_matrix_from_gibbs
from attitude.matrix import rot_x, rot_y, rot_z, rotation_angle
from attitude.quaternion import matrix_from_quat, quat_from_axis_angle
from chaser.cylindrical import (
    N_S_BODY,
    TrackerSettings,
    attitude_from_three_points,
    calibrate_extrinsics,
    calibrate_system,
    control_points_in_cube,
    fit_intrinsic_rbf,
    initialise_tracks,
    intersect_planes,
    measure_points,
    paper_rig,
    rig_detections,
    sigma_from_vector_pairs,
    simulate_turntable_calibration,
    track_frame,
    virtual_point,
    yaw_roll_pitch_from_matrix,
    yaw_roll_pitch_from_sigma,
)
from vision.cylindrical import measure_spot_centres

CENTRE_W = np.array([1.0, 3.5, 0.0])  # middle of the 1 m cube, 3.0–4.0 m in front of the baseline

# 004 Table 1: tracker coordinates of the 8 test points (mm)
TABLE1_MM = np.array([
    [1149.62, 3713.20, -226.45], [1456.99, 3699.62, -5.40], [1376.87, 3599.28, -87.13],
    [1166.75, 3780.24, 48.98], [1372.40, 3602.85, -139.77], [1114.07, 3731.43, -39.39],
    [1172.29, 3673.84, -1.97], [1173.55, 3707.41, 28.15],
])
# 004 Table 2: true (yaw, roll, pitch) of the 8 poses (deg)
TABLE2_DEG = np.array([
    [-2.6460, 87.6570, -45.1910], [87.4626, 77.8150, -87.2480], [-22.0581, 59.1990, 6.0103],
    [-25.2650, 61.2085, 7.3825], [4.7596, 87.9791, -37.5984], [-34.3116, 73.4285, 2.0567],
    [19.3189, 88.6700, -22.1653], [-10.5321, 76.2800, 7.4063],
])
PAPER_MAX_ERR_DEG = np.array([0.20, 0.12, 0.23])  # yaw, roll, pitch (004 abstract, flag P004-12)
SCANS = 20  # static poses: spot centres averaged over 20 line scans (20 ms at 1 kHz)


@pytest.fixture(scope="module")
def system():
    rig = paper_rig()
    cp = control_points_in_cube(30, centre_W=CENTRE_W, rng=1)
    cal = calibrate_system(rig, cp, rng=2, n_scans=SCANS)
    return rig, cal


def _measure(rig, cal, X_W, seed):
    uv_true = rig.true_pixels(X_W)
    uv = np.stack([measure_spot_centres(rig.cameras[c], uv_true[..., c, :], rng=seed + c, n_scans=SCANS)
                   for c in range(rig.n_cameras)], -2)
    return measure_points(cal.cameras, uv)


def _r_ob(angles_deg):
    """004's R_ob of (yaw, roll, pitch): R_y(pitch) R_x(roll) R_z(yaw) of frame rotations (flag P004-3)."""
    return np.swapaxes(matrix_from_euler(np.deg2rad(angles_deg), "312"), -1, -2)


def _led_body(arm_m=0.5, angle_deg=80.0):
    """LEDs a, b, c in the body frame: ab along −x_S, angle abc ≠ 90° so that c′ ≠ c (flag P004-1)."""
    th = np.deg2rad(angle_deg)
    body = np.array([[arm_m, 0.0, 0.0], [0.0, 0.0, 0.0], [-arm_m * np.cos(th), arm_m * np.sin(th), 0.0]])
    return body - body.mean(0)


# ------------------------------------------------------------------ intrinsic calibration
def test_rbf_calibration_matches_true_angles_and_inverts(system):
    rig, cal = system
    for c in range(rig.n_cameras):
        s, intr = cal.samples[c], cal.cameras[c].intrinsic
        assert intr.n_samples == len(s.uv_px) > 500
        # forward map against the simulation truth at fresh points inside the calibrated field
        rng = np.random.default_rng(10 + c)
        ab = rng.uniform(-0.22, 0.22, (400, 2))
        uv_true = rig.cameras[c].pixels_from_angles(ab)
        err = intr.angles_from_pixels(uv_true) - ab
        # the reference angles carry the tracker error (~4.5 µrad per rail stop at 3 m): a few µrad
        assert np.sqrt(np.mean(err**2)) < 6e-6
        assert np.max(np.abs(err)) < 2.5e-5
        # inverse RBF (flag P004-10b): angles -> pixels round trip within 0.1 px
        back = intr.pixels_from_angles(intr.angles_from_pixels(uv_true))
        assert np.max(np.abs(back - uv_true)) < 0.1


def test_rbf_calibration_with_too_few_or_collinear_samples_raises():
    uv = np.random.default_rng(0).uniform(0, 8000, (10, 2))
    with pytest.raises(ValueError, match="at least 20 samples, got 10"):
        fit_intrinsic_rbf(uv, uv * 1e-4)
    line = np.stack([np.linspace(0, 8000, 50), np.linspace(0, 8000, 50)], -1)
    with pytest.raises(ValueError, match="collinear"):
        fit_intrinsic_rbf(line, np.random.default_rng(1).normal(size=(50, 2)))


def test_turntable_samples_cover_the_field_on_a_grid():
    rig = paper_rig()
    s = simulate_turntable_calibration(rig.cameras[0], rng=3, alpha_step_deg=2.0, rail_step_m=0.15)
    a = np.rad2deg(s.alpha_beta_true_rad[:, 0])
    assert np.isclose(a.min(), -14.0, atol=1e-3) and np.isclose(a.max(), 14.0, atol=1e-3)
    # reference angles differ from the truth by the tracker and turntable errors only (µrad)
    d = s.alpha_beta_rad - s.alpha_beta_true_rad
    assert 1e-7 < np.std(d) < 2e-5


# ------------------------------------------------------------------ extrinsic calibration
@pytest.mark.parametrize("method", ["rotvec", "penalty"])
def test_extrinsics_recover_the_true_pose_from_exact_angles(method):
    rig = paper_rig()
    X = control_points_in_cube(30, centre_W=CENTRE_W, rng=4)
    ab = rig.true_angles(X)[:, 1, :]
    e = calibrate_extrinsics(X, ab, method=method)
    np.testing.assert_allclose(e.R_CW, rig.R_CW[1], atol=1e-9)
    np.testing.assert_allclose(e.t_CW, rig.t_CW[1], atol=1e-9)
    # the linear solution (flag P004-8) is already exact on exact data
    np.testing.assert_allclose(e.R_CW_linear, rig.R_CW[1], atol=1e-8)
    assert e.rms_residual_rad < 1e-10


def test_extrinsics_refinement_beats_linear_solution_on_noisy_angles():
    rig = paper_rig()
    X = control_points_in_cube(30, centre_W=CENTRE_W, rng=5)
    ab = rig.true_angles(X)[:, 0, :] + np.random.default_rng(6).normal(0, 5e-6, (30, 2))
    rv = calibrate_extrinsics(X, ab)
    pen = calibrate_extrinsics(X, ab, method="penalty")

    def rot_err(R):
        return float(rotation_angle(R @ rig.R_CW[0].T))

    assert rot_err(rv.R_CW) < 2e-5 and np.linalg.norm(rv.t_CW - rig.t_CW[0]) < 1e-4
    # LM on angles is at least as good as the linear solve on the angular criterion
    Xc = X @ rv.R_CW_linear.T + rv.t_CW_linear
    lin_res = ab - np.stack([np.arctan2(Xc[:, 0], Xc[:, 2]), np.arctan2(Xc[:, 1], Xc[:, 2])], -1)
    assert rv.rms_residual_rad <= np.sqrt(np.mean(lin_res**2)) + 1e-12
    # the paper's penalty form (eq 20) lands on the same pose within the noise
    assert rot_err(pen.R_CW) < 3e-5 and pen.orthogonality_error < 1e-3


def test_extrinsics_with_too_few_or_coplanar_points_raise():
    rig = paper_rig()
    X = control_points_in_cube(5, centre_W=CENTRE_W, rng=7)
    with pytest.raises(ValueError, match="at least 6 control points, got 5"):
        calibrate_extrinsics(X, rig.true_angles(X)[:, 0, :])
    Xp = control_points_in_cube(12, centre_W=CENTRE_W, rng=8)
    Xp[:, 2] = 0.1  # all on one horizontal plane
    with pytest.raises(ValueError, match="degenerate"):
        calibrate_extrinsics(Xp, rig.true_angles(Xp)[:, 0, :])


# ------------------------------------------------------------------ plane intersection
def test_plane_intersection_is_exact_with_any_three_independent_planes():
    rig = paper_rig()
    X = control_points_in_cube(20, centre_W=CENTRE_W, rng=9)
    ab = rig.true_angles(X)
    full = intersect_planes(rig.R_CW, rig.t_CW, ab)
    np.testing.assert_allclose(full.X_W, X, atol=1e-10)
    assert np.all(full.n_planes == 4)
    for drop in [(0, 0), (0, 1), (1, 0), (1, 1)]:
        a3 = ab.copy()
        a3[:, drop[0], drop[1]] = np.nan
        three = intersect_planes(rig.R_CW, rig.t_CW, a3)
        assert np.all(three.ok) and np.all(three.n_planes == 3)
        np.testing.assert_allclose(three.X_W, X, atol=1e-8)


def test_plane_intersection_agrees_with_opencv_dlt_triangulation():
    # with all four channels the two planes of a camera meet in the ray (tan α, tan β, 1): an
    # independent check is OpenCV's DLT on normalised coordinates with P = [R_CW | t_CW]
    rig = paper_rig()
    X = control_points_in_cube(500, centre_W=CENTRE_W, rng=13)
    ab = rig.true_angles(X) + np.random.default_rng(14).normal(0.0, 1e-6, (500, 2, 2))
    ours = intersect_planes(rig.R_CW, rig.t_CW, ab).X_W
    tan = np.tan(ab)
    P = [np.hstack([rig.R_CW[c], rig.t_CW[c][:, None]]) for c in range(2)]
    Xh = cv2.triangulatePoints(P[0], P[1], tan[:, 0, :].T.copy(), tan[:, 1, :].T.copy())
    theirs = (Xh[:3] / Xh[3]).T
    # same data, slightly different criteria (plane distances vs algebraic DLT): within 5 µm
    assert np.max(np.linalg.norm(ours - theirs, axis=-1)) < 5e-6
    assert np.sqrt(np.mean(np.sum((ours - X) ** 2, -1))) <= 1.02 * np.sqrt(np.mean(np.sum((theirs - X) ** 2, -1)))


def test_point_with_fewer_than_three_planes_is_a_reported_failure_or_value_error():
    rig = paper_rig()
    ab = rig.true_angles(CENTRE_W[None])
    ab[0, 1, :] = np.nan  # camera 2 sees nothing: 2 planes left
    res = intersect_planes(rig.R_CW, rig.t_CW, ab)
    assert not res.ok[0] and res.n_planes[0] == 2 and np.all(np.isnan(res.X_W[0]))
    assert res.failure_reason[0] == "fewer than 3 planes"
    with pytest.raises(ValueError, match="2 usable plane"):
        intersect_planes(rig.R_CW, rig.t_CW, ab, strict=True)
    ab2 = rig.true_angles(CENTRE_W[None])
    ab2[0, :, 1] = np.nan  # only the two α planes
    res2 = intersect_planes(rig.R_CW, rig.t_CW, ab2)
    assert not res2.ok[0] and res2.failure_reason[0] == "fewer than 3 planes"
    # three α planes of cameras with parallel (vertical) y axes all contain the vertical line through
    # the point: three planes, but not independent
    R3 = np.concatenate([rig.R_CW, rig.R_CW[:1]])
    t3 = np.concatenate([rig.t_CW, (-rig.R_CW[0] @ np.array([1.0, -0.5, 0.0]))[None]])
    Xc = np.einsum("cij,j->ci", R3, CENTRE_W) + t3
    ab3 = np.stack([np.arctan2(Xc[:, 0], Xc[:, 2]), np.full(3, np.nan)], -1)[None]
    res3 = intersect_planes(R3, t3, ab3)
    assert res3.n_planes[0] == 3 and not res3.ok[0]
    assert res3.failure_reason[0] == "planes not independent"


def test_three_cameras_add_redundancy():
    rig = paper_rig()
    # a third camera to the side, looking across the depth direction of the first two
    c3 = np.array([-1.5, 3.2, 0.5])
    z = (CENTRE_W - c3) / np.linalg.norm(CENTRE_W - c3)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    R_C3W = np.stack([x, np.cross(z, x), z])
    R3 = np.concatenate([rig.R_CW, R_C3W[None]])
    t = np.concatenate([rig.t_CW, (-R_C3W @ c3)[None]])
    X = control_points_in_cube(50, centre_W=CENTRE_W, rng=10)
    Xc = np.einsum("cij,nj->nci", R3, X) + t
    ab = np.stack([np.arctan2(Xc[..., 0], Xc[..., 2]), np.arctan2(Xc[..., 1], Xc[..., 2])], -1)
    noisy = ab + np.random.default_rng(11).normal(0, 3e-6, ab.shape)
    e2 = np.linalg.norm(intersect_planes(rig.R_CW, rig.t_CW, noisy[:, :2]).X_W - X, axis=-1)
    r3 = intersect_planes(R3, t, noisy, angle_sigma_rad=3e-6)
    e3 = np.linalg.norm(r3.X_W - X, axis=-1)
    assert np.all(r3.n_planes == 6)
    assert np.sqrt(np.mean(e3**2)) < 0.6 * np.sqrt(np.mean(e2**2))
    # the predicted covariance matches the scatter (50 points: ratio within a factor 1.5)
    pred = np.sqrt(np.mean(np.trace(r3.covariance_m2, axis1=-2, axis2=-1)))
    assert 0.67 < np.sqrt(np.mean(e3**2)) / pred < 1.5


# ------------------------------------------------------------------ Table 1 analogue
def test_table1_points_error_below_half_millimetre(system):
    rig, cal = system
    X = TABLE1_MM / 1000.0
    fix = _measure(rig, cal, X, seed=20)
    err_mm = np.linalg.norm(fix.X_W - X, axis=-1) * 1000
    assert np.all(fix.ok) and err_mm.max() < 0.5
    # 200 further points spread over the whole 1 m cube
    Xr = control_points_in_cube(200, centre_W=CENTRE_W, rng=21)
    fr = _measure(rig, cal, Xr, seed=22)
    assert np.all(fr.ok)
    assert np.max(np.linalg.norm(fr.X_W - Xr, axis=-1)) < 0.5e-3


# ------------------------------------------------------------------ attitude algebra
def test_virtual_point_corrected_eq5_is_perpendicular_and_equals_gram_schmidt():
    rng = np.random.default_rng(12)
    a, b, c = rng.normal(size=(3, 200, 3))
    cp = virtual_point(a, b, c)
    ab, bc = b - a, c - b
    np.testing.assert_allclose(np.sum((cp - b) * ab, -1), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(cp - b, axis=-1), np.linalg.norm(bc, axis=-1), rtol=1e-12)
    u = ab / np.linalg.norm(ab, axis=-1, keepdims=True)
    w = bc - np.sum(bc * u, -1, keepdims=True) * u
    gs = b + np.linalg.norm(bc, axis=-1, keepdims=True) * w / np.linalg.norm(w, axis=-1, keepdims=True)
    np.testing.assert_allclose(cp, gs, atol=1e-12)
    assert np.all(np.isnan(virtual_point([0, 0, 0], [1, 1, 1], [2, 2, 2])))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3))
def test_corrected_eq9_11_are_the_3_1_2_angles_of_eq8(sig):
    sigma = np.array(sig)
    A = shuster_matrix_from_gibbs(sigma)  # corrected eq (8) = 001 eq (8′)
    ang = yaw_roll_pitch_from_sigma(sigma)
    diff = ang - yaw_roll_pitch_from_matrix(A)
    np.testing.assert_allclose((diff + np.pi) % (2 * np.pi) - np.pi, 0.0, atol=1e-9)
    y, r, p = ang
    # R_ob = R_y(pitch) R_x(roll) R_z(yaw) with frame-rotation (passive) elementary matrices
    np.testing.assert_allclose(rot_y(p).T @ rot_x(r).T @ rot_z(y).T, A, atol=1e-9)
    # Cayley least squares (flag P004-4) recovers sigma from the two vector pairs of eq (6)-(7)
    n_t = N_S_BODY @ A.T
    np.testing.assert_allclose(sigma_from_vector_pairs(n_t), sigma, atol=1e-8 * (1 + sigma @ sigma))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 1e-3),
       st.floats(0.0, np.pi))
def test_three_point_attitude_recovers_any_rotation_up_to_180_degrees(axis, angle):
    R = matrix_from_quat(quat_from_axis_angle(np.array(axis) / np.linalg.norm(axis), angle))
    body = _led_body()
    P = CENTRE_W + body @ R.T
    att = attitude_from_three_points(P[0], P[1], P[2])
    np.testing.assert_allclose(att.R_OS, R, atol=1e-9)
    np.testing.assert_allclose(matrix_from_quat(att.q_OS), R, atol=1e-9)
    assert np.max(np.abs(att.sigma)) <= 1.0 + 1e-9  # 001: every |σ_j| <= 1 after switching
    if angle > np.deg2rad(170):
        assert att.gibbs_set != 0  # 001's switching away from the singular set 0


def test_exact_180_degree_pose_needs_switching():
    e = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    R = 2 * np.outer(e, e) - np.eye(3)
    P = CENTRE_W + _led_body() @ R.T
    att = attitude_from_three_points(P[0], P[1], P[2])
    np.testing.assert_allclose(att.R_OS, R, atol=1e-12)
    assert att.gibbs_set != 0 and np.max(np.abs(att.sigma)) <= 1.0
    # without switching, set 0 is singular and its least-squares answer is a wrong rotation
    n_t = np.stack([(virtual_point(*P) - P[1]), (P[1] - P[0])])
    n_t /= np.linalg.norm(n_t, axis=-1, keepdims=True)
    wrong = shuster_matrix_from_gibbs(sigma_from_vector_pairs(n_t, gibbs_set=0))
    assert rotation_angle(wrong @ R.T) > np.deg2rad(10)


def test_table2_row2_is_a_90_degree_rotation_under_eq9_11_and_167_7_as_an_active_zxy_rotation():
    """Read with scipy's extrinsic "zxy", i.e. the active R_y R_x R_z, Table 2's angles give other
    rotation angles than the frame-rotation product implied by eq 9–11 (flag P004-3,
    docs/papers.md#p004-3).  Under eq 9–11, No. 2 is a 90.1° rotation; the active reading's 167.7°
    rotation is the pose with all three angles negated."""
    ours = np.rad2deg(rotation_angle(_r_ob(TABLE2_DEG[1])))
    a4 = Rotation.from_euler("zxy", TABLE2_DEG[1], degrees=True)
    assert abs(ours - 90.086) < 1e-3
    assert abs(np.rad2deg(a4.magnitude()) - 167.659) < 1e-3
    np.testing.assert_allclose(_r_ob(-TABLE2_DEG[1]), a4.as_matrix(), atol=1e-12)


# ------------------------------------------------------------------ Table 2 analogue
def test_table2_attitude_errors_within_paper_maxima_including_167_7_degree_pose(system):
    rig, cal = system
    poses = np.concatenate([TABLE2_DEG, -TABLE2_DEG[1:2]])  # + A.4's 167.7° pose
    R = _r_ob(poses)
    assert abs(np.rad2deg(rotation_angle(R[-1])) - 167.66) < 0.01
    P = CENTRE_W + np.einsum("kij,pj->kpi", R, _led_body())
    fix = _measure(rig, cal, P, seed=30)
    assert np.all(fix.ok)
    att = attitude_from_three_points(fix.X_W[:, 0], fix.X_W[:, 1], fix.X_W[:, 2])
    err = np.rad2deg(att.yaw_roll_pitch_rad) - poses
    err = (err + 180.0) % 360.0 - 180.0
    assert np.all(np.abs(err).max(axis=0) <= PAPER_MAX_ERR_DEG)
    assert att.gibbs_set[-1] != 0
    # roll is the best-determined angle, as in the paper
    assert np.abs(err[:, 1]).max() < np.abs(err[:, [0, 2]]).max()


# ------------------------------------------------------------------ dynamic multi-target recognition
def _moving_triad(t_s):
    axis = np.array([0.3, 0.5, 1.0]) / np.linalg.norm([0.3, 0.5, 1.0])
    R = matrix_from_quat(quat_from_axis_angle(axis, np.deg2rad(60.0) * t_s))
    centre = CENTRE_W + np.array([0.02, -0.01, 0.01]) * t_s[:, None]
    return centre[:, None, :] + np.einsum("tij,pj->tpi", R, _led_body(arm_m=0.4))


def test_three_moving_targets_crossing_20_times_keep_their_identities(system):
    rig, cal = system
    t = np.arange(0.0, 6.0, 1.0 / 40.0)
    P = _moving_triad(t)
    uv = rig.true_pixels(P)  # (T, K, C, 2)
    crossings = sum(int(np.sum(np.diff(np.sign(uv[:, i] - uv[:, j]), axis=0) != 0))
                    for i in range(3) for j in range(i + 1, 3))
    assert crossings >= 20
    cfg = TrackerSettings(accel_psd_m2_s3=1.0, angle_sigma_rad=3e-6)
    rng = np.random.default_rng(31)
    lit = []
    for f in range(6):  # two rounds of sequential lighting (004 §3.2 step 3)
        on = np.arange(3) == f % 3
        lit.append((f % 3, t[f], rig_detections(rig, P[f], rng=rng, lit=on)))
    state = initialise_tracks(cal.cameras, 3, lit, settings=cfg)
    swaps = dropped = coasted = used = 0
    worst = 0.0
    for f in range(6, t.size):
        frame_det = rig_detections(rig, P[f], rng=rng)
        res = track_frame(cal.cameras, state, frame_det, t[f], settings=cfg)
        state = res.state
        d = np.linalg.norm(state.position_W[:, None, :] - P[f][None], axis=-1)
        swaps += int(np.any(np.argmin(d, axis=1) != np.arange(3)))
        worst = max(worst, float(np.max(np.diag(d))))
        dropped += int(res.overlapped.sum())
        coasted += int((~res.ok).sum())
        # every association made is the target's own spot: the detection nearest its true centre
        det = frame_det
        for c in range(rig.n_cameras):
            for ch in range(2):
                pos = det[c][ch].position_px
                for k in range(3):
                    j = res.spot_index[k, c, ch]
                    if j >= 0:
                        assert j == np.argmin(np.abs(pos - uv[f, k, c, ch]))
                        assert abs(pos[j] - uv[f, k, c, ch]) < 0.5
                        used += 1
        four = res.n_planes == 4
        assert np.all(np.linalg.norm(res.X_W[four] - P[f][four], axis=-1) < 1e-3)
    assert swaps == 0
    assert used > 0.9 * 4 * 3 * (t.size - 6)  # most channels were associated and used
    assert dropped > 0  # overlapped channels did occur and were dropped (004 §3.2 step 8)
    assert worst < 2e-3


def test_tracking_needs_initialised_tracks(system):
    _, cal = system
    with pytest.raises(ValueError, match="never located"):
        initialise_tracks(cal.cameras, 2, [(0, 0.0, [(np.array([4000.0]), np.array([4000.0]))] * 2)])
