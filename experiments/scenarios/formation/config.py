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

import functools
import math
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from experiments.config import (
    Angle_deg,
    ConfigTable,
    Duration_s,
    FiniteFloat,
    Flag,
    Inertia_kg_m2,
    Integer,
    Length_m,
    Rate_deg_s,
    ScenarioConfig,
    Seed,
    Speed_m_s,
    shorten,
)
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
    "MESH_SUFFIXES",
    "MAX_MESH_PATH_CHARS",
]

#: repository root (mesh paths in configs may be relative to it)
REPO_ROOT = Path(__file__).resolve().parents[3]
#: mesh file formats a target model may name (those :func:`vision.target.load_mesh` reads)
MESH_SUFFIXES = (".obj", ".stl", ".ply", ".gltf", ".glb", ".off")
#: longest mesh path, characters
MAX_MESH_PATH_CHARS = 1024


def _vec(n: int, *, positive: bool = False):
    def check(v: list[float]) -> list[float]:
        if len(v) != n:
            raise ValueError(f"expected {n} numbers, got {len(v)}")
        if positive and min(v) <= 0:
            raise ValueError("all entries must be > 0")
        return v

    return check


@functools.lru_cache(maxsize=16)
def _mesh_triangles(path: str, size: int, mtime_ns: int) -> int:
    """Triangles Open3D reads from a mesh file (cached by path, size and modification time)."""
    import open3d as o3d

    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        mesh = o3d.io.read_triangle_mesh(path, enable_post_processing=False)
    return len(mesh.triangles) if len(mesh.vertices) >= 3 else 0


def _check_mesh_file(v: str) -> Path:
    """A mesh file named by a target model: a known format, readable, with triangles; ``ValueError`` otherwise."""
    p = Path(v)
    if p.suffix.lower() not in MESH_SUFFIXES:
        raise ValueError(f"{shorten(v)} is neither 'fy1', a bundled mesh {tuple(sorted(BUNDLED_MESHES))} nor a mesh "
                         f"file ({', '.join(MESH_SUFFIXES)})")
    try:
        if not p.is_file():
            p = REPO_ROOT / p
        if not p.is_file():
            raise ValueError(f"mesh file not found: {shorten(v)}")
        st = p.stat()
        with p.open("rb") as f:
            f.read(1)
    except OSError as exc:
        raise ValueError(f"mesh file {shorten(v)} cannot be read ({exc.strerror or type(exc).__name__})") from None
    if _mesh_triangles(str(p), st.st_size, st.st_mtime_ns) == 0:
        raise ValueError(f"mesh file {shorten(v)} has no triangles that Open3D can read")
    return p


