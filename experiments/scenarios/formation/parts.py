"""The closed-loop parts a formation config names, built through the :mod:`closed_loop` registries.

Each function reads one table of the config; none of them picks an alternative by string
comparison: the observer, registrar and estimator classes come from :data:`closed_loop.OBSERVERS`,
:data:`closed_loop.REGISTRARS` and :data:`closed_loop.ESTIMATORS`.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from closed_loop import ESTIMATORS, OBSERVERS, REGISTRARS, ClosedLoop, Observer, Registrar
from closed_loop.evidence import Evidence
from closed_loop.smoother import SmootherSettings
from closed_loop.smoothing_loop import SmoothingLoop
from closed_loop.target_model import ModelSettings
from experiments.scenarios.formation.config import Config
from filters import AttitudeFilter, ConvergenceCriterion
from formation.constraints import ObservationConstraints
from formation.geometry import symmetric_views
from orbits.cw import mean_motion
from orbits.two_body import R_EARTH_M
from vision.camera import PinholeCamera
from vision.target import Target, fy1_target, load_mesh

__all__ = [
    "load_target",
    "make_camera",
    "make_observer",
    "make_registrar",
    "make_estimator",
    "make_loop",
    "criterion",
    "observation_constraints",
    "orbit_radius_m",
    "orbit_rate_rad_s",
    "symmetric_T_CW",
]


@functools.lru_cache(maxsize=4)
def _target_cached(model: str, unit_m: float, seed: int, path: str) -> Target:
    if model == "fy1":
        return fy1_target(seed=seed)
    return load_mesh(path, unit_m=unit_m, seed=seed)


def load_target(cfg: Config) -> Target:
    """The configured target model (built once per process; :class:`vision.target.Target` is immutable)."""
    t = cfg.target
    path = t.mesh_path()
    return _target_cached(t.model, float(t.mesh_unit_m), int(t.texture_seed), str(path) if path else "")


def make_camera(cfg: Config) -> PinholeCamera:
    """The identical pinhole camera of every observer (``[camera]``)."""
    c = cfg.camera
    return PinholeCamera.from_fov(c.width_px, c.height_px, fov_x_deg=c.fov_deg)


def make_observer(cfg: Config, camera: PinholeCamera | None = None, target: Target | None = None) -> Observer:
    """The observer of ``observation.mode``, with the ``[observation]`` options its class declares."""
    cls = OBSERVERS[cfg.observation.mode]
    names = {f.name for f in dataclasses.fields(cls)} - {"camera", "target"}
    options = {k: v for k, v in cfg.observation.model_dump().items() if k in names}
    if "orbit_radius_m" in names:   # the rendered mode's Earth below the target's orbit, seeded from the config
        options.update(orbit_radius_m=R_EARTH_M + 1e3 * cfg.formation.orbit_altitude_km, earth_seed=cfg.seed)
    return cls(camera=camera if camera is not None else make_camera(cfg),
               target=target if target is not None else load_target(cfg), **options)


def make_registrar(cfg: Config) -> Registrar:
    """The registrar of ``estimator.registration`` (``map`` fits by maximum likelihood) with the evidence thresholds."""
    e = cfg.estimator
    evidence = Evidence(min_inliers=e.min_inliers)
    if e.registration in ("ml", "map"):
        return REGISTRARS["ml"](evidence=evidence, kernel=None if e.ml_kernel == "none" else e.ml_kernel)
    return REGISTRARS[e.registration](evidence=evidence)


def make_estimator(cfg: Config) -> AttitudeFilter:
    """The filter of ``estimator.filter`` with the target's inertia (the smoother starts from an MEKF's prior)."""
    name = "mekf" if cfg.estimator.filter == "smoother" else cfg.estimator.filter
    return ESTIMATORS[name](J_kg_m2=cfg.inertia())


def make_loop(cfg: Config, camera: PinholeCamera | None = None,
              target: Target | None = None) -> ClosedLoop | SmoothingLoop:
    """The closed loop of the config: its observer, registrar and estimator (a filter, or the smoother with
    an optional target model)."""
    e = cfg.estimator
    observer, registrar = make_observer(cfg, camera, target), make_registrar(cfg)
    if e.filter == "smoother":
        J = np.diag(e.inertia_prior_kg_m2) if e.estimate_inertia else cfg.inertia()
        model = ModelSettings(viewpoint_window_deg=e.viewpoint_window_deg) if e.registration == "map" else None
        return SmoothingLoop(observer=observer, registrar=registrar, J_prior_kg_m2=J,
                             settings=SmootherSettings(estimate_inertia=e.estimate_inertia,
                                                       process_sigma_attitude_rad=e.process_sigma_attitude_rad,
                                                       process_sigma_rate_rad_s=e.process_sigma_rate_rad_s),
                             model=model)
    return ClosedLoop(observer=observer, registrar=registrar, estimator=make_estimator(cfg))


def criterion(cfg: Config) -> ConvergenceCriterion:
    """When a run counts as converged (``estimator.convergence_*``)."""
    e = cfg.estimator
    return ConvergenceCriterion(attitude_deg=e.convergence_attitude_deg, rate_deg_s=e.convergence_rate_deg_s,
                                hold_s=e.convergence_hold_s)


def observation_constraints(cfg: Config, target_radius_m: float) -> ObservationConstraints:
    """003 §1.2 observation constraints of the config (:class:`formation.constraints.ObservationConstraints`)."""
    f = cfg.formation
    return ObservationConstraints(
        fov_rad=float(np.deg2rad(cfg.camera.fov_deg)), target_radius_m=float(target_radius_m),
        d_max_m=f.d_max_m, d_min_form="tan", d_min_lambda=f.d_min_lambda,
        pointing_max_rad=float(np.deg2rad(f.max_pointing_deg)),
        axis_angle_min_rad=float(np.deg2rad(f.axis_angle_min_deg)),
        axis_angle_max_rad=float(np.deg2rad(f.axis_angle_max_deg)), comm_range_m=f.max_comm_range_m,
        sun_exclusion_rad=float(np.deg2rad(f.sun_exclusion_deg)), keep_out_radius_m=f.keep_out_radius_m)


def orbit_radius_m(cfg: Config) -> float:
    """Radius of the target's circular orbit, m."""
    return R_EARTH_M + 1e3 * cfg.formation.orbit_altitude_km


def orbit_rate_rad_s(cfg: Config) -> float:
    """Mean motion n of the target's circular orbit, rad/s."""
    return float(mean_motion(orbit_radius_m(cfg)))


def symmetric_T_CW(cfg: Config) -> np.ndarray:
    """Poses ``(n_views, 4, 4)`` of the symmetric cone of ``[formation]`` (003 §3.1)."""
    f = cfg.formation
    return symmetric_views(int(f.n_views), float(f.distance_m), float(f.axis_angle_deg)).T_CW
