"""001 §2 pose solver with Gibbs-vector switching: algebra, Jacobian, accuracy, switching, failures."""

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from attitude.gibbs import (
    gibbs_set_from_quat,
    shuster_matrix_from_gibbs,
    shuster_matrix_from_gibbs_set,
)
from attitude.quaternion import (
    matrix_from_quat,
    quat_angle_between,
    quat_conjugate,
    quat_from_axis_angle,
    quat_from_rotvec,
    quat_multiply,
    rotvec_from_quat,
)
from chaser.rodrigues_pose import (
    FAILURE_REASONS,
    GibbsPose,
    focal_plane_from_pixels,
    pixels_from_focal_plane,
    project_focal_plane,
    projection_jacobian,
    solve_pose_rodrigues,
    track_pose_rodrigues,
)
from chaser.rodrigues_pose.solver import _compose_switch
from tests.attitude.strategies import unit_quats

F_M = 0.2  # 001 §2.4: f = 200 mm
PIXEL_M = 7e-6  # 7 µm pixels
CENTRE_PX = np.array([1024.0, 1024.0])  # 2048 × 2048
K = np.array([[F_M / PIXEL_M, 0, 1024.0], [0, F_M / PIXEL_M, 1024.0], [0, 0, 1.0]])
CUBE_T = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])  # 2 m cube
R_TC_C = np.array([0.3, -0.2, 100.0])


def visible_vertices(q_CT, r_TC_C):
    """Vertices with at least one adjacent face turned to the camera, n·(c − p) > 0 (back-face culling)."""
    R = matrix_from_quat(q_CT)
    c_T = -np.einsum("...ji,...j->...i", R, np.broadcast_to(r_TC_C, R.shape[:-1]))  # camera in T
    vis = np.zeros(c_T.shape[:-1] + (8,), bool)
    for k in range(3):
        for s in (-1.0, 1.0):
            face = s * c_T[..., k] - 1.0 > 0  # outward normal s·e_k, face plane s·p_k = 1
            vis |= face[..., None] & (s * CUBE_T[:, k] > 0)
    return vis


def frames(q_CT, r_TC_C, *, noise_px=0.0, rng=None):
    """Focal-plane images (001 eq 6–7) of the visible cube vertices, NaN elsewhere, with pixel noise."""
    rng = np.random.default_rng(rng)
    xy, _ = project_focal_plane(CUBE_T, matrix_from_quat(q_CT), np.broadcast_to(r_TC_C, np.shape(q_CT)[:-1] + (3,)),
                                focal_length_m=F_M)
    xy = xy + noise_px * PIXEL_M * rng.standard_normal(xy.shape)
    vis = visible_vertices(q_CT, r_TC_C)
    return np.where(vis[..., None], xy, np.nan), vis


def perturbed(q, r, *, angle_deg, offset_m, rng):
    """Truth turned by ``angle_deg`` about a random axis and moved by ``offset_m`` per axis (1σ)."""
    rng = np.random.default_rng(rng)
    axis = rng.standard_normal(np.shape(q)[:-1] + (3,))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    dq = quat_from_rotvec(np.radians(angle_deg) * axis)
    return quat_multiply(dq, q), r + offset_m * rng.standard_normal(np.shape(q)[:-1] + (3,))


# ------------------------------------------------------------------------------ camera model
def test_focal_plane_projection_is_opencv_projectpoints_inverted():
    """001 eq (7) x = −fX/Z is OpenCV's pixel projection mirrored about the principal point."""
    rng = np.random.default_rng(1)
    q = quat_from_rotvec(rng.standard_normal(3))
    xy, depth = project_focal_plane(CUBE_T, matrix_from_quat(q), R_TC_C, focal_length_m=F_M)
    rvec = rotvec_from_quat(q)
    uv_cv, _ = cv2.projectPoints(CUBE_T, rvec, R_TC_C, K, None)
    np.testing.assert_allclose(pixels_from_focal_plane(xy, pixel_size_m=PIXEL_M, principal_point_px=CENTRE_PX),
                               uv_cv[:, 0], atol=1e-9)
    np.testing.assert_allclose(focal_plane_from_pixels(uv_cv[:, 0], pixel_size_m=PIXEL_M, principal_point_px=CENTRE_PX),
                               xy, atol=1e-14)
    np.testing.assert_allclose(depth, (CUBE_T @ matrix_from_quat(q).T + R_TC_C)[:, 2])