class TargetConfig(ConfigTable):
    """The tumbling target: model, inertia, initial attitude and rate."""

    model: str = Field("fy1", min_length=1, max_length=MAX_MESH_PATH_CHARS,
                       description='"fy1" (procedural FY-1-like), a bundled mesh ("topex", "hubble") or a '
                       'mesh file (OBJ, STL, PLY, glTF/GLB, OFF) with triangles, read at validation')
    mesh_unit_m: FiniteFloat = Field(1.0, gt=0, le=1e3, description="metres per mesh-file unit (bundled mesh: "
                                     "its own unit), at most 1 km")
    texture_seed: Seed = Field(0, description="seed of the procedural textures and surface features")
    inertia_kg_m2: list[Inertia_kg_m2] = Field([1000.0, 800.0, 600.0], description="principal moments, each at "
                                               "most 1e12 kg m^2 (003 gives none: flag P003-14, docs/papers.md#p003-14)")
    q_NT0: list[FiniteFloat] = Field([1.0, 0.0, 0.0, 0.0], description="initial attitude (003 eq 34), [w, x, y, z]")
    omega_TN_T0_deg_s: list[Rate_deg_s] = Field([5.0, 5.0, 5.0], description="initial body rate, each component "
                                                "within ±1e3 deg/s (003 eq 34, flag P003-13, docs/papers.md#p003-13)")

    inertia_tensor_kg_m2: list[list[FiniteFloat]] | None = Field(
        None, description="full 3x3 inertia tensor in the body frame (the first frame's, not the principal one); "
                          "replaces inertia_kg_m2 when given")

    _c_inertia = field_validator("inertia_kg_m2")(_vec(3, positive=True))

    @field_validator("inertia_tensor_kg_m2")
    @classmethod
    def _tensor(cls, v: list[list[float]] | None) -> list[list[float]] | None:
        if v is None:
            return v
        J = np.asarray(v, dtype=float)
        if J.shape != (3, 3):
            raise ValueError(f"expected a 3x3 matrix, got shape {J.shape}")
        if not np.allclose(J, J.T, rtol=1e-9, atol=1e-9 * np.abs(J).max()):
            raise ValueError("must be symmetric")
        m = np.linalg.eigvalsh(J)
        if m[0] <= 0 or np.abs(J).max() > 1e12:
            raise ValueError(f"must be positive definite with entries at most 1e12 (eigenvalues {shorten(m.tolist())})")
        if m[0] + m[1] < m[2] * (1 - 1e-12):
            raise ValueError(f"principal moments {shorten(m.tolist())} violate the triangle inequality")
        return v
    _c_rate = field_validator("omega_TN_T0_deg_s")(_vec(3))

    @field_validator("q_NT0")
    @classmethod
    def _unit(cls, v: list[float]) -> list[float]:
        _vec(4)(v)
        n = math.hypot(*v)
        if abs(n - 1.0) > 1e-6:
            raise ValueError(f"must be a unit quaternion (norm {n:.6g})")
        return v

    @field_validator("inertia_kg_m2")
    @classmethod
    def _triangle(cls, v: list[float]) -> list[float]:
        a, b, c = sorted(v)
        if a + b < c * (1 - 1e-12):
            raise ValueError(f"principal moments {shorten(v)} violate the triangle inequality (not a rigid body)")
        return v

    @model_validator(mode="before")
    @classmethod
    def _bundled_unit(cls, data: object) -> object:
        if (isinstance(data, dict) and isinstance(data.get("model"), str) and data["model"] in BUNDLED_MESHES
                and "mesh_unit_m" not in data):
            return {**data, "mesh_unit_m": BUNDLED_MESHES[data["model"]].unit_m}
        return data

    @field_validator("model")
    @classmethod
    def _model_exists(cls, v: str) -> str:
        if v == "fy1" or v in BUNDLED_MESHES:
            return v
        _check_mesh_file(v)
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

    name: str = Field(min_length=1, max_length=64)
    r_H_m: list[Length_m] = Field(description="position, each component within ±1e8 m")
    v_H_m_s: list[Speed_m_s] = Field([0.0, 0.0, 0.0], description="velocity, each component within ±1e4 m/s")

    _c_r = field_validator("r_H_m")(_vec(3))
    _c_v = field_validator("v_H_m_s")(_vec(3))


