"""Scenario kind ``rodrigues_001``: paper 001's 6000 s monocular relative-pose simulation.

The Table 1 scenario of 001: chaser and target on two-body orbits
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

The truth (orbits, the Table 1 attitude model, visible vertices) is :mod:`experiments.scenarios.rodrigues.truth`.

Errors are reported in the camera frame and in the chaser's Hill frame (flag P001-4, docs/papers.md#p001-4: the paper's
"X, along the optical axis" is the along-track axis, the line of sight); attitude errors as
3-2-1 Euler angles of ``R_CT`` (estimate minus truth) and as the small rotation ``R̂_CT R_CTᵀ`` in
camera axes.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import cv2
import numpy as np
import pycolmap
import xarray as xr

from attitude.euler import euler_from_matrix
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
from experiments.results import ScenarioResult, no_progress
from experiments.scenarios.rodrigues.config import Config
from experiments.scenarios.rodrigues.opencv_pnp import solve_pnp
from experiments.scenarios.rodrigues.truth import (
    crossing_times_s,
    cube_vertices,
    truth_001,
    visible_vertices,
)

__all__ = ["run", "SOLVERS"]

#: Solvers compared on the same frames, in dataset order.
SOLVERS = ("switching", "non_switching", "opencv_sqpnp", "opencv_iterative", "pycolmap")


# ------------------------------------------------------------------------------------ solvers
class _Timer:
    def __init__(self):
        self.t0 = 0.0

    def __enter__(self):
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.dt = time.perf_counter() - self.t0


def run(cfg: Config, *, progress: Callable[[int, int], None] | None = None) -> ScenarioResult:
    """Run the 001 scenario: truth, noisy frames, the five solvers, errors and timings.

    With ``study = "envelope"`` one point of the working envelope instead
    (:func:`experiments.scenarios.rodrigues.envelope.envelope_run`).

    Parameters
    ----------
    cfg : Config
        The validated ``rodrigues_001`` config.
    progress : callable, optional
        ``progress(done, total)`` as the epochs are solved.

    Returns
    -------
    ScenarioResult
        Per solver and epoch: pose errors in camera and Hill axes, ``ok``, ``failure_reason``, solve
        times; the summary of error statistics per solver.
    """
    if cfg.study == "envelope":
        from experiments.scenarios.rodrigues.envelope import envelope_run

        ds, summary = envelope_run(cfg, progress=progress)
        return ScenarioResult(ds, {"study": "envelope", **summary})
    progress = progress or no_progress
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
                    rvec, tvec, why = solve_pnp(flag, P, uv, K, guess, failed_reason="not_converged")
                solve_time[s, k] = tm.dt
                reason[s, k] = why
                if rvec is not None:
                    R_est[s, k], r_est[s, k] = cv2.Rodrigues(rvec)[0], tvec.ravel()
                    if s == 3:
                        cv_guess = (rvec, tvec)
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
