"""The ``rodrigues_001`` config: 001 Table 1 (orbits and attitudes), camera, target, simulation, solver and
comparison options; the ``envelope`` study (one point of the working envelope, static random attitudes) and
an optional ``[sweep]`` table (:class:`experiments.sweep.SweepSpec`) over any of these keys.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from attitude.euler import matrix_from_euler
from attitude.quaternion import (
    quat_from_matrix,
    quat_from_rotvec,
    quat_multiply,
)
from experiments.config import (
    Angle_deg,
    ConfigTable,
    Duration_s,
    FiniteFloat,
    Flag,
    Integer,
    Length_km,
    Length_m,
    Rate_deg_s,
    ScenarioConfig,
    Seed,
)
from experiments.sweep import SweepSpec
from orbits.scenario_001 import Table1Orbit
from orbits.two_body import R_EARTH_M

__all__ = ["Config", "SpacecraftConfig", "CameraConfig", "TargetConfig", "SimulationConfig", "SolverConfig",
           "ComparisonConfig", "EnvelopeConfig"]


class SpacecraftConfig(ConfigTable):
    """One column of 001 Table 1: orbit and attitude (angles in the 3-2-1 reading, rates about body axes)."""

    a_km: Length_km = Field(6721.2, gt=R_EARTH_M / 1e3, description="semi-major axis, at most 1e5 km")
    e: FiniteFloat = Field(0.0, ge=0.0, lt=1.0)
    i_deg: Angle_deg = Field(42.225, ge=0.0, le=180.0)
    raan_deg: Angle_deg = Field(0.0, ge=-360.0, le=360.0)
    argp_deg: Angle_deg = Field(0.0, ge=-360.0, le=360.0)
    t_node_s: Duration_s = Field(0.0, description="time of ascending-node passage, within ±1e7 s")
    roll_deg: Angle_deg = Field(0.0, ge=-180.0, le=180.0)
    pitch_deg: Angle_deg = Field(0.0, ge=-90.0, le=90.0)
    yaw_deg: Angle_deg = Field(0.0, ge=-180.0, le=180.0)
    roll_rate_deg_s: Rate_deg_s = Field(0.0, ge=-10.0, le=10.0)
    pitch_rate_deg_s: Rate_deg_s = Field(0.0, ge=-10.0, le=10.0)
    yaw_rate_deg_s: Rate_deg_s = Field(0.0, ge=-10.0, le=10.0)

    @model_validator(mode="after")
    def _perigee_above_earth(self):
        if self.a_km * (1.0 - self.e) * 1e3 <= R_EARTH_M:
            raise ValueError(f"a_km: perigee radius a_km*(1-e) = {self.a_km * (1 - self.e):.1f} km is inside the Earth")
        return self

    def orbit(self) -> Table1Orbit:
        return Table1Orbit(a_m=self.a_km * 1e3, e=self.e, i_rad=float(np.radians(self.i_deg)),
                           raan_rad=float(np.radians(self.raan_deg)), argp_rad=float(np.radians(self.argp_deg)),
                           t_node_s=self.t_node_s)

    def q_OB(self, t_s: np.ndarray) -> np.ndarray:
        """Body attitude relative to O, ``(T, 4)``: ``q_OB(0) ⊗ exp(½ ω_B t)`` (constant body rates)."""
        q0 = quat_from_matrix(matrix_from_euler(np.radians([self.yaw_deg, self.pitch_deg, self.roll_deg]), "321"))
        w = np.radians([self.roll_rate_deg_s, self.pitch_rate_deg_s, self.yaw_rate_deg_s])
        return quat_multiply(q0, quat_from_rotvec(t_s[:, None] * w))


class CameraConfig(ConfigTable):
    focal_length_mm: FiniteFloat = Field(200.0, gt=0.0, le=10_000.0)
    pixel_size_um: FiniteFloat = Field(7.0, gt=0.0, le=1000.0)
    width_px: Integer = Field(2048, ge=16, le=100_000)
    height_px: Integer = Field(2048, ge=16, le=100_000)
    noise_px: FiniteFloat = Field(1.0, ge=0.0, le=100.0, description="white noise, 1 sigma per image coordinate")


class TargetConfig(ConfigTable):
    cube_edge_m: Length_m = Field(2.0, gt=0.0, le=100.0)


class SimulationConfig(ConfigTable):
    duration_s: Duration_s = Field(6000.0, gt=0.0, le=1e6)
    step_s: Duration_s = Field(5.0, gt=0.0, description="time step, at most 1e7 s")

    @model_validator(mode="after")
    def _step_fits(self):
        if self.step_s > self.duration_s:
            raise ValueError(f"step_s: {self.step_s:g} s is longer than duration_s = {self.duration_s:g} s")
        return self


class SolverConfig(ConfigTable):
    eps_attitude: FiniteFloat = Field(1e-8, gt=0.0, lt=1.0, description="epsilon_1 on |dg|")
    eps_translation_m: Length_m = Field(1e-5, gt=0.0, lt=10.0, description="epsilon_2 on |dt|")
    max_iterations: Integer = Field(50, ge=1, le=1000)
    eta: FiniteFloat = Field(0.0, ge=0.0, le=1.0, description="switching hysteresis")
    initial_attitude_error_deg: Angle_deg = Field(1.0, ge=0.0, le=60.0)
    initial_position_error_m: Length_m = Field(1.0, ge=0.0, le=50.0)


class ComparisonConfig(ConfigTable):
    opencv: Flag = True
    pycolmap: Flag = True


class EnvelopeConfig(ConfigTable):
    """One point of the working envelope (the ``envelope`` study and its sweep cell).

    The cube (``target_model.cube_edge_m``) sits on the boresight at ``range_m`` in a uniformly random
    static attitude per trial, seen by ``[camera]`` with ``camera.noise_px``; every solver gets the same
    frame.  The local solvers (ours, OpenCV iterative) start from the truth turned by
    ``initial_attitude_error_deg`` about a random axis and moved by ``initial_position_error_frac``
    times the range in a random direction (a tracker's previous epoch); SQPnP needs no guess.
    """

    range_m: Length_m = Field(100.0, ge=1.0, le=100_000.0, description="distance camera to target centre")
    trials: Integer = Field(200, ge=1, le=1_000_000, description="random attitudes of the envelope study")
    initial_attitude_error_deg: Angle_deg = Field(5.0, ge=0.0, le=60.0)
    initial_position_error_frac: FiniteFloat = Field(0.02, ge=0.0, le=0.5, description="fraction of range_m")


class Config(ScenarioConfig):
    """``rodrigues_001`` config: 001 Table 1 and the camera, target, solver and comparison options.

    ``study = "table1"`` (default) is the 6000 s scenario of the paper; ``"envelope"`` one point of the
    working envelope (:class:`EnvelopeConfig`), the cell of ``coobs sweep``.
    """

    kind: Literal["rodrigues_001"]
    study: Literal["table1", "envelope"] = "table1"
    seed: Seed = 1
    chaser: SpacecraftConfig = SpacecraftConfig(e=1e-7, i_deg=42.225005, t_node_s=0.013, roll_deg=0.1, pitch_deg=0.1,
                                                yaw_deg=0.1, roll_rate_deg_s=1e-4, pitch_rate_deg_s=1e-4,
                                                yaw_rate_deg_s=1e-4)
    target: SpacecraftConfig = SpacecraftConfig(roll_deg=2.0, pitch_deg=2.0, yaw_deg=2.0, roll_rate_deg_s=1e-3,
                                                pitch_rate_deg_s=1e-3, yaw_rate_deg_s=0.08)
    camera: CameraConfig = CameraConfig()
    target_model: TargetConfig = TargetConfig()
    simulation: SimulationConfig = SimulationConfig()
    solver: SolverConfig = SolverConfig()
    comparison: ComparisonConfig = ComparisonConfig()
    envelope: EnvelopeConfig = EnvelopeConfig()
    sweep: SweepSpec | None = None

    @model_validator(mode="after")
    def _grid_keys(self):
        """Each swept key must be a config key and each swept value valid on its own."""
        self.check_swept_values()
        return self