@settings(max_examples=200, deadline=None)
@given(unit_quats(), st.sampled_from([None, 0, 1, 2, 3]))
def test_gibbs_pose_round_trips_the_hamilton_quaternion_in_every_set(q, gibbs_set):
    """GibbsPose(q_CT) in any non-singular set gives back q_CT (up to sign) and R_CT = R(q_CT) (P001-3 (docs/papers.md#p001-3))."""
    if gibbs_set is not None:
        with np.errstate(over="ignore"):
            g = gibbs_set_from_quat(quat_conjugate(q), gibbs_set)
        if not np.all(np.abs(g) < 1e6):
            return  # the set is singular here, or within 1e-6 of it (the round trip loses digits)
    pose = GibbsPose.from_quat(q, R_TC_C, gibbs_set=gibbs_set)
    assert quat_angle_between(pose.q_CT, q) < 1e-7
    np.testing.assert_allclose(pose.R_CT, matrix_from_quat(q), atol=1e-9)
    if gibbs_set is None:
        assert np.max(np.abs(pose.g)) <= 1.0 + 1e-12


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-2, 2), min_size=3, max_size=3), st.lists(st.floats(-3, 3), min_size=3, max_size=3),
       st.integers(0, 3))
def test_composition_then_switch_keeps_the_rotation_and_bounds_the_set(dg, g, i):
    """001 eq (10) then (5): A(g') R^(i') = A(δg) A(g) R^(i), and afterwards every |g'_j| <= 1."""
    dg, g = np.array([dg]), np.array([g])
    i = np.array([i])
    if abs(1.0 - dg[0] @ g[0]) < 1e-6:
        return  # handled exactly by the dedicated test below; near it the target matrix loses digits
    g2, i2 = _compose_switch(dg, g, i, 0.0)
    np.testing.assert_allclose(shuster_matrix_from_gibbs_set(g2, i2),
                               shuster_matrix_from_gibbs(dg) @ shuster_matrix_from_gibbs_set(g, i), atol=1e-9)
    assert np.max(np.abs(g2)) <= 1.0 + 1e-12


def test_composition_landing_exactly_on_180_degrees_switches_to_a_finite_set():
    """δg·g = 1 makes eq (10) divide by zero; the switch is done on the homogeneous form instead."""
    cases = [([0.5, 0.0, 0.0], [2.0, 0.0, 0.0], 0), ([0.0, 0.25, 0.0], [1.0, 4.0, -2.0], 2),
             ([0.0, 0.0, -1.0], [0.3, 0.2, -1.0], 3)]
    for dg, g, i in cases:
        dg, g, i = np.array([dg]), np.array([g]), np.array([i])
        assert 1.0 - dg[0] @ g[0] == 0.0
        g2, i2 = _compose_switch(dg, g, i, 0.0)
        assert np.all(np.isfinite(g2)) and np.max(np.abs(g2)) <= 1.0
        np.testing.assert_allclose(shuster_matrix_from_gibbs_set(g2, i2),
                                   shuster_matrix_from_gibbs(dg) @ shuster_matrix_from_gibbs_set(g, i), atol=1e-12)


def test_projection_jacobian_matches_central_differences_of_the_corrected_model():
    """A_j of eq (25) with J_c of flag P001-1 (docs/papers.md#p001-1) equals ∂x/∂[δg, Δt] under the eq (10) error composition."""
    rng = np.random.default_rng(2)
    for gibbs_set in (0, 1, 2, 3):
        q = quat_from_rotvec(rng.standard_normal(3))
        pose = GibbsPose.from_quat(q, R_TC_C + rng.standard_normal(3), gibbs_set=gibbs_set)
        _, A = projection_jacobian(CUBE_T, pose, focal_length_m=F_M)
        h = 1e-6
        for k in range(6):
            xs = []
            for s in (1.0, -1.0):
                dX = np.zeros(6)
                dX[k] = s * h
                g = (dX[:3] + pose.g - np.cross(dX[:3], pose.g)) / (1.0 - dX[:3] @ pose.g)  # eq (10)
                moved = GibbsPose(g, pose.gibbs_set, pose.r_TC_C + dX[3:])
                xs.append(projection_jacobian(CUBE_T, moved, focal_length_m=F_M)[0])
            fd = (xs[0] - xs[1]) / (2 * h)
            np.testing.assert_allclose(A[..., k], fd, rtol=1e-5, atol=1e-9 * np.abs(fd).max())


