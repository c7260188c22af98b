"""Pinhole camera, poses and conversions to OpenCV and pycolmap, against analytic truth."""

import cv2
import numpy as np
import pycolmap
import pytest

from attitude.quaternion import matrix_from_quat, quat_normalize
from vision.camera import (
    PinholeCamera,
    camera_center,
    invert_pose,
    look_at,
    pose_from_rigid3d,
    pose_from_Rt,
    pose_from_rvec_tvec,
    rigid3d_from_pose,
    rvec_tvec_from_pose,
    transform_points,
    uv_colmap_from_opencv,
)

CAM = PinholeCamera(800, 600, 700.0, 710.0, 401.3, 297.8)


def _random_poses(rng, n):
    R = matrix_from_quat(quat_normalize(rng.standard_normal((n, 4))))
    return pose_from_Rt(R, rng.uniform(-5, 5, (n, 3)))


def test_from_fov_puts_the_image_edges_at_half_the_field_of_view():
    cam = PinholeCamera.from_fov(1024, 768, fov_x_deg=20.0)
    d = cam.ray_directions(np.array([[-0.5, cam.cy], [1023.5, cam.cy]]))
    half = np.degrees(np.arctan2(np.abs(d[:, 0]), d[:, 2]))
    np.testing.assert_allclose(half, 10.0, atol=1e-12)
    assert cam.fx == cam.fy and (cam.cx, cam.cy) == (511.5, 383.5)
    np.testing.assert_allclose(np.degrees(cam.fov_x_rad), 20.0, atol=1e-12)


def test_backprojection_inverts_projection_for_random_points():
    rng = np.random.default_rng(1)
    X = np.c_[rng.uniform(-3, 3, (500, 2)), rng.uniform(1, 100, 500)]
    uv = CAM.project(X)
    np.testing.assert_allclose(CAM.backproject(uv, X[:, 2]), X, rtol=1e-12, atol=1e-9)


def test_points_behind_the_camera_project_to_nan_and_are_outside_the_image():
    uv = CAM.project([[0.1, 0.2, -3.0], [0.0, 0.0, 0.0]])
    assert np.all(np.isnan(uv))
    assert not CAM.in_image(uv).any()


def test_in_image_uses_pixel_edges_at_minus_half_and_size_minus_half():
    uv = np.array([[-0.5, -0.5], [799.5, 599.5], [-0.51, 10], [10, 599.51], [3.0, 3.0]])
    np.testing.assert_array_equal(CAM.in_image(uv), [True, True, False, False, True])
    np.testing.assert_array_equal(CAM.in_image(uv, margin_px=4.0), [False, False, False, False, False])


def test_look_at_centres_the_target_and_keeps_world_up_upwards_in_the_image():
    eye = np.array([30.0, -40.0, 10.0])
    T = look_at(eye, np.zeros(3), up_W=[0, 0, 1])
    uv, z = CAM.project_world(np.zeros(3), T)
    np.testing.assert_allclose(uv, [CAM.cx, CAM.cy], atol=1e-9)
    np.testing.assert_allclose(z, np.linalg.norm(eye), rtol=1e-12)
    up_uv, _ = CAM.project_world([0, 0, 1.0], T)
    assert up_uv[1] < CAM.cy                      # v grows downwards
    np.testing.assert_allclose(camera_center(T), eye, atol=1e-12)
    R = T[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)


def test_look_at_is_vectorised_over_eyes():
    eyes = np.array([[10.0, 0, 0], [0, 10.0, 0], [-7, -7, 3]])
    T = look_at(eyes, np.zeros(3))
    assert T.shape == (3, 4, 4)
    np.testing.assert_allclose(T[1], look_at(eyes[1], np.zeros(3)))


def test_look_at_rejects_degenerate_geometry():
    with pytest.raises(ValueError, match="eye_W"):
        look_at([1.0, 2, 3], [1.0, 2, 3])
    with pytest.raises(ValueError, match="up_W"):
        look_at([0, 0, 10.0], [0, 0, 0], up_W=[0, 0, 1])


def test_invert_pose_composes_to_identity_and_transform_points_matches_matrix_product():
    rng = np.random.default_rng(2)
    T = _random_poses(rng, 20)
    np.testing.assert_allclose(T @ invert_pose(T), np.broadcast_to(np.eye(4), T.shape), atol=1e-12)
    X = rng.standard_normal((20, 3))
    expected = (T @ np.c_[X, np.ones(20)][..., None])[..., :3, 0]
    np.testing.assert_allclose(transform_points(T, X), expected, atol=1e-12)


def test_projection_agrees_with_opencv_projectpoints():
    rng = np.random.default_rng(3)
    T = _random_poses(rng, 1)[0]
    X_C = np.c_[rng.uniform(-2, 2, (50, 2)), rng.uniform(5, 60, 50)]
    X_W = transform_points(invert_pose(T), X_C)
    rvec, tvec = rvec_tvec_from_pose(T)
    K, dist = CAM.to_opencv()
    uv_cv, _ = cv2.projectPoints(X_W, rvec, tvec, K, dist)
    uv, _ = CAM.project_world(X_W, T)
    np.testing.assert_allclose(uv, uv_cv.reshape(-1, 2), atol=1e-8)
    np.testing.assert_allclose(pose_from_rvec_tvec(rvec, tvec), T, atol=1e-12)


def test_pycolmap_camera_projects_half_a_pixel_right_and_down_of_opencv():
    rng = np.random.default_rng(4)
    X_C = np.c_[rng.uniform(-2, 2, (50, 2)), rng.uniform(5, 60, 50)]
    pc = CAM.to_pycolmap()
    np.testing.assert_allclose(pc.img_from_cam(X_C), uv_colmap_from_opencv(CAM.project(X_C)), atol=1e-8)
    assert PinholeCamera.from_pycolmap(pc) == CAM


def test_pycolmap_rigid3d_round_trip_and_action_match_T_CW():
    rng = np.random.default_rng(5)
    T = _random_poses(rng, 1)[0]
    r = rigid3d_from_pose(T)
    X = rng.standard_normal(3)
    np.testing.assert_allclose(np.asarray(r * X).ravel(), transform_points(T, X), atol=1e-12)
    np.testing.assert_allclose(pose_from_rigid3d(r), T, atol=1e-12)
    assert isinstance(r, pycolmap.Rigid3d)


@pytest.mark.parametrize("kwargs,name", [
    (dict(width=0, height=10, fx=1, fy=1, cx=0, cy=0), "width"),
    (dict(width=10, height=10, fx=-1, fy=1, cx=0, cy=0), "fx"),
    (dict(width=10, height=10, fx=1, fy=1, cx=np.nan, cy=0), "cx"),
])
def test_camera_rejects_bad_intrinsics_naming_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        PinholeCamera(**kwargs)


def test_from_fov_rejects_out_of_range_angle():
    with pytest.raises(ValueError, match="fov_x_deg"):
        PinholeCamera.from_fov(100, 100, fov_x_deg=180.0)
