"""Cramér–Rao selection score (formation.quality): agreement with reconstruction's bound, ordering."""

import numpy as np
import pytest

from attitude.quaternion import matrix_from_quat, quat_from_axis_angle, quat_from_rotvec
from formation.constraints import ObservationConstraints, evaluate
from formation.geometry import symmetric_views
from formation.quality import DEFAULT_INCREMENT_ROTVEC_H, crlb_score
from formation.selection import point_dop, select_observers
from reconstruction.accuracy import attitude_increment_crlb
from vision.camera import PinholeCamera
from vision.camera import look_at as vision_look_at

CAM = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)
Q_TRAIL = quat_from_axis_angle([1.0, 0.0, 0.0], np.pi / 2)  # cone axis along −y_H (observers trailing)


def _sphere(m: int, radius_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Fibonacci points on a sphere and their outward normals."""
    i = np.arange(m) + 0.5
    polar = np.arccos(1.0 - 2.0 * i / m)
    az = np.pi * (1.0 + 5.0**0.5) * i
    u = np.stack([np.cos(az) * np.sin(polar), np.sin(az) * np.sin(polar), np.cos(polar)], -1)
    return radius_m * u, u


def _cones(pairs):
    return np.stack([symmetric_views(3, d, g, orientation=Q_TRAIL).r_CT_H for d, g in pairs])


def test_score_equals_the_reconstruction_bound_computed_subset_by_subset():
    """Vectorised (T, S) scores, in small chunks, against one attitude_increment_crlb call per subset
    with poses from vision.camera.look_at (an independent look-at)."""
    X, _ = _sphere(40, 4.0)
    rng = np.random.default_rng(3)
    pos = _cones([(50.0, 10.0), (80.0, 20.0), (40.0, 5.0)]) + rng.normal(scale=2.0, size=(3, 3, 3))
    pos = np.stack([pos, pos[::-1]])  # (T=2, S=3, k=3, 3)
    rv = np.deg2rad([[0.5, 0.5, 0.5], [1.0, -0.2, 0.3]])
    got = crlb_score(CAM, X, pixel_sigma_px=0.5, increment_rotvec_H=rv, max_batch_views=250)(pos)
    for t in range(2):
        R = matrix_from_quat(quat_from_rotvec(rv[t]))
        for s in range(3):
            T = np.stack([vision_look_at(e, np.zeros(3), (0.0, 0.0, 1.0)) for e in pos[t, s]])
            b = attitude_increment_crlb(X, np.broadcast_to(CAM.K, (3, 3, 3)), T, pixel_sigma_px=0.5,
                                        R_delta=R, image_size=CAM.image_size)
            assert got[t, s] == pytest.approx(float(b.rms_angle_rad), rel=1e-9)


def test_wider_baseline_ranks_above_narrower_and_closer_above_farther_like_point_dop():
    """One factor at a time (no occlusion), the bound and point_dop give the same order."""
    X, _ = _sphere(60, 4.0)
    score = crlb_score(CAM, X, pixel_sigma_px=0.5)
    gammas = [2.0, 5.0, 10.0, 20.0, 30.0]
    ranges = [35.0, 60.0, 100.0, 140.0]
    by_gamma = _cones([(60.0, g) for g in gammas])[None]
    by_range = _cones([(d, 10.0) for d in ranges])[None]
    for pos in (by_gamma, by_range):
        s_crlb = score(pos)[0]
        s_dop = point_dop(pos)[0]
        assert np.all(np.isfinite(s_crlb))
        np.testing.assert_array_equal(np.argsort(s_crlb), np.argsort(s_dop))
    s = score(by_gamma)[0]
    assert np.all(np.diff(s) < 0)  # strictly better with every wider baseline
    assert s[-1] < 0.99 * s[0]


def test_bound_grows_in_proportion_to_range_and_weakly_with_baseline():
    """Far field: the pixel footprint, hence the bound, scales with range; baseline is secondary.

    This is where the bound and the point-at-the-centre proxy part ways: a close narrow set beats a
    far wide one for the attitude increment, while point DOP prefers the far wide one.
    """
    X, _ = _sphere(60, 4.0)
    score = crlb_score(CAM, X, pixel_sigma_px=0.5)
    s = score(_cones([(35.0, 10.0), (140.0, 10.0), (35.0, 2.0), (140.0, 30.0)])[None])[0]
    assert s[1] / s[0] == pytest.approx(4.0, rel=0.03)
    assert s[2] < s[3]
    dop = point_dop(_cones([(35.0, 2.0), (140.0, 30.0)]))
    assert dop[1] < dop[0]


def test_cameras_behind_an_opaque_face_see_nothing_and_score_inf():
    """A flat panel facing +y_H: cameras in front get a finite bound, cameras behind it none."""
    g = np.linspace(-2.0, 2.0, 7)
    X = np.stack(np.meshgrid(g, [0.0], g, indexing="ij"), -1).reshape(-1, 3)
    X[:, 1] = 0.3 * np.sin(X[:, 0]) * np.cos(X[:, 2])  # a little relief so the points are not coplanar
    N = np.broadcast_to([0.0, 1.0, 0.0], X.shape)
    front = symmetric_views(3, 50.0, 10.0, orientation=quat_from_axis_angle([1.0, 0.0, 0.0], -np.pi / 2)).r_CT_H
    pos = np.stack([front, front * np.array([1.0, -1.0, 1.0])])[None]
    s = crlb_score(CAM, X, pixel_sigma_px=0.5, normals_H=N)(pos)[0]
    assert np.isfinite(s[0]) and s[1] == np.inf
    no_occlusion = crlb_score(CAM, X, pixel_sigma_px=0.5)(pos)[0]
    assert s[0] == pytest.approx(no_occlusion[0], rel=1e-12)  # every point faces the front cameras


def test_selection_with_the_bound_prefers_the_close_set_over_the_far_wide_one():
    """Six candidates: a 3-view cone at 35 m (γ = 5°) and one at 140 m (γ = 30°), all feasible alone."""
    X, _ = _sphere(40, 4.0)
    r = np.concatenate(_cones([(35.0, 5.0), (140.0, 30.0)]))[None].repeat(2, axis=0)  # (T=2, 6, 3)
    con = ObservationConstraints(axis_angle_min_rad=0.0, axis_angle_max_rad=np.pi)
    ev = evaluate(con, r)
    by_bound = select_observers(ev, r, 3, score_fn=crlb_score(CAM, X, pixel_sigma_px=0.5))
    by_dop = select_observers(ev, r, 3)
    assert list(by_bound.subset[0]) == [0, 1, 2]
    assert list(by_dop.subset[0]) != [0, 1, 2]
    assert np.all(np.isfinite(by_bound.score))


def test_default_increment_is_the_papers_step():
    assert np.rad2deg(np.linalg.norm(DEFAULT_INCREMENT_ROTVEC_H)) == pytest.approx(0.5 * np.sqrt(3), rel=1e-12)


def test_bad_arguments_are_named():
    X, _ = _sphere(10, 4.0)
    with pytest.raises(ValueError, match="points_H"):
        crlb_score(CAM, X[:2], pixel_sigma_px=0.5)
    with pytest.raises(ValueError, match="pixel_sigma_px"):
        crlb_score(CAM, X, pixel_sigma_px=0.0)
    with pytest.raises(ValueError, match="normals_H"):
        crlb_score(CAM, X, pixel_sigma_px=0.5, normals_H=X[:5])
    with pytest.raises(ValueError, match="camera"):
        crlb_score(np.eye(3), X, pixel_sigma_px=0.5)
    with pytest.raises(ValueError, match="r_ST_H"):
        crlb_score(CAM, X, pixel_sigma_px=0.5)(np.zeros((2, 3, 3)))
    with pytest.raises(ValueError, match="points_H: 4 epochs"):
        crlb_score(CAM, np.stack([X] * 4), pixel_sigma_px=0.5)(np.ones((2, 1, 3, 3)))