# ------------------------------------------------------------------------------ accuracy
def test_noise_free_images_give_the_true_pose_from_a_5_degree_1_metre_guess():
    rng = np.random.default_rng(3)
    q = quat_from_rotvec(rng.standard_normal((50, 3)))
    r = R_TC_C + rng.uniform(-1.5, 1.5, (50, 3)) * [1, 1, 0]
    xy, vis = frames(q, r)
    q0, r0 = perturbed(q, r, angle_deg=5.0, offset_m=1.0, rng=4)
    res = solve_pose_rodrigues(CUBE_T, xy, GibbsPose.from_quat(q0, r0), focal_length_m=F_M)
    assert res.ok.all(), np.unique(res.failure_reason)
    assert np.max(quat_angle_between(res.q_CT, q)) < 1e-9
    np.testing.assert_allclose(res.r_TC_C, r, atol=1e-7)
    assert np.all(res.iterations <= 8)
    assert np.all(res.n_points == vis.sum(-1))


def test_noisy_solution_is_the_reprojection_minimum_found_by_opencv_sqpnp_plus_lm():
    """Same frames, independent solver: SQPnP then Levenberg–Marquardt reach the same minimum."""
    rng = np.random.default_rng(5)
    n = 40
    q = quat_from_rotvec(rng.standard_normal((n, 3)))
    xy, vis = frames(q, R_TC_C, noise_px=1.0, rng=6)
    q0, r0 = perturbed(q, R_TC_C, angle_deg=3.0, offset_m=0.5, rng=7)
    res = solve_pose_rodrigues(CUBE_T, xy, GibbsPose.from_quat(q0, r0), focal_length_m=F_M,
                               eps_attitude=1e-12, eps_translation_m=1e-9, max_iterations=50)
    assert res.ok.all()
    xy_hat, _ = project_focal_plane(CUBE_T, res.R_CT, res.r_TC_C, focal_length_m=F_M)
    rms = np.sqrt(np.nanmean((xy_hat - xy) ** 2, axis=(-1, -2)))
    np.testing.assert_allclose(res.residual_rms_m, rms, rtol=1e-9)
    assert 0.2 * PIXEL_M < np.median(rms) < 1.0 * PIXEL_M  # 1 px noise, 12–14 residuals, 6 unknowns
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-14)
    for b in range(n):
        uv = pixels_from_focal_plane(xy[b, vis[b]], pixel_size_m=PIXEL_M, principal_point_px=CENTRE_PX)
        ok, rvec, tvec = cv2.solvePnP(CUBE_T[vis[b]], uv, K, None, flags=cv2.SOLVEPNP_SQPNP)
        assert ok
        rvec, tvec = cv2.solvePnPRefineLM(CUBE_T[vis[b]], uv, K, None, rvec, tvec, crit)
        if vis[b].sum() == 4:
            continue  # a face seen head-on: two near-equal minima, SQPnP may start in the other one
        assert np.degrees(quat_angle_between(quat_from_rotvec(rvec.ravel()), res.q_CT[b])) < 1e-5
        np.testing.assert_allclose(tvec.ravel(), res.r_TC_C[b], atol=1e-5)


def test_weight_zero_is_the_same_as_not_seeing_the_point():
    rng = np.random.default_rng(8)
    q = quat_from_rotvec(rng.standard_normal(3))
    xy, vis = frames(q, R_TC_C, noise_px=1.0, rng=9)
    init = GibbsPose.from_quat(*perturbed(q, R_TC_C, angle_deg=2.0, offset_m=0.3, rng=10))
    drop = np.flatnonzero(vis)[0]
    w = np.ones(8)
    w[drop] = 0.0
    a = solve_pose_rodrigues(CUBE_T, xy, init, focal_length_m=F_M, weights=w)
    v2 = vis.copy()
    v2[drop] = False
    b = solve_pose_rodrigues(CUBE_T, xy, init, focal_length_m=F_M, visible=v2)
    assert a.ok and b.ok and a.n_points == b.n_points == vis.sum() - 1
    np.testing.assert_allclose(a.r_TC_C, b.r_TC_C, atol=1e-12)


