"""Scenario kind ``rodrigues_001``: paper 001's 6000 s monocular relative-pose simulation.

The Table 1 scenario of 001 (SEEDS_SPEC §2.4–2.7): chaser and target on two-body orbits
(:class:`orbits.scenario_001.Table1Orbit`, the target 0.013 s ahead at the node, ≈100 m ahead
along-track), a 2 m cube target whose visible vertices are the features, a 2048×2048 camera with
7 µm pixels and f = 200 mm, 1 px white noise, 0–6000 s at 5 s.  Each epoch is solved by

* ``switching``: :func:`chaser.rodrigues_pose.solve_pose_rodrigues` with the four-set switching,
* ``non_switching``: the same solver kept in set 0 (the paper's comparison, ref [4]),
* ``opencv_sqpnp``: ``cv2.solvePnP(..., SOLVEPNP_SQPNP)`` (global, no initial guess),
* ``opencv_iterative``: ``cv2.solvePnP(..., SOLVEPNP_ITERATIVE, useExtrinsicGuess=True)`` warm-started
  from its own previous solution, like ours,
* ``pycolmap``: ``pycolmap.estimate_and_refine_absolute_pose`` (LO-RANSAC P3P + refinement),

all on the same noisy frames, each timed per call.

Attitude model (FLAG P001-5, SEEDS_SPEC Appendix A.2): each spacecraft's Table 1 angles are 3-2-1
(yaw, pitch, roll) Euler angles of its body B relative to its *orbital reference frame* O, and the
Table 1 rates are constant body rates relative to O, ``R_OB(t) = R_OB(0) exp([ω_B×] t)``.  O turns
with the spacecraft's own Hill frame H (x radial, y along-track, z normal) and is the camera-pointing
frame ``x_O = −z_H``, ``y_O = −x_H`` (nadir, image "down"), ``z_O = y_H`` (along-track, at the target);
the camera frame is the chaser body (boresight z).  Under this reading the relative rotation
target→camera passes 180° at 2228.6 s (A.2: 2228.61 s).

Errors are reported in the camera frame and in the chaser's Hill frame (FLAG P001-4: the paper's
"X, along the optical axis" is the along-track axis, the line of sight); attitude errors as
3-2-1 Euler angles of ``R_CT`` (estimate minus truth) and as the small rotation ``R̂_CT R_CTᵀ`` in
camera axes.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Literal

import cv2
import numpy as np
import pycolmap
import xarray as xr
from pydantic import BaseModel, ConfigDict, Field, model_validator
from scipy.optimize import brentq

from attitude.euler import euler_from_matrix, matrix_from_euler
from attitude.quaternion import (
    matrix_from_quat,
    quat_from_matrix,
    quat_from_rotvec,
    quat_multiply,
    rotvec_from_quat,
)
from chaser.rodrigues_pose import (
    GibbsPose,
    pixels_from_focal_plane,
    project_focal_plane,
    solve_pose_rodrigues,
)
from experiments.results import ScenarioResult
from orbits.hill import hill_frame
from orbits.scenario_001 import Table1Orbit
from orbits.two_body import R_EARTH_M

__all__ = ["Config", "run", "plot", "SOLVERS", "R_HO", "truth_001", "crossing_times_s", "cube_vertices",
           "visible_vertices"]

#: Solvers compared on the same frames, in dataset order.
SOLVERS = ("switching", "non_switching", "opencv_sqpnp", "opencv_iterative", "pycolmap")

#: Orbital reference frame O of the Table 1 Euler angles, in H components (columns x_O, y_O, z_O).
R_HO = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])


# ------------------------------------------------------------------------------------ config
class SpacecraftConfig(BaseModel):
    """One column of 001 Table 1: orbit and attitude (angles in the 3-2-1 reading, rates about body axes)."""

    model_config = ConfigDict(extra="forbid")
    a_km: float = Field(6721.2, gt=R_EARTH_M / 1e3, description="semi-major axis")
    e: float = Field(0.0, ge=0.0, lt=1.0)
    i_deg: float = Field(42.225, ge=0.0, le=180.0)
    raan_deg: float = Field(0.0, ge=-360.0, le=360.0)
    argp_deg: float = Field(0.0, ge=-360.0, le=360.0)
    t_node_s: float = Field(0.0, description="time of ascending-node passage")
    roll_deg: float = Field(0.0, ge=-180.0, le=180.0)
    pitch_deg: float = Field(0.0, ge=-90.0, le=90.0)
    yaw_deg: float = Field(0.0, ge=-180.0, le=180.0)
    roll_rate_deg_s: float = Field(0.0, ge=-10.0, le=10.0)
    pitch_rate_deg_s: float = Field(0.0, ge=-10.0, le=10.0)
    yaw_rate_deg_s: float = Field(0.0, ge=-10.0, le=10.0)

    @model_validator(mode="after")
    def _perigee_above_earth(self):
        if self.a_km * (1.0 - self.e) * 1e3 <= R_EARTH_M:
            raise ValueError(f"perigee radius a_km*(1-e) = {self.a_km * (1 - self.e):.1f} km is inside the Earth")
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


class CameraConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")
    focal_length_mm: float = Field(200.0, gt=0.0, le=10_000.0)
    pixel_size_um: float = Field(7.0, gt=0.0, le=1000.0)
    width_px: int = Field(2048, ge=16, le=100_000)
    height_px: int = Field(2048, ge=16, le=100_000)
    noise_px: float = Field(1.0, ge=0.0, le=100.0, description="white noise, 1 sigma per image coordinate")


class TargetConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")
    cube_edge_m: float = Field(2.0, gt=0.0, le=100.0)


class SimulationConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")
    duration_s: float = Field(6000.0, gt=0.0, le=1e6)
    step_s: float = Field(5.0, gt=0.0)

    @model_validator(mode="after")
    def _step_fits(self):
        if self.step_s > self.duration_s:
            raise ValueError(f"step_s = {self.step_s} is longer than duration_s = {self.duration_s}")
        return self


class SolverConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")
    eps_attitude: float = Field(1e-8, gt=0.0, lt=1.0, description="epsilon_1 on |dg|")
    eps_translation_m: float = Field(1e-5, gt=0.0, lt=10.0, description="epsilon_2 on |dt|")
    max_iterations: int = Field(50, ge=1, le=1000)
    eta: float = Field(0.0, ge=0.0, le=1.0, description="switching hysteresis")
    initial_attitude_error_deg: float = Field(1.0, ge=0.0, le=60.0)
    initial_position_error_m: float = Field(1.0, ge=0.0, le=50.0)


class ComparisonConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")
    opencv: bool = True
    pycolmap: bool = True


class Config(BaseModel):
    """``rodrigues_001`` config: 001 Table 1 and the camera, target, solver and comparison options."""

    model_config = ConfigDict(extra="forbid")
    kind: Literal["rodrigues_001"]
    seed: int = Field(1, ge=0)
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


# ------------------------------------------------------------------------------------ truth
def cube_vertices(edge_m: float) -> np.ndarray:
    """The 8 vertices ``(8, 3)`` of a cube centred on the target origin, body frame, m."""
    h = 0.5 * edge_m
    return np.array([[x, y, z] for x in (-h, h) for y in (-h, h) for z in (-h, h)])


def visible_vertices(R_CT: np.ndarray, r_TC_C: np.ndarray, edge_m: float) -> np.ndarray:
    """``(..., 8)``: a vertex is visible if one of its faces has ``n·(c − p) > 0`` (SEEDS_SPEC §2.7)."""
    c_T = -np.einsum("...ji,...j->...i", R_CT, r_TC_C)  # camera position in the target frame
    V = cube_vertices(edge_m)
    vis = np.zeros(c_T.shape[:-1] + (8,), bool)
    for k in range(3):
        for s in (-1.0, 1.0):
            vis |= (s * c_T[..., k] - 0.5 * edge_m > 0)[..., None] & (s * V[:, k] > 0)
    return vis


def truth_001(cfg: Config, t_s: np.ndarray) -> dict[str, np.ndarray]:
    """Relative pose truth at epochs ``t_s`` (T,).

    Returns ``R_CT (T,3,3)``, ``r_TC_C (T,3)`` (m), ``R_HC (T,3,3)`` (chaser Hill frame from camera)
    and ``range_m (T,)``.
    """
    r_c, v_c = cfg.chaser.orbit().state_N(t_s)
    r_t, v_t = cfg.target.orbit().state_N(t_s)
    R_NHc = hill_frame(r_c, v_c)
    R_NHt = hill_frame(r_t, v_t)
    R_OS = matrix_from_quat(cfg.chaser.q_OB(t_s))  # camera C = chaser body S
    R_OT = matrix_from_quat(cfg.target.q_OB(t_s))
    R_HC = R_HO @ R_OS
    R_NC = R_NHc @ R_HC
    R_CN = np.swapaxes(R_NC, -1, -2)
    R_CT = R_CN @ R_NHt @ R_HO @ R_OT
    r_TC_C = np.einsum("tij,tj->ti", R_CN, r_t - r_c)
    return {"R_CT": R_CT, "r_TC_C": r_TC_C, "R_HC": R_HC, "range_m": np.linalg.norm(r_t - r_c, axis=-1)}


def crossing_times_s(cfg: Config, t_s: np.ndarray) -> np.ndarray:
    """Times where the relative rotation target→camera passes exactly 180° (scalar part of q_CT = 0).

    The quaternion is made sign-continuous over the epochs; each sign change of its scalar part is
    refined with Brent's method on the continuous truth.
    """
    q = quat_from_matrix(truth_001(cfg, t_s)["R_CT"])
    for k in range(1, len(q)):
        if q[k] @ q[k - 1] < 0:
            q[k] = -q[k]
    out = []
    for k in np.flatnonzero(np.sign(q[:-1, 0]) * np.sign(q[1:, 0]) < 0):
        ref = q[k]

        def w(t, ref=ref):
            qq = quat_from_matrix(truth_001(cfg, np.array([t]))["R_CT"])[0]
            return qq[0] * np.sign(qq @ ref)

        out.append(brentq(w, t_s[k], t_s[k + 1], xtol=1e-6))
    return np.array(out)


# ------------------------------------------------------------------------------------ solvers
class _Timer:
    def __init__(self):
        self.t0 = 0.0

    def __enter__(self):
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.dt = time.perf_counter() - self.t0


def _opencv(flag, P, uv, K, guess):
    """One OpenCV solvePnP call; returns (R_CT, t, reason)."""
    if len(P) < (4 if flag == cv2.SOLVEPNP_ITERATIVE else 3):
        return None, None, "too_few_points"
    try:
        if guess is None:
            ok, rvec, tvec = cv2.solvePnP(P, uv, K, None, flags=flag)
        else:
            ok, rvec, tvec = cv2.solvePnP(P, uv, K, None, guess[0].copy(), guess[1].copy(), True, flags=flag)
    except cv2.error:
        return None, None, "opencv_error"
    if not ok:
        return None, None, "not_converged"
    return (rvec, tvec), tvec.ravel(), ""


def run(cfg: Config, *, progress: Callable[[int, int], None]) -> ScenarioResult:
    """Run the 001 scenario: truth, noisy frames, the five solvers, errors and timings."""
    t_s = np.arange(0.0, cfg.simulation.duration_s + 0.5 * cfg.simulation.step_s, cfg.simulation.step_s)
    n_t = len(t_s)
    noise_rng, init_rng, colmap_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(cfg.seed).spawn(3))
    f = cfg.camera.focal_length_mm * 1e-3
    pix = cfg.camera.pixel_size_um * 1e-6
    centre = np.array([cfg.camera.width_px / 2.0, cfg.camera.height_px / 2.0])
    K = np.array([[f / pix, 0.0, centre[0]], [0.0, f / pix, centre[1]], [0.0, 0.0, 1.0]])
    cube = cube_vertices(cfg.target_model.cube_edge_m)

    # truth and frames
    tr = truth_001(cfg, t_s)
    R_CT, r_TC = tr["R_CT"], tr["r_TC_C"]
    xy, depth = project_focal_plane(cube, R_CT, r_TC, focal_length_m=f)
    xy = xy + cfg.camera.noise_px * pix * noise_rng.standard_normal(xy.shape)
    uv_all = pixels_from_focal_plane(xy, pixel_size_m=pix, principal_point_px=centre)
    in_image = np.all((uv_all >= 0) & (uv_all <= [cfg.camera.width_px, cfg.camera.height_px]), -1)
    vis = visible_vertices(R_CT, r_TC, cfg.target_model.cube_edge_m) & (depth > 0) & in_image
    xy = np.where(vis[..., None], xy, np.nan)

    # initial guess at t = 0: the truth turned by the configured angle and moved by the configured distance
    axis = init_rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    shift = init_rng.standard_normal(3)
    shift /= np.linalg.norm(shift)
    q0 = quat_multiply(quat_from_rotvec(np.radians(cfg.solver.initial_attitude_error_deg) * axis),
                       quat_from_matrix(R_CT[0]))
    r0 = r_TC[0] + cfg.solver.initial_position_error_m * shift

    n_s = len(SOLVERS)
    R_est = np.full((n_s, n_t, 3, 3), np.nan)
    r_est = np.full((n_s, n_t, 3), np.nan)
    reason = np.full((n_s, n_t), "", dtype=object)
    enabled = np.array([True, True, cfg.comparison.opencv, cfg.comparison.opencv, cfg.comparison.pycolmap])
    reason[~enabled] = "disabled"
    solve_time = np.full((n_s, n_t), np.nan)
    iterations = np.full((2, n_t), -1)
    gibbs_set = np.full((2, n_t), -1)

    opts = dict(focal_length_m=f, eps_attitude=cfg.solver.eps_attitude, eps_translation_m=cfg.solver.eps_translation_m,
                max_iterations=cfg.solver.max_iterations)
    state = [GibbsPose.from_quat(q0, r0), GibbsPose.from_quat(q0, r0, gibbs_set=0)]
    cv_guess = (cv2.Rodrigues(matrix_from_quat(q0))[0], r0.reshape(3, 1).copy())
    cam = pycolmap.Camera(model="PINHOLE", width=cfg.camera.width_px, height=cfg.camera.height_px,
                          params=[K[0, 0], K[1, 1], centre[0], centre[1]])
    col_opts = pycolmap.AbsolutePoseEstimationOptions()

    for k in range(n_t):
        # ours: switching and non-switching, each warm-started from its last successful solution
        for s, switching in ((0, True), (1, False)):
            with _Timer() as tm:
                res = solve_pose_rodrigues(cube, xy[k], state[s], visible=vis[k], switching=switching,
                                           eta=cfg.solver.eta if switching else 0.0, **opts)
            solve_time[s, k] = tm.dt
            reason[s, k] = str(res.failure_reason)
            iterations[s, k] = int(res.iterations)
            if res.ok:
                R_est[s, k], r_est[s, k] = res.R_CT, res.r_TC_C
                gibbs_set[s, k] = int(res.pose.gibbs_set)
                state[s] = res.pose
        P, uv = cube[vis[k]], np.ascontiguousarray(uv_all[k, vis[k]])
        if cfg.comparison.opencv:
            for s, flag, guess in ((2, cv2.SOLVEPNP_SQPNP, None), (3, cv2.SOLVEPNP_ITERATIVE, cv_guess)):
                with _Timer() as tm:
                    sol, tvec, why = _opencv(flag, P, uv, K, guess)
                solve_time[s, k] = tm.dt
                reason[s, k] = why
                if sol is not None:
                    R_est[s, k], r_est[s, k] = cv2.Rodrigues(sol[0])[0], tvec
                    if s == 3:
                        cv_guess = sol
        if cfg.comparison.pycolmap:
            col_opts.ransac.random_seed = int(colmap_rng.integers(0, 2**31 - 1))
            with _Timer() as tm:
                out = pycolmap.estimate_and_refine_absolute_pose(uv, P, cam, col_opts) if len(P) >= 4 else None
            solve_time[4, k] = tm.dt
            if out is None:
                reason[4, k] = "too_few_points" if len(P) < 4 else "not_converged"
            else:
                R_est[4, k] = out["cam_from_world"].rotation.matrix()
                r_est[4, k] = out["cam_from_world"].translation
        progress(k + 1, n_t)

    ok = np.all(np.isfinite(r_est), -1)
    ds = _dataset(cfg, t_s, tr, vis, R_est, r_est, ok, reason, solve_time, iterations, gibbs_set)
    return ScenarioResult(ds, _summary(cfg, ds))


# ------------------------------------------------------------------------------------ results
def _wrap_deg(a):
    return (a + 180.0) % 360.0 - 180.0


def _dataset(cfg, t_s, tr, vis, R_est, r_est, ok, reason, solve_time, iterations, gibbs_set) -> xr.Dataset:
    R_CT, r_TC, R_HC = tr["R_CT"], tr["r_TC_C"], tr["R_HC"]
    err_C = r_est - r_TC
    err_H = np.einsum("tij,stj->sti", R_HC, err_C)
    los = r_TC / np.linalg.norm(r_TC, axis=-1, keepdims=True)
    along = np.sum(err_C * los, -1)
    across = np.linalg.norm(err_C - along[..., None] * los, axis=-1)
    eul_true = np.degrees(euler_from_matrix(R_CT, "321")[0])
    R_safe = np.where(ok[..., None, None], R_est, np.eye(3))
    eul_est = np.where(ok[..., None], np.degrees(euler_from_matrix(R_safe, "321")[0]), np.nan)
    dR = R_safe @ np.swapaxes(R_CT, -1, -2)
    rot_err = np.where(ok[..., None], np.degrees(rotvec_from_quat(quat_from_matrix(dR))), np.nan)
    axis3 = ("solver", "time_s", "axis")
    ds = xr.Dataset(
        {
            "r_TC_C_true": (("time_s", "axis"), r_TC, {"units": "m", "long_name": "target position, camera frame"}),
            "euler_321_true": (("time_s", "euler"), eul_true,
                               {"units": "deg", "long_name": "3-2-1 Euler angles of R_CT (target to camera)"}),
            "range_m": (("time_s",), tr["range_m"], {"units": "m"}),
            "relative_angle_deg": (("time_s",), np.degrees(np.arccos(np.clip((np.trace(R_CT, axis1=-2, axis2=-1) - 1) / 2,
                                                                             -1, 1))),
                                   {"units": "deg", "long_name": "rotation angle of R_CT"}),
            "n_points": (("time_s",), vis.sum(-1), {"units": "1", "long_name": "visible cube vertices"}),
            "r_TC_C_est": (axis3, r_est, {"units": "m"}),
            "euler_321_est": (("solver", "time_s", "euler"), eul_est, {"units": "deg"}),
            "position_error_C": (axis3, err_C, {"units": "m", "long_name": "position error, camera frame"}),
            "position_error_H": (("solver", "time_s", "hill_axis"), err_H,
                                 {"units": "m", "long_name": "position error, chaser Hill frame (P001-4)"}),
            "position_error_los_m": (("solver", "time_s"), along, {"units": "m", "long_name": "along line of sight"}),
            "position_error_across_m": (("solver", "time_s"), across,
                                        {"units": "m", "long_name": "across line of sight (norm)"}),
            "attitude_error_euler": (("solver", "time_s", "euler"), _wrap_deg(eul_est - eul_true),
                                     {"units": "deg", "long_name": "3-2-1 Euler angles of R_CT, estimate minus truth"}),
            "attitude_error_C": (axis3, rot_err,
                                 {"units": "deg", "long_name": "rotation vector of R_est R_CT^T, camera axes"}),
            "ok": (("solver", "time_s"), ok.astype(np.int8), {"units": "1", "long_name": "pose returned (1) or not"}),
            "failure_reason": (("solver", "time_s"), np.where(ok, "", reason).astype(str)),
            "solve_time_s": (("solver", "time_s"), solve_time, {"units": "s", "long_name": "wall time of one solve"}),
            "iterations": (("variant", "time_s"), iterations, {"units": "1"}),
            "gibbs_set": (("variant", "time_s"), gibbs_set, {"units": "1", "long_name": "parameter set i (001 eq 4)"}),
        },
        coords={"solver": list(SOLVERS), "time_s": t_s, "axis": ["x", "y", "z"],
                "hill_axis": ["radial", "along_track", "cross_track"], "euler": ["yaw", "pitch", "roll"],
                "variant": ["switching", "non_switching"]},
        attrs={"title": "paper 001 relative pose, Table 1 scenario", "seed": cfg.seed,
               "crossing_time_s": float(np.r_[crossing_times_s(cfg, t_s), np.nan][0])},
    )
    ds["time_s"].attrs["units"] = "s"
    return ds


def _stats(x: np.ndarray) -> dict[str, float]:
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {"rms": float("nan"), "max_abs": float("nan"), "p95_abs": float("nan"), "std": float("nan")}
    return {"rms": float(np.sqrt(np.mean(x**2))), "max_abs": float(np.max(np.abs(x))),
            "p95_abs": float(np.percentile(np.abs(x), 95)), "std": float(np.std(x))}


def _summary(cfg: Config, ds: xr.Dataset) -> dict:
    out: dict = {"crossing_time_s": ds.attrs["crossing_time_s"], "epochs": int(ds.sizes["time_s"])}
    per: dict = {}
    t = ds["time_s"].values
    for s in SOLVERS:
        d = ds.sel(solver=s)
        if np.all(d["failure_reason"].values == "disabled"):
            continue
        ok = d["ok"].values.astype(bool)
        fail_t = t[~ok]
        per[s] = {
            "failures": int((~ok).sum()),
            "first_failure_s": float(fail_t[0]) if fail_t.size else None,
            "along_los_m": _stats(d["position_error_los_m"].values),
            "across_los_m": _stats(d["position_error_across_m"].values),
            **{f"hill_{a}_m": _stats(d["position_error_H"].sel(hill_axis=a).values)
               for a in ("radial", "along_track", "cross_track")},
            **{f"camera_{a}_m": _stats(d["position_error_C"].sel(axis=a).values) for a in ("x", "y", "z")},
            **{f"{e}_deg": _stats(d["attitude_error_euler"].sel(euler=e).values) for e in ("yaw", "pitch", "roll")},
            "median_solve_time_us": float(np.nanmedian(d["solve_time_s"].values) * 1e6),
        }
    out["solvers"] = per
    sw = per["switching"]
    out["switching_failures"] = sw["failures"]
    out["non_switching_first_failure_s"] = per["non_switching"]["first_failure_s"]
    out["switching_along_los_rms_m"] = sw["along_los_m"]["rms"]
    out["switching_across_los_rms_m"] = sw["across_los_m"]["rms"]
    out["switching_attitude_rms_deg"] = max(sw[f"{e}_deg"]["rms"] for e in ("yaw", "pitch", "roll"))
    out["switching_median_solve_time_us"] = sw["median_solve_time_us"]
    return out


# ------------------------------------------------------------------------------------ figures
def plot(dataset: xr.Dataset, fig_dir: Path) -> list[Path]:
    """Figures like 001 Figs 1–2 (position and attitude errors), the comparison and the switching."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from experiments.plotting import save

    ds = dataset
    t = ds["time_s"].values
    fail_ns = t[ds["ok"].sel(solver="non_switching").values == 0]
    t_fail = fail_ns[0] if fail_ns.size else None
    paths = []

    def _series(ax, y_sw, y_ns, ylabel):
        ax.plot(t, y_ns, color="tab:orange", lw=0.8, label="non-switching (set 0)")
        ax.plot(t, y_sw, color="tab:blue", lw=0.6, label="switching")
        if t_fail is not None:
            ax.axvline(t_fail, color="k", ls="--", lw=0.8)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        return ax

    # Fig 1: position error in the chaser Hill frame (paper X = along-track = line of sight)
    fig, axes = plt.subplots(3, 1, figsize=(7.0, 7.0), sharex=True, layout="constrained")
    for ax, a, lab in zip(axes, ("along_track", "radial", "cross_track"),
                          ("along-track / LOS (paper X) [m]", "radial [m]", "cross-track [m]"), strict=True):
        e = ds["position_error_H"].sel(hill_axis=a)
        _series(ax, e.sel(solver="switching").values, e.sel(solver="non_switching").values, lab)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[0].set_title("001 Fig 1: position error, chaser Hill frame"
                      + (f"; non-switching fails at {t_fail:.0f} s" if t_fail is not None else ""), fontsize=10)
    axes[-1].set_xlabel("t [s]")
    paths.append(save(fig, fig_dir / "fig1_position_error.png"))

    # Fig 2: attitude error, 3-2-1 Euler angles of R_CT
    fig, axes = plt.subplots(3, 1, figsize=(7.0, 7.0), sharex=True, layout="constrained")
    for ax, e in zip(axes, ("yaw", "pitch", "roll"), strict=True):
        v = ds["attitude_error_euler"].sel(euler=e)
        _series(ax, v.sel(solver="switching").values, v.sel(solver="non_switching").values, f"{e} [deg]")
    axes[0].legend(loc="upper right", fontsize=8)
    axes[0].set_title("001 Fig 2: attitude error, 3-2-1 Euler angles of R_CT (the two solvers agree until"
                      " the failure)", fontsize=10)
    axes[-1].set_xlabel("t [s]")
    paths.append(save(fig, fig_dir / "fig2_attitude_error.png"))

    # Fig 3: the relative rotation angle and the active Gibbs parameter set
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7.0, 4.5), sharex=True, layout="constrained")
    a1.plot(t, ds["relative_angle_deg"].values, color="k", lw=0.8)
    a1.axhline(180.0, color="grey", ls=":")
    if np.isfinite(ds.attrs.get("crossing_time_s", np.nan)):
        a1.axvline(ds.attrs["crossing_time_s"], color="tab:red", ls="--", lw=0.8,
                   label=f"180° at {ds.attrs['crossing_time_s']:.2f} s")
        a1.legend(fontsize=8)
    a1.set_ylabel("angle of R_CT [deg]")
    a2.step(t, ds["gibbs_set"].sel(variant="switching").values, where="post", lw=0.8)
    a2.set_yticks([0, 1, 2, 3])
    a2.set_ylabel("Gibbs set i")
    a2.set_xlabel("t [s]")
    paths.append(save(fig, fig_dir / "fig3_rotation_and_switching.png"))

    # Fig 4: accuracy and time of the solvers on the same frames
    solvers = [s for s in ds["solver"].values if not np.all(ds["failure_reason"].sel(solver=s).values == "disabled")]
    fig, axes = plt.subplots(1, 4, figsize=(13.0, 3.6), layout="constrained")
    metrics = [("position_error_los_m", "along LOS RMS [m]"), ("position_error_across_m", "across LOS RMS [m]")]
    for ax, (name, lab) in zip(axes[:2], metrics, strict=True):
        vals = [float(np.sqrt(np.nanmean(ds[name].sel(solver=s).values ** 2))) for s in solvers]
        ax.bar(range(len(solvers)), vals)
        ax.set_ylabel(lab)
    att = [float(np.sqrt(np.nanmean(ds["attitude_error_C"].sel(solver=s).values ** 2, axis=0)).max()) for s in solvers]
    axes[2].bar(range(len(solvers)), att)
    axes[2].set_ylabel("attitude RMS, worst camera axis [deg]")
    tm = [float(np.nanmedian(ds["solve_time_s"].sel(solver=s).values) * 1e6) for s in solvers]
    axes[3].bar(range(len(solvers)), tm)
    axes[3].set_yscale("log")
    axes[3].set_ylabel("median time per solve [µs]")
    for ax in axes:
        ax.set_xticks(range(len(solvers)), solvers, rotation=30, ha="right", fontsize=8)
        ax.grid(axis="y", alpha=0.3)
    paths.append(save(fig, fig_dir / "fig4_solver_comparison.png"))
    return paths
