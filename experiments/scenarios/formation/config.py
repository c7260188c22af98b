"""Configuration of the 003 scenario kind ``"formation"`` (validated by pydantic before any work).

A config file names ``kind = "formation"`` and the study to run with ``coobs run``:

``study = "closed_loop"``
    one scenario end to end (:mod:`closed_loop`): truth, observers, observation (rendered or
    geometric), triangulation, inter-frame association and registration, EKF;
``study = "error_map"``
    one cell of 003 Experiment A (Figs 5–6) at ``formation.distance_m`` / ``axis_angle_deg``;
``study = "ekf"``
    003 Experiments B–D (Figs 7–12): the EKF driven by synthetic measurements of a given error.

An optional ``[sweep]`` table (:class:`experiments.sweep.SweepSpec`) turns the same file into a
``coobs sweep`` over any of these keys.  Units are in the key names; angles in degrees at this edge.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from experiments.config import ConfigTable, ScenarioConfig
from experiments.sweep import SweepSpec
from vision.target import BUNDLED_MESHES, bundled_mesh_path

__all__ = [
    "Config",
    "TargetConfig",
    "SpacecraftConfig",
    "FormationConfig",
    "CameraConfig",
    "ObservationConfig",
    "EstimatorConfig",
    "TimeConfig",
    "ErrorMapConfig",
    "EkfStudyConfig",
    "REPO_ROOT",
]

#: repository root (mesh paths in configs may be relative to it)
REPO_ROOT = Path(__file__).resolve().parents[3]


def _vec(n: int, *, positive: bool = False):
    def check(v: list[float]) -> list[float]:
        if len(v) != n:
            raise ValueError(f"expected {n} numbers, got {len(v)}")
        if not all(np.isfinite(v)):
            raise ValueError("contains non-finite numbers")
        if positive and min(v) <= 0:
            raise ValueError("all entries must be > 0")
        return v

    return check


class TargetConfig(ConfigTable):
    """The tumbling target: model, inertia, initial attitude and rate."""

    model: str = Field("fy1", description='"fy1" (procedural FY-1-like), a bundled mesh ("topex", '
                       '"hubble") or a mesh file (OBJ, STL, PLY, ...)')
    mesh_unit_m: float = Field(1.0, gt=0, description="metres per mesh-file unit (bundled mesh: its own unit)")
    texture_seed: int = Field(0, ge=0, description="seed of the procedural textures and surface features")
    inertia_kg_m2: list[float] = Field([1000.0, 800.0, 600.0], description="principal moments (003 gives none: flag P003-14, docs/papers.md#p003-14)")
    q_NT0: list[float] = Field([1.0, 0.0, 0.0, 0.0], description="initial attitude (003 eq 34), [w, x, y, z]")
    omega_TN_T0_deg_s: list[float] = Field([5.0, 5.0, 5.0], description="initial body rate (003 eq 34, flag P003-13, docs/papers.md#p003-13)")

    _c_inertia = field_validator("inertia_kg_m2")(_vec(3, positive=True))
    _c_rate = field_validator("omega_TN_T0_deg_s")(_vec(3))

    @field_validator("q_NT0")
    @classmethod
    def _unit(cls, v: list[float]) -> list[float]:
        _vec(4)(v)
        n = float(np.linalg.norm(v))
        if abs(n - 1.0) > 1e-6:
            raise ValueError(f"must be a unit quaternion (norm {n:.6g})")
        return v

    @field_validator("inertia_kg_m2")
    @classmethod
    def _triangle(cls, v: list[float]) -> list[float]:
        a, b, c = sorted(v)
        if a + b < c * (1 - 1e-12):
            raise ValueError(f"principal moments {v} violate the triangle inequality (not a rigid body)")
        return v

    @model_validator(mode="before")
    @classmethod
    def _bundled_unit(cls, data: object) -> object:
        if isinstance(data, dict) and data.get("model") in BUNDLED_MESHES and "mesh_unit_m" not in data:
            return {**data, "mesh_unit_m": BUNDLED_MESHES[data["model"]].unit_m}
        return data

    @field_validator("model")
    @classmethod
    def _model_exists(cls, v: str) -> str:
        if v == "fy1" or v in BUNDLED_MESHES:
            return v
        p = Path(v)
        if not (p.is_file() or (REPO_ROOT / p).is_file()):
            raise ValueError(f"mesh file not found: {v}")
        return v

    def mesh_path(self) -> Path | None:
        """The mesh file of the model (``None`` for the procedural FY-1-like target)."""
        if self.model == "fy1":
            return None
        if self.model in BUNDLED_MESHES:
            return bundled_mesh_path(self.model)
        p = Path(self.model)
        return p if p.is_file() else REPO_ROOT / p


class SpacecraftConfig(ConfigTable):
    """A candidate observer on a Clohessy–Wiltshire orbit about the target (H frame at t = 0)."""

    name: str = Field(min_length=1)
    r_H_m: list[float]
    v_H_m_s: list[float] = [0.0, 0.0, 0.0]

    _c_r = field_validator("r_H_m")(_vec(3))
    _c_v = field_validator("v_H_m_s")(_vec(3))


class FormationConfig(ConfigTable):
    """Observers: a symmetric n-view cone (003 §3.1) or candidate spacecraft on CW orbits."""

    geometry: Literal["symmetric", "cw"] = "symmetric"
    n_views: int = Field(3, ge=1, le=12, description="symmetric geometry: number of cameras")
    distance_m: float = Field(50.0, gt=0, le=1000.0, description="symmetric geometry: range to the target")
    axis_angle_deg: float = Field(10.0, gt=0, le=120.0, description="angle between adjacent optical axes")
    spacecraft: list[SpacecraftConfig] = Field(default_factory=list, description="cw geometry: candidates")
    orbit_altitude_km: float = Field(870.0, gt=150.0, lt=40000.0, description="target's circular orbit")
    max_active: int = Field(3, ge=2, le=12, description="observers used at once (selection)")
    min_active: int = Field(2, ge=2, le=12, description="fallback set size when no max_active set qualifies")
    d_min_lambda: float = Field(1.1, gt=0, le=10.0, description="λ of 003 eq (1) (flag P003-1, docs/papers.md#p003-1, suggests 1.1)")
    d_max_m: float = Field(150.0, gt=0, description="maximum useful range (003 §1.2)")
    max_pointing_deg: float = Field(5.0, gt=0, le=90.0, description="boresight-to-target angle limit")
    axis_angle_min_deg: float = Field(5.0, ge=0, le=180.0, description="pairwise optical-axis angle window")
    axis_angle_max_deg: float = Field(30.0, gt=0, le=180.0)
    max_comm_range_m: float = Field(1000.0, gt=0, description="inter-spacecraft communication range")
    sun_exclusion_deg: float = Field(30.0, ge=0, le=180.0, description="smallest boresight-Sun angle")
    keep_out_radius_m: float = Field(20.0, ge=0, description="keep-out sphere about the target")
    reconfigure: bool = Field(True, description="cw geometry: plan a minimum-fuel reconfiguration when "
                                                "no set qualifies")
    reconfiguration_time_s: float = Field(600.0, gt=0, description="transfer time of a reconfiguration")
    dv_max_m_s: float = Field(1.0, gt=0, description="largest single impulse")

    @model_validator(mode="after")
    def _geometry(self) -> FormationConfig:
        if self.geometry == "symmetric" and self.n_views > 1:
            lim = 360.0 / self.n_views
            if self.axis_angle_deg > lim:
                raise ValueError(f"axis_angle_deg: {self.axis_angle_deg} deg is impossible for "
                                 f"{self.n_views} views on a cone (at most {lim:.6g} deg)")
        if self.geometry == "cw" and len(self.spacecraft) < 2:
            raise ValueError("spacecraft: the cw geometry needs at least 2 candidate spacecraft")
        if self.min_active > self.max_active:
            raise ValueError(f"min_active: {self.min_active} exceeds max_active {self.max_active}")
        if self.axis_angle_min_deg > self.axis_angle_max_deg:
            raise ValueError(f"axis_angle_min_deg: {self.axis_angle_min_deg} exceeds axis_angle_max_deg "
                             f"{self.axis_angle_max_deg}")
        names = [s.name for s in self.spacecraft]
        if len(set(names)) != len(names):
            raise ValueError("spacecraft: names must be unique")
        return self


class CameraConfig(ConfigTable):
    """Identical pinhole cameras, one per observer (003 gives no intrinsics; a 20° field of view keeps
    003 eq (1) at 30 m for a 5 m target)."""

    width_px: int = Field(1024, ge=64, le=8192)
    height_px: int = Field(1024, ge=64, le=8192)
    fov_deg: float = Field(20.0, gt=0.5, lt=120.0)


class ObservationConfig(ConfigTable):
    """How the cameras see the target."""

    mode: Literal["rendered", "geometric"] = "geometric"
    pixel_sigma_px: float = Field(0.5, gt=0, le=10.0, description="feature localisation noise σ")
    false_match_fraction: float = Field(
        0.02, ge=0, lt=1.0, description="geometric mode: false-match fraction (vision calibrated 0.02 against the rendered mode)")
    n_features: int = Field(2000, ge=10, le=100000, description="geometric mode: surface features")
    sun_H: list[float] = Field([1.0, -0.5, 0.6], description="rendered mode: direction to the Sun (H)")
    detector: Literal["sift", "orb", "akaze", "surf"] = "sift"

    _c_sun = field_validator("sun_H")(_vec(3))


class EstimatorConfig(ConfigTable):
    """Registration and filter settings."""

    registration: Literal["kabsch", "ransac", "ml"] = Field(
        "kabsch", description="kabsch: 003 eq (11)-(13) weighted; ransac: + 3-point RANSAC; ml: covariance-aware")
    filter: Literal["ekf", "mekf"] = "ekf"
    sigma_q: float = Field(0.1, gt=0, le=1.0, description="003 eq (35) initial quaternion σ per component")
    sigma_omega_deg_s: float = Field(0.1, gt=0, le=90.0, description="003 eq (35) initial rate σ")
    initial_attitude_known: bool = Field(
        True, description="closed loop: the body frame is defined by the first frame (flag P003-14a, docs/papers.md#p003-14a), so the "
                          "filter starts at q_NT0 with sigma_q_known; else from 003 eq (35)")
    sigma_q_known: float = Field(1e-4, gt=0, le=1.0, description="initial quaternion sigma when known")
    convergence_attitude_deg: float = Field(0.5, gt=0, description="convergence threshold (003 gives none: flag P003-15, docs/papers.md#p003-15)")
    convergence_rate_deg_s: float = Field(0.05, gt=0)
    convergence_hold_s: float = Field(10.0, ge=0)


class TimeConfig(ConfigTable):
    """Epochs ``t = 0, dt, …, duration``."""

    dt_s: float = Field(0.1, gt=0, le=600.0)
    duration_s: float = Field(60.0, gt=0, le=86400.0 * 2)

    @model_validator(mode="after")
    def _steps(self) -> TimeConfig:
        n = self.duration_s / self.dt_s
        if n < 1:
            raise ValueError(f"duration_s: {self.duration_s} is shorter than dt_s {self.dt_s}")
        if n > 200_000:
            raise ValueError(f"duration_s: {n:.0f} epochs is too many (at most 200000)")
        return self

    def epochs(self) -> np.ndarray:
        """Epochs ``(T,)``, s: ``0, dt_s, …`` up to ``duration_s``."""
        n = int(np.floor(self.duration_s / self.dt_s + 1e-9))
        return self.dt_s * np.arange(n + 1)


class ErrorMapConfig(ConfigTable):
    """003 Experiment A: random initial attitudes, each followed by equal attitude steps."""

    steps: int = Field(10, ge=1, le=1000, description="attitude steps after each initial attitude")
    step_deg: list[float] = Field([0.5, 0.5, 0.5], description="commanded increment Δθ (H frame rotation vector)")
    filter_runs: int = Field(0, ge=0, le=10000,
                             description="> 0: also run the EKF driven by this cell's measured error")
    filter_error: Literal["step_rms", "e_dtheta"] = Field(
        "step_rms", description="the cell statistic used as the filter's measurement error (median over trials)")

    _c_step = field_validator("step_deg")(_vec(3))


class EkfStudyConfig(ConfigTable):
    """003 Experiments B–D: the EKF on synthetic attitude measurements."""

    runs: int = Field(100, ge=1, le=100000, description="Monte Carlo runs per case (003: 100)")
    angle_error_deg: float = Field(0.2, ge=0, le=45.0, description="measurement error of a single case / sweep cell")
    cases_deg: list[float] = Field([0.2, 0.6], description="Experiments B-C: measurement errors")
    windows_deg: dict[str, list[float]] = Field(
        {"3 views": [0.025, 0.35], "2 views": [0.03, 0.85]},
        description="Experiment D: per-run error drawn uniformly from [lo, hi]")
    measurement: Literal["absolute", "increment", "chained_absolute"] = "absolute"
    typical_runs: int = Field(10, ge=1, le=1000, description="runs drawn in Figs 7-12 (003: 10)")

    @field_validator("cases_deg")
    @classmethod
    def _cases(cls, v: list[float]) -> list[float]:
        if any((not np.isfinite(x)) or x < 0 or x > 45 for x in v):
            raise ValueError(f"each error must be in [0, 45] deg, got {v}")
        return v

    @field_validator("windows_deg")
    @classmethod
    def _windows(cls, v: dict[str, list[float]]) -> dict[str, list[float]]:
        for name, w in v.items():
            if len(w) != 2 or not (0 <= w[0] <= w[1] <= 45):
                raise ValueError(f"{name}: need [lo, hi] with 0 <= lo <= hi <= 45 deg, got {w}")
        return v


class Config(ScenarioConfig):
    """A ``kind = "formation"`` config (003: multi-view cooperative observation)."""

    kind: Literal["formation"]
    study: Literal["closed_loop", "error_map", "ekf"] = "closed_loop"
    title: str = ""
    seed: int = Field(0, ge=0)
    trials: int = Field(1, ge=1, le=100000, description="coobs run: trials of error_map / closed_loop")
    target: TargetConfig = TargetConfig()
    formation: FormationConfig = FormationConfig()
    camera: CameraConfig = CameraConfig()
    observation: ObservationConfig = ObservationConfig()
    estimator: EstimatorConfig = EstimatorConfig()
    time: TimeConfig = TimeConfig()
    error_map: ErrorMapConfig = ErrorMapConfig()
    ekf: EkfStudyConfig = EkfStudyConfig()
    sweep: SweepSpec | None = None

    @model_validator(mode="after")
    def _consistent(self) -> Config:
        if self.sweep is not None:
            self._check_grid_values()
        hold = self.estimator.convergence_hold_s
        if self.study in ("ekf", "closed_loop") and hold > self.time.duration_s:
            raise ValueError(f"estimator.convergence_hold_s: {hold} s exceeds time.duration_s "
                             f"{self.time.duration_s}")
        return self

    def _check_grid_values(self) -> None:
        """Each swept value must give a valid config on its own (combinations are checked by the sweep)."""
        import copy

        from pydantic import ValidationError

        base = self.model_dump(exclude={"sweep"})
        for key, values in self.sweep.grid_values().items():
            for v in values:
                raw = copy.deepcopy(base)
                node = raw
                parts = key.split(".")
                for p in parts[:-1]:
                    if not isinstance(node.get(p), dict):
                        raise ValueError(f"sweep.grid: {key!r} is not a config key")
                    node = node[p]
                if parts[-1] not in node:
                    raise ValueError(f"sweep.grid: {key!r} is not a config key")
                node[parts[-1]] = v
                try:
                    type(self).model_validate(raw)
                except ValidationError as exc:
                    err = exc.errors()[0]
                    raise ValueError(f"sweep.grid: {key} = {v!r}: {err['msg']}") from None

    def inertia(self) -> np.ndarray:
        """Target inertia tensor (3, 3), kg·m²."""
        return np.diag(self.target.inertia_kg_m2)

    def omega0_rad_s(self) -> np.ndarray:
        """Initial body rate ``(3,)``, rad/s."""
        return np.deg2rad(np.asarray(self.target.omega_TN_T0_deg_s, dtype=float))