class FormationConfig(ConfigTable):
    """Observers: a symmetric n-view cone (003 §3.1) or candidate spacecraft on CW orbits."""

    geometry: Literal["symmetric", "cw"] = "symmetric"
    n_views: Integer = Field(3, ge=1, le=12, description="symmetric geometry: number of cameras")
    distance_m: Length_m = Field(50.0, gt=0, le=1000.0, description="symmetric geometry: range to the target")
    axis_angle_deg: Angle_deg = Field(10.0, gt=0, le=120.0, description="angle between adjacent optical axes")
    spacecraft: list[SpacecraftConfig] = Field(default_factory=list, max_length=64,
                                               description="cw geometry: candidates (at most 64)")
    orbit_altitude_km: FiniteFloat = Field(870.0, gt=150.0, lt=40000.0, description="target's circular orbit")
    max_active: Integer = Field(3, ge=2, le=12, description="observers used at once (selection)")
    min_active: Integer = Field(2, ge=2, le=12, description="fallback set size when no max_active set qualifies")
    d_min_lambda: FiniteFloat = Field(1.1, gt=0, le=10.0, description="λ of 003 eq (1) (flag P003-1, docs/papers.md#p003-1, suggests 1.1)")
    d_max_m: Length_m = Field(150.0, gt=0, description="maximum useful range (003 §1.2), at most 1e8 m")
    max_pointing_deg: Angle_deg = Field(5.0, gt=0, le=90.0, description="boresight-to-target angle limit")
    axis_angle_min_deg: Angle_deg = Field(5.0, ge=0, le=180.0, description="pairwise optical-axis angle window")
    axis_angle_max_deg: Angle_deg = Field(30.0, gt=0, le=180.0)
    max_comm_range_m: Length_m = Field(1000.0, gt=0, description="inter-spacecraft communication range, at most 1e8 m")
    sun_exclusion_deg: Angle_deg = Field(30.0, ge=0, le=180.0, description="smallest boresight-Sun angle")
    keep_out_radius_m: Length_m = Field(20.0, ge=0, description="keep-out sphere about the target, at most 1e8 m")
    reconfigure: Flag = Field(True, description="cw geometry: plan a minimum-fuel reconfiguration when "
                                                "no set qualifies")
    reconfiguration_time_s: Duration_s = Field(600.0, gt=0, description="transfer time of a reconfiguration, "
                                               "at most 1e7 s")
    dv_max_m_s: Speed_m_s = Field(1.0, gt=0, description="largest single impulse, at most 1e4 m/s")

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

    width_px: Integer = Field(1024, ge=64, le=8192)
    height_px: Integer = Field(1024, ge=64, le=8192)
    fov_deg: Angle_deg = Field(20.0, gt=0.5, lt=120.0)


class ObservationConfig(ConfigTable):
    """How the cameras see the target."""

    mode: Literal["rendered", "geometric"] = "geometric"
    pixel_sigma_px: FiniteFloat = Field(0.5, gt=0, le=10.0, description="feature localisation noise σ")
    false_match_fraction: FiniteFloat = Field(
        0.02, ge=0, lt=1.0, description="geometric mode: false-match fraction (vision calibrated 0.02 against the rendered mode)")
    n_features: Integer = Field(2000, ge=10, le=100000, description="geometric mode: surface features")
    sun_H: list[FiniteFloat] = Field([1.0, -0.5, 0.6], description="rendered mode: direction to the Sun (H), "
                                     "not zero")
    detector: Literal["sift", "orb", "akaze", "surf"] = "sift"
    noise_model: Literal["fixed", "calibrated"] = Field(
        "fixed", description="fixed: pixel_sigma_px (and false_match_fraction) as given; calibrated: as measured on "
        "rendered images by 'coobs calibrate' (rendered: sigma per keypoint from its SIFT size; geometric: also "
        "detection, match/association survival and false rates)")
    earth_background: Flag = Field(
        False, description="rendered mode: the Earth (seeded procedural ocean, land and clouds lit by the Sun; "
        "vision.earth) behind the target where the cameras look down at it, and its albedo light on the target")
    earth_albedo: FiniteFloat = Field(0.3, ge=0, le=1.0, description="rendered mode with earth_background: the "
                                      "Earth's mean albedo (its light on the target and the texture's scale)")
    glints: Flag = Field(False, description="rendered mode: sharp, saturating specular glints on MLI and solar "
                         "cells (vision.glints) instead of the targets' mild specular term")

    _c_sun = field_validator("sun_H")(_vec(3))

    @field_validator("sun_H")
    @classmethod
    def _nonzero(cls, v: list[float]) -> list[float]:
        if not math.hypot(*v) > 1e-12:
            raise ValueError("the direction to the Sun must not be zero (norm above 1e-12)")
        return v

    @model_validator(mode="after")
    def _rendered_only(self) -> ObservationConfig:
        for key in ("earth_background", "glints"):
            if getattr(self, key) and self.mode != "rendered":
                raise ValueError(f"{key}: true needs mode = 'rendered' (the {self.mode} mode draws no images), "
                                 f"got mode {self.mode!r}")
        return self


