"""The ``cylindrical_004`` config: the 004 rig, its calibration, the Table 1/2 analogues and the dynamic test;
with 004's Table 1 and Table 2 values as printed.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from experiments.config import (
    Angle_deg,
    ConfigTable,
    Duration_s,
    FiniteFloat,
    Flag,
    Integer,
    Length_m,
    Length_mm,
    ScenarioConfig,
    Seed,
    Speed_mm_s,
)
from experiments.sweep import SweepSpec

__all__ = ["Config", "CameraConfig", "RigConfig", "CalibrationConfig", "PointsConfig", "AttitudeConfig",
           "DynamicConfig", "EnvelopeConfig", "TABLE1_MM", "TABLE1_ERR_MM", "TABLE2_DEG", "TABLE2_ERR_DEG", "PAPER_MAX_ERR_DEG",
           "POSE_167_DEG"]

#: 004 Table 1: tracker coordinates (X, Y, Z) of the 8 test points, mm.
TABLE1_MM = [
    [1149.62, 3713.20, -226.45], [1456.99, 3699.62, -5.40], [1376.87, 3599.28, -87.13],
    [1166.75, 3780.24, 48.98], [1372.40, 3602.85, -139.77], [1114.07, 3731.43, -39.39],
    [1172.29, 3673.84, -1.97], [1173.55, 3707.41, 28.15],
]
#: 004 Table 1: the paper's errors (Δx, Δy, Δz, Δxyz), mm.
TABLE1_ERR_MM = [
    [-0.05, -0.09, 0.06, 0.12], [0.06, -0.11, 0.06, 0.14], [-0.09, 0.22, -0.07, 0.25],
    [-0.12, 0.27, -0.08, 0.31], [0.08, -0.17, -0.11, 0.22], [0.13, -0.21, -0.07, 0.26],
    [-0.17, -0.34, 0.16, 0.41], [-0.14, 0.30, 0.13, 0.36],
]
#: 004 Table 2: "true" (yaw α, roll β, pitch γ) of the 8 poses, degrees.
TABLE2_DEG = [
    [-2.6460, 87.6570, -45.1910], [87.4626, 77.8150, -87.2480], [-22.0581, 59.1990, 6.0103],
    [-25.2650, 61.2085, 7.3825], [4.7596, 87.9791, -37.5984], [-34.3116, 73.4285, 2.0567],
    [19.3189, 88.6700, -22.1653], [-10.5321, 76.2800, 7.4063],
]
#: 004 Table 2: the paper's errors (Δα, Δβ, Δγ), degrees.
TABLE2_ERR_DEG = [
    [0.1747, 0.1236, -0.0650], [0.0775, -0.0433, -0.1967], [0.1624, -0.0549, -0.1880],
    [-0.1372, -0.0275, 0.2322], [-0.1127, -0.0717, 0.1356], [-0.2012, 0.0204, 0.0904],
    [0.1947, 0.0473, -0.1115], [0.1160, 0.0601, -0.2233],
]
#: The paper's maxima (yaw, roll, pitch), degrees (abstract; flag P004-12, docs/papers.md#p004-12).
PAPER_MAX_ERR_DEG = [0.20, 0.12, 0.23]
#: The 167.7° reading of Table 2 No. 2 (scipy extrinsic "zxy"; flag P004-3, docs/papers.md#p004-3): in the
#: 3-1-2 reading of eq 9–11 this is No. 2 with the three angles negated.
POSE_167_DEG = [-87.4626, -77.8150, 87.2480]


class CameraConfig(ConfigTable):
    """Linear-CCD hardware (not given in 004: assumed values, see docs/cylindrical.md)."""

    n_pixels: Integer = Field(8000, ge=512, le=100_000)
    pixel_pitch_um: FiniteFloat = Field(7.0, gt=0.0, le=100.0)
    focal_length_mm: FiniteFloat = Field(100.0, gt=1.0, le=2000.0)
    spot_sigma_px: FiniteFloat = Field(2.5, gt=0.3, le=50.0)
    peak_dn: FiniteFloat = Field(3000.0, gt=0.0, le=60000.0)
    read_noise_dn: FiniteFloat = Field(4.0, ge=0.0, le=1000.0)
    electrons_per_dn: FiniteFloat = Field(4.0, gt=0.0, le=1e6)
    spot_method: Literal["threshold_centroid", "gaussian3"] = "threshold_centroid"
    distortion_scale: FiniteFloat = Field(1.0, ge=0.0, le=10.0, description="multiplies the default lens distortion")


class RigConfig(ConfigTable):
    baseline_m: Length_m = Field(2.0, gt=0.0, le=50.0)
    convergence_deg: Angle_deg = Field(30.0, gt=0.0, lt=120.0)
    volume_centre_depth_m: Length_m = Field(3.5, gt=0.0, le=100.0, description="cube centre, in front of the baseline")
    volume_edge_m: Length_m = Field(1.0, gt=0.0, le=20.0)


class CalibrationConfig(ConfigTable):
    rail_distance_m: Length_m = Field(3.0, gt=0.1, le=100.0)
    alpha_max_deg: Angle_deg = Field(14.0, gt=0.0, lt=60.0)
    alpha_step_deg: Angle_deg = Field(0.75, gt=0.0, le=10.0)
    beta_max_deg: Angle_deg = Field(14.0, gt=0.0, lt=60.0)
    rail_step_mm: Length_mm = Field(40.0, gt=0.0, le=1000.0)
    tracker_distance_m: Length_m = Field(2.0, ge=0.0, le=100.0)
    turntable_sigma_urad: FiniteFloat = Field(1.0, ge=0.0, le=1000.0)
    axis_offset_mm: list[Length_mm] = Field([0.0, 0.0, 0.3], description="turntable axis relative to the optical "
                                            "centre, each component within ±1e11 mm")
    n_scans: Integer = Field(20, ge=1, le=100_000)
    n_control_points: Integer = Field(30, ge=6, le=10_000)
    extrinsic_method: Literal["rotvec", "penalty"] = "rotvec"

    @field_validator("axis_offset_mm")
    @classmethod
    def _three(cls, v):
        if len(v) != 3:
            raise ValueError(f"expected 3 numbers (x, y, z), got {len(v)}")
        return v

    @model_validator(mode="after")
    def _enough_samples(self):
        n = (2 * self.alpha_max_deg / self.alpha_step_deg + 1) * (
            2 * self.rail_distance_m * np.tan(np.deg2rad(self.beta_max_deg)) / (self.rail_step_mm / 1e3) + 1)
        if n < 20:
            raise ValueError(f"alpha_step_deg: about {n:.0f} calibration samples (from alpha_max_deg, alpha_step_deg, "
                             "beta_max_deg, rail_distance_m, rail_step_mm); the RBF needs at least 20")
        if n > 6000:
            raise ValueError(f"alpha_step_deg: about {n:.0f} calibration samples (from alpha_max_deg, alpha_step_deg, "
                             "beta_max_deg, rail_distance_m, rail_step_mm); the dense RBF solve is limited to 6000")
        return self


class PointsConfig(ConfigTable):
    test_points_mm: list[list[Length_mm]] = Field(default_factory=lambda: [list(p) for p in TABLE1_MM],
                                                  max_length=100_000)
    n_random: Integer = Field(500, ge=0, le=100_000)
    n_scans: Integer = Field(20, ge=1, le=100_000)

    @field_validator("test_points_mm")
    @classmethod
    def _xyz(cls, v):
        if not v or any(len(p) != 3 for p in v):
            raise ValueError("expected a non-empty list of [X, Y, Z] points")
        return v


class AttitudeConfig(ConfigTable):
    poses_deg: list[list[Angle_deg]] = Field(default_factory=lambda: [list(p) for p in TABLE2_DEG] + [POSE_167_DEG],
                                             max_length=10_000)
    arm_mm: Length_mm = Field(500.0, gt=10.0, le=2000.0, description="|ab| = |bc|")
    abc_angle_deg: Angle_deg = Field(80.0, gt=5.0, lt=175.0, description="angle between the vectors ab and bc")
    n_trials: Integer = Field(20, ge=1, le=10_000)
    n_scans: Integer = Field(20, ge=1, le=100_000)

    @field_validator("poses_deg")
    @classmethod
    def _ypr(cls, v):
        if not v or any(len(p) != 3 for p in v):
            raise ValueError("expected a non-empty list of [yaw, roll, pitch] poses")
        return v


class DynamicConfig(ConfigTable):
    enabled: Flag = True
    duration_s: Duration_s = Field(6.0, gt=0.0, le=3600.0)
    frame_rate_hz: FiniteFloat = Field(40.0, gt=0.0, le=10_000.0)
    spin_rate_deg_s: FiniteFloat = Field(60.0, ge=0.0, le=3600.0, description="spin rate, at most 3600 deg/s")
    spin_axis: list[FiniteFloat] = Field([0.3, 0.5, 1.0])
    drift_mm_s: list[Speed_mm_s] = Field([20.0, -10.0, 10.0], description="drift velocity, each component within "
                                         "±1e7 mm/s")
    arm_mm: Length_mm = Field(400.0, gt=10.0, le=2000.0)
    accel_psd_m2_s3: FiniteFloat = Field(1.0, gt=0.0, le=1e6)
    overlap_px: FiniteFloat = Field(15.0, ge=0.0, le=1000.0)
    angle_sigma_urad: FiniteFloat = Field(3.0, gt=0.0, le=1e4)

    @field_validator("spin_axis", "drift_mm_s")
    @classmethod
    def _three(cls, v):
        if len(v) != 3:
            raise ValueError(f"expected 3 numbers, got {len(v)}")
        return v

    @field_validator("spin_axis")
    @classmethod
    def _nonzero(cls, v):
        if not math.hypot(*v) > 1e-12:
            raise ValueError("the spin axis must not be zero (norm above 1e-12)")
        return v

    @model_validator(mode="after")
    def _frames(self):
        n = self.duration_s * self.frame_rate_hz
        if n < 10:
            raise ValueError(f"duration_s: duration_s × frame_rate_hz = {n:.0f} frames; need at least 10")
        if n > 200_000:
            raise ValueError(f"duration_s: duration_s × frame_rate_hz = {n:.0f} frames; at most 200000")
        return self


class EnvelopeConfig(ConfigTable):
    """The ``envelope`` sweep cell: three-LED targets at positions of the measuring volume.

    At every (depth, lateral offset) the config's attitude poses are measured ``trials`` times with
    one calibration of the cell's rig (calibrated in the cube at ``rig.volume_centre_depth_m``).
    """

    depths_m: list[Length_m] = Field([2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0], min_length=1, max_length=200,
                                     description="target centre in front of the baseline (world y)")
    offsets_m: list[Length_m] = Field([0.0, 0.5, 1.0, 1.5, 2.0], min_length=1, max_length=200,
                                      description="target centre along the baseline from its middle (world x)")

    @field_validator("depths_m", "offsets_m")
    @classmethod
    def _distinct(cls, v):
        if len(set(v)) != len(v):
            raise ValueError(f"values are not distinct: {v!r}")
        return v

    @field_validator("depths_m")
    @classmethod
    def _in_front(cls, v):
        if min(v) <= 0.0:
            raise ValueError(f"depths must be positive (in front of the baseline), got {min(v)!r}")
        return v


class Config(ScenarioConfig):
    """``cylindrical_004`` config: 004 §4 rig, calibration, Table 1/2 analogues and the dynamic test."""

    kind: Literal["cylindrical_004"]
    seed: Seed = 0
    camera: CameraConfig = CameraConfig()
    rig: RigConfig = RigConfig()
    calibration: CalibrationConfig = CalibrationConfig()
    points: PointsConfig = PointsConfig()
    attitude: AttitudeConfig = AttitudeConfig()
    dynamic: DynamicConfig = DynamicConfig()
    envelope: EnvelopeConfig = EnvelopeConfig()
    sweep: SweepSpec | None = None
