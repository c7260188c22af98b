"""Rigid registration of point clouds, ``Q ≈ R P + t``: Kabsch, RANSAC, maximum likelihood, ICP."""

from reconstruction.registration.icp import register_fpfh_ransac, register_icp
from reconstruction.registration.kabsch import fit_rigid
from reconstruction.registration.ml import fit_rigid_ml
from reconstruction.registration.result import RigidRegistration
from reconstruction.registration.robust import fit_rigid_robust

__all__ = [
    "RigidRegistration",
    "fit_rigid",
    "fit_rigid_robust",
    "fit_rigid_ml",
    "register_icp",
    "register_fpfh_ransac",
]
