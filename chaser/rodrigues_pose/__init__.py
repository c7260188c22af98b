"""Monocular relative pose from known feature points by Gibbs vectors with parameter-set switching (paper 001)."""

from chaser.rodrigues_pose.bound import PoseBound, pose_crlb
from chaser.rodrigues_pose.pose import FAILURE_REASONS, GibbsPose, RodriguesPoseResult
from chaser.rodrigues_pose.projection import (
    focal_plane_from_pixels,
    pixels_from_focal_plane,
    project_focal_plane,
    projection_jacobian,
)
from chaser.rodrigues_pose.solver import solve_pose_rodrigues, track_pose_rodrigues

__all__ = [
    "FAILURE_REASONS",
    "GibbsPose",
    "PoseBound",
    "RodriguesPoseResult",
    "focal_plane_from_pixels",
    "pixels_from_focal_plane",
    "pose_crlb",
    "project_focal_plane",
    "projection_jacobian",
    "solve_pose_rodrigues",
    "track_pose_rodrigues",
]