class EstimatorConfig(ConfigTable):
    """Registration and filter settings."""

    registration: Literal["kabsch", "ransac", "ml", "map"] = Field(
        "kabsch", description="kabsch: 003 eq (11)-(13) weighted; ransac: + 3-point RANSAC; ml: covariance-aware; "
                              "map: ml to the previous epoch and to the target model's keyframes, with loop closure "
                              "(needs filter = smoother)")
    ml_kernel: Literal["none", "cauchy"] = Field(
        "none", description="ml and map: robust weight of the residuals; cauchy (scale 2.5 in Mahalanobis units) "
                            "for the rendered mode's heavy-tailed keypoint errors, none: the Gaussian likelihood")
    filter: Literal["ekf", "mekf", "smoother"] = Field(
        "ekf", description="ekf: 003's additive EKF; mekf: multiplicative EKF; smoother: gtsam iSAM2 factor graph "
                           "with torque-free dynamics")
    estimate_inertia: Flag = Field(True, description="smoother: estimate the inertia shape (principal axes and two "
                                   "ratios) from inertia_prior_kg_m2; else use the target's true tensor")
    inertia_prior_kg_m2: list[Inertia_kg_m2] = Field([1.0, 0.9, 0.8], description="smoother: prior mean of the "
                                                     "inertia shape (principal moments along the body axes)")
    process_sigma_attitude_rad: FiniteFloat = Field(
        1e-6, gt=0, le=1.0, description="smoother: per-second σ of the attitude process noise (un-modelled torque), "
        "rad/√s")
    process_sigma_rate_rad_s: FiniteFloat = Field(
        1e-8, gt=0, le=1.0, description="smoother: per-second σ of the rate process noise, rad/s/√s (the simulated "
        "target is torque-free; raise it for a real one: gravity-gradient torque on a 1000 kg m² body in low orbit "
        "changes the rate by up to about 1e-6 rad/s²)")
    viewpoint_window_deg: Angle_deg = Field(30.0, gt=0, le=180.0, description="map: largest viewpoint change over "
                                            "which descriptors associate (beyond: registration by geometry)")
    min_inliers: Integer = Field(10, ge=3, le=10000, description="evidence: fewest inlier pairs a registration "
                                 "needs to reach any estimator")

    _c_prior = field_validator("inertia_prior_kg_m2")(_vec(3, positive=True))
    sigma_q: FiniteFloat = Field(0.1, gt=0, le=1.0, description="003 eq (35) initial quaternion σ per component")
    sigma_omega_deg_s: Rate_deg_s = Field(0.1, gt=0, le=90.0, description="003 eq (35) initial rate σ")
    initial_attitude_known: Flag = Field(
        True, description="closed loop: the body frame is defined by the first frame (flag P003-14a, docs/papers.md#p003-14a), so the "
                          "filter starts at q_NT0 with sigma_q_known; else from 003 eq (35)")
    sigma_q_known: FiniteFloat = Field(1e-4, gt=0, le=1.0, description="initial quaternion sigma when known")
    convergence_attitude_deg: Angle_deg = Field(0.5, gt=0, description="convergence threshold, at most 360 deg "
                                                "(003 gives none: flag P003-15, docs/papers.md#p003-15)")
    convergence_rate_deg_s: Rate_deg_s = Field(0.05, gt=0, description="rate convergence threshold, at most 1e3 deg/s")
    convergence_hold_s: Duration_s = Field(10.0, ge=0, description="time the thresholds must hold, at most 1e7 s")


class TimeConfig(ConfigTable):
    """Epochs ``t = 0, dt, …, duration``."""

    dt_s: Duration_s = Field(0.1, gt=0, le=600.0)
    duration_s: Duration_s = Field(60.0, gt=0, le=86400.0 * 2)

    @model_validator(mode="after")
    def _steps(self) -> TimeConfig:
        n = self.duration_s / self.dt_s
        if n < 1:
            raise ValueError(f"duration_s: {self.duration_s:g} is shorter than dt_s {self.dt_s:g}")
        if n > 200_000:
            raise ValueError(f"duration_s: {n:.0f} epochs is too many (at most 200000)")
        return self

    def epochs(self) -> np.ndarray:
        """Epochs ``(T,)``, s: ``0, dt_s, …`` up to ``duration_s``."""
        n = int(np.floor(self.duration_s / self.dt_s + 1e-9))
        return self.dt_s * np.arange(n + 1)