# ------------------------------------------------------------------------------ switching
def test_switching_never_fails_over_10000_random_attitudes_including_exact_180_degree_rotations():
    """9000 uniform attitudes and 1000 exact 180° rotations (random, coordinate and diagonal axes),
    1 px noise, guesses 5° / 0.5 m off, half of them forced into set 0 (|g| up to ~23 at 180°)."""
    rng = np.random.default_rng(11)
    q = rng.standard_normal((10000, 4))
    axes = rng.standard_normal((1000, 3))
    special = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, 0, 1], [0, 1, 1], [1, 1, 1], [1, -1, 0]], float)
    axes[: 8 * 12] = np.tile(special, (12, 1))
    q[9000:, 0] = 0.0  # [0, n]: a rotation by exactly π about n
    q[9000:, 1:] = axes
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    assert np.all(q[9000:, 0] == 0.0)  # exactly 180°
    r = R_TC_C + rng.uniform(-1.5, 1.5, (10000, 3)) * [1, 1, 0]
    xy, vis = frames(q, r, noise_px=1.0, rng=12)
    q0, r0 = perturbed(q, r, angle_deg=5.0, offset_m=0.5, rng=13)
    init = GibbsPose.from_quat(q0, r0)
    forced = GibbsPose.from_quat(q0, r0, gibbs_set=np.zeros(10000, int))
    half = np.arange(10000) % 2 == 0
    init = forced.where(half, init)
    assert np.max(np.abs(init.g)) > 10.0

    res = solve_pose_rodrigues(CUBE_T, xy, init, focal_length_m=F_M)

    assert res.ok.all(), dict(zip(*np.unique(res.failure_reason, return_counts=True), strict=True))
    assert np.max(np.abs(res.pose.g)) <= 1.0 + 1e-12
    assert np.count_nonzero(res.switches) > 2500  # the switching was exercised
    err_deg = np.degrees(quat_angle_between(res.q_CT, q))
    # 1 px on a 570 px cube: ~0.1° typical; a face seen head-on (4 coplanar points) is much weaker.
    assert np.median(err_deg) < 0.2 and np.percentile(err_deg, 99) < 0.5 and err_deg.max() < 10.0
    assert np.median(err_deg[9000:]) < 0.2
    assert np.max(res.residual_rms_m) < 2.0 * PIXEL_M
    assert np.percentile(np.abs(res.r_TC_C - r)[:, 2], 99) < 0.5
    assert np.percentile(res.iterations, 99) <= 6  # face-on views take longer (see max_iterations)


def _track_through_180(noise_px, rng):
    """Rotation about a fixed axis, 0.4° per epoch, from 170.15° across 180° (between epochs 24 and 25)."""
    angle = np.radians(170.15 + 0.4 * np.arange(50))
    axis = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])
    q = quat_from_axis_angle(axis, angle)
    xy, vis = frames(q, R_TC_C, noise_px=noise_px, rng=rng)
    return q, xy, vis


def test_non_switching_solver_fails_at_the_180_degree_crossing_and_switching_solver_does_not():
    q, xy, _ = _track_through_180(0.0, 0)
    first = q[0]
    sw = track_pose_rodrigues(CUBE_T, xy, GibbsPose.from_quat(first, R_TC_C), focal_length_m=F_M)
    assert sw.ok.all()
    assert np.max(quat_angle_between(sw.q_CT, q)) < 1e-9
    assert set(np.unique(sw.pose.gibbs_set)) != {0}
    ns = track_pose_rodrigues(CUBE_T, xy, GibbsPose.from_quat(first, R_TC_C, gibbs_set=0), focal_length_m=F_M,
                              switching=False)
    assert ns.ok[:25].all()
    assert not ns.ok[25:].any()
    assert set(ns.failure_reason[25:]) == {"gibbs_singular"}
    assert np.max(np.abs(ns.pose.g[24])) > 400  # tan(89.875°) = 458: the set-0 vector just before


def test_noisy_track_through_180_degrees_switching_stays_accurate():
    q, xy, _ = _track_through_180(1.0, 14)
    res = track_pose_rodrigues(CUBE_T, xy, GibbsPose.from_quat(q[0], R_TC_C), focal_length_m=F_M)
    assert res.ok.all()
    assert np.degrees(np.max(quat_angle_between(res.q_CT, q))) < 0.5
    ns = track_pose_rodrigues(CUBE_T, xy, GibbsPose.from_quat(q[0], R_TC_C, gibbs_set=0), focal_length_m=F_M,
                              switching=False)
    first_fail = np.flatnonzero(~ns.ok)[0]
    assert first_fail in (24, 25) and not ns.ok[first_fail:].any()


# ------------------------------------------------------------------------------ failures
def test_too_few_points_is_flagged_and_the_next_epoch_recovers_from_the_last_good_pose():
    q, xy, vis = _track_through_180(1.0, 15)
    q, xy, vis = q[:8], xy[:8].copy(), vis[:8].copy()
    keep = np.flatnonzero(vis[3])[:2]
    vis[3] = False
    vis[3, keep] = True
    res = track_pose_rodrigues(CUBE_T, xy, GibbsPose.from_quat(q[0], R_TC_C), focal_length_m=F_M, visible=vis)
    assert res.failure_reason[3] == "too_few_points" and res.n_points[3] == 2
    assert np.all(np.isnan(res.r_TC_C[3])) and np.all(np.isnan(res.q_CT[3]))
    ok = np.r_[0:3, 4:8]
    assert res.ok[ok].all()
    assert np.degrees(np.max(quat_angle_between(res.q_CT[ok], q[ok]))) < 0.5


