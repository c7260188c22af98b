"""Shared fixtures of the vision tests: targets and the two-camera 50 m set-up of issue 5."""

import numpy as np
import pytest

from attitude.quaternion import quat_from_axis_angle, quat_from_matrix, quat_multiply
from vision.camera import PinholeCamera, look_at
from vision.target import bundled_mesh_path, fy1_target, load_mesh

TOPEX = bundled_mesh_path("topex")
HUBBLE = bundled_mesh_path("hubble")
INCH_M = 0.0254

# Issue 5 "done when" set-up: 1024 x 1024 px, 20 deg field of view, 50 m, optical axes 10 deg apart,
# Sun from the side (perpendicular to the mean line of sight).
SUN_SIDE_H = np.array([0.0, 0.0, 1.0])


def two_camera_poses(distance_m: float, angle_deg: float = 10.0) -> np.ndarray:
    """Two cameras in the x-y plane of H at +-angle/2 about +x, both looking at the origin."""
    g = np.deg2rad(angle_deg) / 2
    eyes = [distance_m * np.array([np.cos(a), np.sin(a), 0.0]) for a in (-g, g)]
    return np.stack([look_at(e, np.zeros(3)) for e in eyes])


def facing_attitude(normal_T, spin_deg: float = 0.0) -> np.ndarray:
    """q_HT that turns the body direction ``normal_T`` onto the bisector of the cameras (+x) and the
    Sun (+z), then spins the body about that bisector by ``spin_deg``."""
    nb = np.asarray(normal_T, float) / np.linalg.norm(normal_T)
    a = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)
    v, c = np.cross(nb, a), float(nb @ a)
    Kx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    R = np.eye(3) + Kx + Kx @ Kx / (1.0 + c)
    return quat_multiply(quat_from_axis_angle(a, np.deg2rad(spin_deg)), quat_from_matrix(R))


@pytest.fixture(scope="session")
def camera() -> PinholeCamera:
    return PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)


@pytest.fixture(scope="session")
def fy1():
    return fy1_target(seed=0)


@pytest.fixture(scope="session")
def topex():
    return load_mesh(TOPEX, unit_m=INCH_M, seed=0)


@pytest.fixture(scope="session")
def fy1_pair(camera, fy1):
    """Rendered views of FY-1 at 50 m, cells facing the camera/Sun bisector."""
    from vision.rendered import render_views

    T = two_camera_poses(50.0)
    q = facing_attitude([1.0, 0.0, 0.0])
    return T, q, render_views(camera, T, fy1, q, SUN_SIDE_H, rng=0)