class ErrorMapConfig(ConfigTable):
    """003 Experiment A: random initial attitudes, each followed by equal attitude steps."""

    steps: Integer = Field(10, ge=1, le=1000, description="attitude steps after each initial attitude")
    step_deg: list[Angle_deg] = Field([0.5, 0.5, 0.5], description="commanded increment Δθ (H frame rotation vector)")
    filter_runs: Integer = Field(0, ge=0, le=10000,
                             description="> 0: also run the EKF driven by this cell's measured error")
    filter_error: Literal["step_rms", "e_dtheta"] = Field(
        "step_rms", description="the cell statistic used as the filter's measurement error (median over trials)")

    _c_step = field_validator("step_deg")(_vec(3))


class EkfStudyConfig(ConfigTable):
    """003 Experiments B–D: the EKF on synthetic attitude measurements."""

    runs: Integer = Field(100, ge=1, le=100000, description="Monte Carlo runs per case (003: 100)")
    angle_error_deg: Angle_deg = Field(0.2, ge=0, le=45.0, description="measurement error of a single case / sweep cell")
    cases_deg: list[Angle_deg] = Field([0.2, 0.6], max_length=1000, description="Experiments B-C: measurement errors")
    windows_deg: dict[str, list[Angle_deg]] = Field(
        {"3 views": [0.025, 0.35], "2 views": [0.03, 0.85]},
        description="Experiment D: per-run error drawn uniformly from [lo, hi]")
    measurement: Literal["absolute", "increment", "chained_absolute"] = "absolute"
    typical_runs: Integer = Field(10, ge=1, le=1000, description="runs drawn in Figs 7-12 (003: 10)")

    @field_validator("cases_deg")
    @classmethod
    def _cases(cls, v: list[float]) -> list[float]:
        if any((not np.isfinite(x)) or x < 0 or x > 45 for x in v):
            raise ValueError(f"each error must be in [0, 45] deg, got {shorten(v)}")
        return v

    @field_validator("windows_deg")
    @classmethod
    def _windows(cls, v: dict[str, list[float]]) -> dict[str, list[float]]:
        if len(v) > 64:
            raise ValueError(f"at most 64 windows, got {len(v)}")
        for name, w in v.items():
            if len(w) != 2 or not (0 <= w[0] <= w[1] <= 45):
                raise ValueError(f"{shorten(name)}: need [lo, hi] with 0 <= lo <= hi <= 45 deg, got {shorten(w)}")
        return v


class Config(ScenarioConfig):
    """A ``kind = "formation"`` config (003: multi-view cooperative observation)."""

    kind: Literal["formation"]
    study: Literal["closed_loop", "error_map", "ekf"] = "closed_loop"
    title: str = Field("", max_length=200)
    seed: Seed = 0
    trials: Integer = Field(1, ge=1, le=100000, description="coobs run: trials of error_map / closed_loop")
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
        self.check_swept_values()
        if self.estimator.registration == "map" and self.estimator.filter != "smoother":
            raise ValueError(f"estimator.registration: 'map' needs estimator.filter = 'smoother', got "
                             f"{self.estimator.filter!r}")
        hold = self.estimator.convergence_hold_s
        if self.study in ("ekf", "closed_loop") and hold > self.time.duration_s:
            raise ValueError(f"estimator.convergence_hold_s: {hold:g} s exceeds time.duration_s "
                             f"{self.time.duration_s:g}")
        return self

    def inertia(self) -> np.ndarray:
        """Target inertia tensor (3, 3) in the body frame, kg·m² (``inertia_tensor_kg_m2`` when given)."""
        if self.target.inertia_tensor_kg_m2 is not None:
            return np.asarray(self.target.inertia_tensor_kg_m2, dtype=float)
        return np.diag(self.target.inertia_kg_m2)

    def omega0_rad_s(self) -> np.ndarray:
        """Initial body rate ``(3,)``, rad/s."""
        return np.deg2rad(np.asarray(self.target.omega_TN_T0_deg_s, dtype=float))
