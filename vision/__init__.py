"""Cameras, target models, rendering, features and the two observation modes of the formation's views."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

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

# Public name -> submodule. Submodules are imported on first use: the renderer needs Open3D and the
# features need OpenCV, both slow to import, and ``import vision`` stays light. No public name equals
# a submodule's name (``vision.render`` is the module; its function is ``vision.render.render``).
_PUBLIC = {
    "PinholeCamera": "camera",
    "cameras_per_view": "camera",
    "look_at": "camera",
    "CylindricalCamera": "cylindrical",
    "Keypoints": "features",
    "detect": "features",
    "match_views": "features",
    "SurfaceFeatures": "geometric",
    "surface_features": "geometric",
    "Observation": "observation",
    "RenderResult": "render",
    "render_views": "rendered",
    "SensorModel": "sensor",
    "Material": "target",
    "Target": "target",
    "available_meshes": "target",
    "bundled_mesh_path": "target",
    "fy1_target": "target",
    "load_mesh": "target",
    "procedural_texture": "target",
    "TofCamera": "tof",
    "sr4000": "tof",
}
_SUBMODULES = ("camera", "cylindrical", "features", "geometric", "observation", "render",
               "rendered", "sensor", "target", "tof")

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


def __getattr__(name: str) -> Any:
    if name in _PUBLIC:
        value = getattr(importlib.import_module(f"vision.{_PUBLIC[name]}"), name)
    elif name in _SUBMODULES:
        value = importlib.import_module(f"vision.{name}")
    else:
        raise AttributeError(f"module 'vision' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC) | set(_SUBMODULES))
