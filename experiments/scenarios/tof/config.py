"""The ``tof_000`` config: camera, target pose, pipeline options and the optional sweep and matching studies."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from experiments.config import (
    Angle_deg,
    ConfigTable,
    FiniteFloat,
    Integer,
    Length_m,
    ScenarioConfig,
    Seed,
)
from experiments.sweep import SweepSpec

__all__ = ["Config", "MATCHING_CASES", "MATCHERS", "CameraConfig", "TargetConfig", "StaticConfig", "SweepConfig",
           "MatchingConfig", "PipelineConfig"]

#: matching cases: name → keyword arguments of :func:`chaser.tof.random_matching_trials`
MATCHING_CASES = {
    "all_visible": dict(),
    "one_missing": dict(n_missing=1),
    "one_spurious_volume": dict(n_spurious=1, spurious="volume"),
    "one_spurious_plate": dict(n_spurious=1, spurious="plate"),
    "missing_and_spurious": dict(n_missing=1, n_spurious=1, spurious="volume"),
}
MATCHERS = ("mrf", "mrf-literal", "mrf-sinkhorn", "mrf-quadratic", "hungarian")
#: range estimators of the key points
Estimator = Literal["plane", "mean"]


class CameraConfig(ConfigTable):
    """The SR4000 TOF camera: ambient light and supersampling of the renderer."""

    model: Literal["sr4000"] = "sr4000"
    ambient_dn: FiniteFloat = Field(0.0, ge=0.0, le=1e6, description="ambient light per pixel (DN)")
    supersample: Integer = Field(3, ge=1, le=6, description="sub-rays per pixel and axis")


class TargetConfig(ConfigTable):
    """Pose of the marker plate in the camera frame, and its mount."""

    distance_m: Length_m = Field(0.7, description="plate origin on the boresight at this z (m)")
    attitude_deg: tuple[Angle_deg, Angle_deg, Angle_deg] = Field((0.0, 0.0, 0.0), description="pitch, yaw, roll (3-2-1)")
    off_boresight_deg: Angle_deg = Field(0.0, ge=0.0, le=75.0,
                                         description="envelope cell: extra tilt of the plate normal off the boresight, "
                                                     "about a random axis in the image plane per frame")
    lateral_offset_m: tuple[Length_m, Length_m] = (0.0, 0.0)
    standoff_m: Length_m = Field(0.05, ge=0.0, le=1.0)
    body_reflectivity: FiniteFloat = Field(0.3, ge=0.0, le=1.0)

    @field_validator("distance_m")
    @classmethod
    def _fits(cls, v: float) -> float:
        # inside the 5.0 m unambiguous range; below 0.45 m the 0.30 m plate overfills the 38.8 deg
        # undistorted field of view (markers leave it: the envelope sweep's near edge)
        if not 0.3 <= v <= 4.5:
            raise ValueError("must lie in [0.3, 4.5] m (plate centre in the SR4000 field of view, inside its range)")
        return v

    @field_validator("attitude_deg")
    @classmethod
    def _angles(cls, v):
        if any(abs(a) > 75.0 for a in v):
            raise ValueError("each angle must lie in [-75, 75] deg (plate facing the camera)")
        return v


class StaticConfig(ConfigTable):
    """The static repeatability study (000 Table 1): frames of a held target."""

    frames: Integer = Field(200, ge=2, le=100_000)


class SweepConfig(ConfigTable):
    """The attitude sweep: one Euler angle offset at a time."""

    axes: list[Literal["pitch", "yaw", "roll"]] = ["pitch", "yaw", "roll"]
    angles_deg: list[Angle_deg] = Field([-60.0, -45.0, -30.0, -15.0, 0.0, 15.0, 30.0, 45.0, 60.0], max_length=1000)
    frames_per_angle: Integer = Field(5, ge=1, le=10_000)

    @field_validator("angles_deg")
    @classmethod
    def _angles(cls, v):
        if not v or any(abs(a) > 75.0 for a in v):
            raise ValueError("needs at least one angle, each in [-75, 75] deg")
        return v


class MatchingConfig(ConfigTable):
    """The matching Monte Carlo: random matching problems per case and matcher."""

    trials: Integer = Field(1000, ge=1, le=1_000_000)
    noise_m: Length_m = Field(0.002, ge=0.0, le=0.05, description="isotropic 3-D point noise (1 sigma)")
    cases: list[Literal[tuple(MATCHING_CASES)]] = list(MATCHING_CASES)
    matchers: list[Literal[MATCHERS]] = ["mrf", "mrf-literal", "hungarian"]


class PipelineConfig(ConfigTable):
    """The pose pipeline: matcher, thresholds, range estimators, weighting."""

    matcher: Literal["mrf", "mrf-sinkhorn", "mrf-literal", "hungarian"] = "mrf"
    alpha_m: Length_m = Field(0.010, gt=0.0, le=0.2, description="distance-consistency threshold alpha")
    gate_factor: FiniteFloat = Field(2.0, gt=0.0, le=20.0, description="verification gate in units of alpha")
    range_estimators: list[Estimator] = ["plane", "mean"]
    weighting: Literal["inverse_variance", "uniform"] = "inverse_variance"
    pose_estimator: Literal["ml", "svd"] = Field("ml", description="ML refinement of the weighted SVD on the key points' "
                                                                  "pixels and ranges, or the weighted SVD (000 eqs 27-38) alone")
    centre_estimator: Literal["fit", "centroid"] = Field("fit", description="dot centre: fit of the dot's image model or "
                                                                           "the contrast-weighted centroid (000 eqs 9-11)")

    @field_validator("range_estimators")
    @classmethod
    def _nonempty(cls, v):
        if not v or len(set(v)) != len(v):
            raise ValueError("needs one or more distinct estimators")
        return v


class Config(ScenarioConfig):
    """The whole ``tof_000`` config."""

    kind: Literal["tof_000"]
    title: str = Field("000 TOF cooperative-marker pose", max_length=200)
    seed: Seed = 0
    camera: CameraConfig = CameraConfig()
    target: TargetConfig = TargetConfig()
    pipeline: PipelineConfig = PipelineConfig()
    static: StaticConfig = StaticConfig()
    sweep: SweepConfig | SweepSpec | None = Field(None, description="the attitude-sweep study of coobs run, or the "
                                                                    "grid of coobs sweep (cell, trials, grid)")
    matching: MatchingConfig | None = None

    @model_validator(mode="after")
    def _fov(self):
        half = self.target.distance_m * np.tan(np.arctan(88.0 / 250.0))
        if max(abs(o) for o in self.target.lateral_offset_m) + (0.15 if self.target.distance_m >= 0.45 else 0.0) > half:
            raise ValueError("target.lateral_offset_m: the plate leaves the field of view at this distance")
        return self
