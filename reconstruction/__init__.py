"""3-D reconstruction of the target: triangulation, inter-frame association, rigid registration."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from reconstruction.accuracy import (
        AttitudeIncrementBound,
        attitude_increment_crlb,
        point_covariance,
    )
    from reconstruction.association import (
        Association,
        associate,
        associate_from_observations,
        camera_weights_from_counts,
    )
    from reconstruction.registration import (
        RigidRegistration,
        fit_rigid,
        fit_rigid_ml,
        fit_rigid_robust,
        register_fpfh_ransac,
        register_icp,
    )
    from reconstruction.triangulation import (
        Triangulation,
        triangulate,
        triangulate_from_observation,
    )

__all__ = [
    "AttitudeIncrementBound",
    "attitude_increment_crlb",
    "point_covariance",
    "Association",
    "associate",
    "associate_from_observations",
    "camera_weights_from_counts",
    "RigidRegistration",
    "fit_rigid",
    "fit_rigid_ml",
    "fit_rigid_robust",
    "register_fpfh_ransac",
    "register_icp",
    "Triangulation",
    "triangulate",
    "triangulate_from_observation",
]

# module of each public name; imported on first use, so that ``import reconstruction`` does not
# load SciPy, Numba (the registration kernels) or, through them, Open3D and OpenCV
_MODULES = {
    "reconstruction.accuracy": ("AttitudeIncrementBound", "attitude_increment_crlb",
                                "point_covariance"),
    "reconstruction.association": ("Association", "associate", "associate_from_observations",
                                   "camera_weights_from_counts"),
    "reconstruction.registration": ("RigidRegistration", "fit_rigid", "fit_rigid_ml",
                                    "fit_rigid_robust", "register_fpfh_ransac", "register_icp"),
    "reconstruction.triangulation": ("Triangulation", "triangulate",
                                     "triangulate_from_observation"),
}
_SOURCES = {name: module for module, names in _MODULES.items() for name in names}


def __getattr__(name: str) -> Any:
    """Load a public name from its module on first access (PEP 562)."""
    module = _SOURCES.get(name)
    if module is None:
        raise AttributeError(f"module 'reconstruction' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
