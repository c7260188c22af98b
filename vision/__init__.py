"""Cameras, target models, rendering, features and the two observation modes of the formation's views."""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader as lazy

if TYPE_CHECKING:
    from vision.camera import PinholeCamera, cameras_per_view, look_at
    from vision.cylindrical import CylindricalCamera
    from vision.features import Keypoints, detect, match_views
    from vision.geometric import SurfaceFeatures, surface_features
    from vision.observation import Observation
    from vision.render import RenderResult
    from vision.rendered import render_views
    from vision.sensor import SensorModel
    from vision.target import (
        Material,
        Target,
        available_meshes,
        bundled_mesh_path,
        fy1_target,
        load_mesh,
        procedural_texture,
    )
    from vision.tof import TofCamera, sr4000

__all__ = [
    "PinholeCamera",
    "cameras_per_view",
    "look_at",
    "CylindricalCamera",
    "Keypoints",
    "detect",
    "match_views",
    "SurfaceFeatures",
    "surface_features",
    "Observation",
    "RenderResult",
    "render_views",
    "SensorModel",
    "Material",
    "Target",
    "available_meshes",
    "bundled_mesh_path",
    "fy1_target",
    "load_mesh",
    "procedural_texture",
    "TofCamera",
    "sr4000",
]

# Submodules and public names are imported on first use: the renderer needs Open3D and the features
# need OpenCV, both slow to import, and ``import vision`` stays light. No public name equals a
# submodule's name (``vision.render`` is the module; its function is ``vision.render.render``).
_SUBMODULES = ("camera", "cylindrical", "features", "geometric", "observation", "render",
               "rendered", "sensor", "target", "tof")
__getattr__, __dir__, _ = lazy.attach(__name__, submodules=_SUBMODULES, submod_attrs={
    "camera": ["PinholeCamera", "cameras_per_view", "look_at"],
    "cylindrical": ["CylindricalCamera"],
    "features": ["Keypoints", "detect", "match_views"],
    "geometric": ["SurfaceFeatures", "surface_features"],
    "observation": ["Observation"],
    "render": ["RenderResult"],
    "rendered": ["render_views"],
    "sensor": ["SensorModel"],
    "target": ["Material", "Target", "available_meshes", "bundled_mesh_path", "fy1_target",
               "load_mesh", "procedural_texture"],
    "tof": ["TofCamera", "sr4000"],
})
