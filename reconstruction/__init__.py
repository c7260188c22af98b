"""3-D reconstruction of the target: triangulation, inter-frame association, rigid registration."""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader as lazy

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
        associate_observation_pairs,
        associate_pairs,
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
    "associate_observation_pairs",
    "associate_pairs",
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

# each public name is imported from its submodule on first use, so that ``import reconstruction``
# does not load SciPy, Numba (the registration kernels) or, through them, Open3D and OpenCV
__getattr__, __dir__, _ = lazy.attach(__name__, submod_attrs={
    "accuracy": ["AttitudeIncrementBound", "attitude_increment_crlb", "point_covariance"],
    "association": ["Association", "associate", "associate_from_observations", "associate_observation_pairs",
                    "associate_pairs", "camera_weights_from_counts"],
    "registration": ["RigidRegistration", "fit_rigid", "fit_rigid_ml", "fit_rigid_robust",
                     "register_fpfh_ransac", "register_icp"],
    "triangulation": ["Triangulation", "triangulate", "triangulate_from_observation"],
})