def test_collinear_points_are_flagged_rank_deficient_and_the_next_epoch_recovers():
    line_T = np.array([[-1.0, -1.0, -1.0], [-0.5, -0.5, -0.5], [0.5, 0.5, 0.5], [1.0, 1.0, 1.0], [1.0, -1.0, 1.0]])
    q = quat_from_axis_angle([0, 0, 1.0], np.radians([10.0, 10.4, 10.8]))
    xy, _ = project_focal_plane(line_T, matrix_from_quat(q), np.broadcast_to(R_TC_C, (3, 3)), focal_length_m=F_M)
    vis = np.ones((3, 5), bool)
    vis[1, 4] = False  # epoch 1 sees only the four points on the diagonal
    res = track_pose_rodrigues(line_T, xy, GibbsPose.from_quat(q[0], R_TC_C + 0.1), focal_length_m=F_M, visible=vis)
    assert list(res.failure_reason) == ["", "rank_deficient", ""]
    assert quat_angle_between(res.q_CT[2], q[2]) < 1e-9


def test_point_behind_the_camera_and_iteration_limit_are_reported_not_raised():
    q = quat_from_rotvec([0.1, 0.2, 0.3])
    xy, _ = frames(q, R_TC_C)
    behind = GibbsPose.from_quat(q, [0.0, 0.0, -5.0])
    res = solve_pose_rodrigues(CUBE_T, xy, behind, focal_length_m=F_M)
    assert res.failure_reason == "behind_camera" and not res.ok
    q0, r0 = perturbed(q, R_TC_C, angle_deg=5.0, offset_m=1.0, rng=16)
    res = solve_pose_rodrigues(CUBE_T, xy, GibbsPose.from_quat(q0, r0), focal_length_m=F_M, max_iterations=1)
    assert res.failure_reason == "not_converged"
    assert set(FAILURE_REASONS) >= {"behind_camera", "not_converged", "too_few_points", "rank_deficient",
                                    "gibbs_singular"}


def test_non_switching_solver_refuses_an_initial_set_at_its_singularity():
    q = np.array([0.0, 0.0, 0.0, 1.0])  # exactly 180° about z
    xy, _ = frames(q, R_TC_C)
    init = GibbsPose.from_quat(q, R_TC_C, gibbs_set=0)  # g^(0) = inf
    res = solve_pose_rodrigues(CUBE_T, xy, init, focal_length_m=F_M, switching=False)
    assert res.failure_reason == "gibbs_singular"


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"focal_length_m": 0.0}, "focal_length_m"),
        ({"focal_length_m": F_M, "eps_attitude": -1.0}, "eps_attitude"),
        ({"focal_length_m": F_M, "max_iterations": 0}, "max_iterations"),
        ({"focal_length_m": F_M, "eta": -0.1}, "eta"),
        ({"focal_length_m": F_M, "visible": np.ones(7, bool)}, "visible"),
        ({"focal_length_m": F_M, "weights": -np.ones(8)}, "weights"),
    ],
)
def test_bad_arguments_raise_value_error_naming_the_parameter(kwargs, name):
    xy, _ = frames(np.array([1.0, 0, 0, 0]), R_TC_C)
    init = GibbsPose.from_quat([1.0, 0, 0, 0], R_TC_C)
    with pytest.raises(ValueError, match=name):
        solve_pose_rodrigues(CUBE_T, xy, init, **kwargs)


def test_bad_shapes_and_sets_raise_value_error_naming_the_parameter():
    init = GibbsPose.from_quat([1.0, 0, 0, 0], R_TC_C)
    with pytest.raises(ValueError, match="xy_m"):
        solve_pose_rodrigues(CUBE_T, np.zeros((7, 2)), init, focal_length_m=F_M)
    with pytest.raises(ValueError, match="points_T"):
        solve_pose_rodrigues(CUBE_T[:, :2], np.zeros((8, 2)), init, focal_length_m=F_M)
    with pytest.raises(ValueError, match="gibbs_set"):
        GibbsPose.from_quat([1.0, 0, 0, 0], R_TC_C, gibbs_set=4)
    with pytest.raises(ValueError, match="initial"):
        solve_pose_rodrigues(CUBE_T, np.zeros((8, 2)), (np.zeros(3), 0, R_TC_C), focal_length_m=F_M)
