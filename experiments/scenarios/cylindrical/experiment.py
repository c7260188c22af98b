"""Scenario kind ``cylindrical_004``: paper 004's experiments with the simulated linear-CCD system.

004 §4: two orthogonal cylindrical-imaging cameras 2 m apart whose optical axes
converge at 30°, a 1 m cube measuring volume 3 m in front of the baseline, 30 control points for the
extrinsic calibration.  The scenario

1. simulates the turntable-and-rail intrinsic calibration of each camera and fits the RBF maps,
   then measures the control points (laser tracker and cameras) and calibrates the extrinsics
   (:func:`chaser.cylindrical.calibrate_system`);
2. **Table 1 analogue**: measures the paper's 8 test points (and ``n_random`` more spread over the
   cube) and compares them with the truth;
3. **Table 2 analogue**: places a three-LED target at the paper's 8 "true" attitudes (3-1-2 reading of
   flag P004-3, docs/papers.md#p004-3) plus their 167.7° reading of pose No. 2, measures the LEDs
   and computes yaw/roll/pitch with the corrected eq 5–11 (``n_trials`` noise draws);
4. **dynamic test**: three LEDs on a spinning, drifting body seen at ``frame_rate_hz``; initial
   identities by sequential lighting, then Kalman-predicted association on every CCD; counts the
   spot crossings and identity swaps.

All draws come from one ``seed`` through ``SeedSequence.spawn`` (calibration, points, attitude,
dynamic), so changing one part does not change the others.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import xarray as xr

from attitude.euler import matrix_from_euler
from attitude.matrix import rotation_angle
from attitude.quaternion import matrix_from_quat, quat_from_axis_angle
from chaser.cylindrical import (
    TrackerSettings,
    attitude_crlb,
    attitude_from_three_points,
    calibrate_system,
    control_points_in_cube,
    initialise_tracks,
    measure_points,
    paper_rig,
    point_crlb,
    rig_detections,
    rotation_error_vector,
    track_frame,
)
from experiments.results import ScenarioResult, no_progress
from experiments.scenarios.cylindrical.config import (
    PAPER_MAX_ERR_DEG,
    TABLE1_ERR_MM,
    TABLE1_MM,
    TABLE2_DEG,
    TABLE2_ERR_DEG,
    CameraConfig,
    Config,
)
from vision.cylindrical import CylindricalCamera, measure_spot_centres

__all__ = ["run"]


# ------------------------------------------------------------------------------------ helpers
def _camera(cfg: CameraConfig) -> CylindricalCamera:
    d = CylindricalCamera()
    s = cfg.distortion_scale
    return CylindricalCamera(
        n_pixels=cfg.n_pixels, pixel_pitch_m=cfg.pixel_pitch_um * 1e-6, focal_length_m=cfg.focal_length_mm * 1e-3,
        principal_px=(cfg.n_pixels / 2 + 3.7, cfg.n_pixels / 2 - 3.8),
        k1=tuple(s * k for k in d.k1), k2=tuple(s * k for k in d.k2), bow=tuple(s * k for k in d.bow),
        line_tilt_rad=tuple(s * k for k in d.line_tilt_rad), spot_sigma_px=cfg.spot_sigma_px, peak_dn=cfg.peak_dn,
        read_noise_dn=cfg.read_noise_dn, electrons_per_dn=cfg.electrons_per_dn,
        bits=16 if cfg.peak_dn + d.background_dn >= 4095 else 12,
    )


def _calibrate(cfg: Config, rig, centre_W: np.ndarray, rng: np.random.Generator):
    """004 §4 calibration of ``rig``: control points in the cube at ``centre_W``, then :func:`calibrate_system`."""
    cc = cfg.calibration
    control = control_points_in_cube(cc.n_control_points, centre_W=centre_W, edge_m=cfg.rig.volume_edge_m, rng=rng)
    turntable = dict(rail_distance_m=cc.rail_distance_m, alpha_max_deg=cc.alpha_max_deg,
                     alpha_step_deg=cc.alpha_step_deg, beta_max_deg=cc.beta_max_deg,
                     rail_step_m=cc.rail_step_mm / 1e3, tracker_distance_m=cc.tracker_distance_m,
                     turntable_sigma_rad=cc.turntable_sigma_urad * 1e-6,
                     axis_offset_m=tuple(np.asarray(cc.axis_offset_mm) / 1e3), n_scans=cc.n_scans)
    return calibrate_system(rig, control, rng=rng, turntable=turntable, n_scans=cc.n_scans,
                            extrinsic_method=cc.extrinsic_method, method=cfg.camera.spot_method)


def _led_body(arm_m: float, angle_deg: float) -> np.ndarray:
    """LEDs a, b, c in the body frame of 004 eq (6) (−x_S ∥ ab), centred on their centroid."""
    th = np.deg2rad(angle_deg)
    body = np.array([[arm_m, 0.0, 0.0], [0.0, 0.0, 0.0], [-arm_m * np.cos(th), arm_m * np.sin(th), 0.0]])
    return body - body.mean(0)


def _measure(rig, cameras, X_W, rng, n_scans, method):
    uv_true = rig.true_pixels(X_W)
    uv = np.stack([measure_spot_centres(rig.cameras[c], uv_true[..., c, :], rng=rng, n_scans=n_scans, method=method)
                   for c in range(rig.n_cameras)], -2)
    return measure_points(cameras, uv)


def _wrap_deg(x):
    return (np.asarray(x) + 180.0) % 360.0 - 180.0


def _stats(x) -> dict:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {"max_abs": float("nan"), "rms": float("nan")}
    return {"max_abs": float(np.max(np.abs(x))), "rms": float(np.sqrt(np.mean(x**2)))}


# ------------------------------------------------------------------------------------ run
def run(cfg: Config, *, progress: Callable[[int, int], None] | None = None) -> ScenarioResult:
    """Run the 004 experiments; returns the dataset and a summary (see the module docstring).

    Parameters
    ----------
    cfg : Config
        The validated ``cylindrical_004`` config.
    progress : callable, optional
        ``progress(done, total)`` as calibration, points, attitudes and frames are done.

    Returns
    -------
    ScenarioResult
    """
    progress = progress or no_progress
    ss = np.random.SeedSequence(cfg.seed).spawn(5)
    rng_cal, rng_pts, rng_att, rng_dyn, rng_noise = (np.random.default_rng(s) for s in ss)
    n_dyn = int(round(cfg.dynamic.duration_s * cfg.dynamic.frame_rate_hz)) if cfg.dynamic.enabled else 0
    total = 4 + cfg.attitude.n_trials + n_dyn
    done = 0
    progress(done, total)
    method = cfg.camera.spot_method
    rig = paper_rig(baseline_m=cfg.rig.baseline_m, convergence_deg=cfg.rig.convergence_deg,
                    camera=_camera(cfg.camera))
    centre = np.array([cfg.rig.baseline_m / 2, cfg.rig.volume_centre_depth_m, 0.0])
    cal = _calibrate(cfg, rig, centre, rng_cal)
    cams = cal.cameras
    done += 2
    progress(done, total)

    # stated angular noise: one static source measured 400 times, per channel, through the RBF
    X0 = centre[None].repeat(400, 0)
    uv0 = rig.true_pixels(X0)[:, 0, :]
    noise = {}
    for label, n in (("single_scan", 1), ("averaged", cfg.points.n_scans)):
        ab = cams[0].angles_from_pixels(measure_spot_centres(rig.cameras[0], uv0, rng=rng_noise, n_scans=n,
                                                             method=method))
        noise[label] = float(np.mean(np.std(ab, axis=0)))

    # ---- Table 1 analogue
    X_t = np.asarray(cfg.points.test_points_mm, dtype=float) / 1e3
    fix_t = _measure(rig, cams, X_t, rng_pts, cfg.points.n_scans, method)
    err_t = (fix_t.X_W - X_t) * 1e3
    if cfg.points.n_random:
        X_r = control_points_in_cube(cfg.points.n_random, centre_W=centre, edge_m=cfg.rig.volume_edge_m,
                                     rng=rng_pts)
        fix_r = _measure(rig, cams, X_r, rng_pts, cfg.points.n_scans, method)
        err_r = (fix_r.X_W - X_r) * 1e3
    else:
        X_r = np.zeros((0, 3))
        err_r = np.zeros((0, 3))
    done += 2
    progress(done, total)

    # ---- Table 2 analogue
    ac = cfg.attitude
    poses = np.asarray(ac.poses_deg, dtype=float)
    R_ob = np.swapaxes(matrix_from_euler(np.deg2rad(poses), "312"), -1, -2)  # flag P004-3, docs/papers.md#p004-3
    body = _led_body(ac.arm_mm / 1e3, ac.abc_angle_deg)
    P = centre + np.einsum("kij,pj->kpi", R_ob, body)
    truth = attitude_from_three_points(P[:, 0], P[:, 1], P[:, 2])
    meas = np.full((ac.n_trials, len(poses), 3), np.nan)
    sets = np.zeros((ac.n_trials, len(poses)), dtype=int)
    rot_err = np.full((ac.n_trials, len(poses)), np.nan)
    for k in range(ac.n_trials):
        fix = _measure(rig, cams, P, rng_att, ac.n_scans, method)
        att = attitude_from_three_points(fix.X_W[:, 0], fix.X_W[:, 1], fix.X_W[:, 2])
        meas[k] = np.rad2deg(att.yaw_roll_pitch_rad)
        sets[k] = att.gibbs_set
        rot_err[k] = np.rad2deg(np.linalg.norm(rotation_error_vector(att.R_OS, R_ob), axis=-1))
        done += 1
        progress(done, total)
    att_err = _wrap_deg(meas - poses)
    # Cramér–Rao bound of each pose from the stated (averaged) angle noise, true extrinsics
    pb = point_crlb(rig.R_CW, rig.t_CW, P, noise["averaged"])
    bound = attitude_crlb(P[:, 0], P[:, 1], P[:, 2], pb.covariance_m2[:, 0], pb.covariance_m2[:, 1],
                          pb.covariance_m2[:, 2])

    data = {
        "table1_true_mm": (("point", "axis"), X_t * 1e3),
        "table1_error_mm": (("point", "axis"), err_t),
        "table1_error_norm_mm": (("point",), np.linalg.norm(err_t, axis=-1)),
        "random_true_mm": (("random_point", "axis"), X_r * 1e3),
        "random_error_mm": (("random_point", "axis"), err_r),
        "pose_deg": (("pose", "angle"), poses),
        "pose_rotation_angle_deg": (("pose",), np.rad2deg(rotation_angle(R_ob))),
        "pose_truth_recovered_deg": (("pose", "angle"), _wrap_deg(np.rad2deg(truth.yaw_roll_pitch_rad))),
        "attitude_rotation_error_deg": (("trial", "pose"), rot_err),
        "attitude_rotation_bound_deg": (("pose",), np.rad2deg(bound.rotation_rms_rad)),
        "attitude_euler_bound_deg": (("pose", "angle"), np.rad2deg(bound.euler_sigma_rad)),
        "attitude_measured_deg": (("trial", "pose", "angle"), meas),
        "attitude_error_deg": (("trial", "pose", "angle"), att_err),
        "gibbs_set": (("trial", "pose"), sets),
    }
    if len(X_t) == len(TABLE1_MM) and np.allclose(X_t * 1e3, TABLE1_MM):
        data["paper_table1_error_mm"] = (("point", "component"), np.asarray(TABLE1_ERR_MM))
    n_paper = min(len(poses), len(TABLE2_DEG))
    if np.allclose(poses[:n_paper], TABLE2_DEG[:n_paper]):
        pe = np.full((len(poses), 3), np.nan)
        pe[:n_paper] = np.asarray(TABLE2_ERR_DEG)[:n_paper]
        data["paper_attitude_error_deg"] = (("pose", "angle"), pe)
    summary = {
        "angle_noise_single_scan_urad": noise["single_scan"] * 1e6,
        "angle_noise_averaged_urad": noise["averaged"] * 1e6,
        "n_scans_static": cfg.points.n_scans,
        "rbf_samples": [c.intrinsic.n_samples for c in cams],
        "rbf_holdout_rms_urad": [c.intrinsic.holdout_rms_rad * 1e6 for c in cams],
        "extrinsic_rms_residual_urad": [e.rms_residual_rad * 1e6 for e in cal.extrinsics],
        "table1_max_error_mm": float(np.max(np.linalg.norm(err_t, axis=-1))),
        "table1_mean_error_mm": float(np.mean(np.linalg.norm(err_t, axis=-1))),
        "table1_axis_rms_mm": np.sqrt(np.mean(err_t**2, axis=0)).tolist(),
        "random_points": int(len(X_r)),
        "random_max_error_mm": float(np.max(np.linalg.norm(err_r, axis=-1))) if len(X_r) else float("nan"),
        "random_rms_error_mm": float(np.sqrt(np.mean(np.sum(err_r**2, -1)))) if len(X_r) else float("nan"),
        "random_axis_rms_mm": np.sqrt(np.mean(err_r**2, axis=0)).tolist() if len(X_r) else [],
        "attitude_rotation_error_max_deg": float(np.max(rot_err)),
        "attitude_rotation_error_rms_deg": float(np.sqrt(np.mean(rot_err**2))),
        "attitude_rotation_bound_rms_deg": float(np.sqrt(np.mean(bound.rotation_rms_rad**2)) * 180 / np.pi),
        "attitude_max_error_trial0_deg": np.max(np.abs(att_err[0]), axis=0).tolist(),
        "attitude_max_error_all_trials_deg": np.max(np.abs(att_err), axis=(0, 1)).tolist(),
        "attitude_rms_error_deg": np.sqrt(np.mean(att_err**2, axis=(0, 1))).tolist(),
        "paper_max_error_deg": PAPER_MAX_ERR_DEG,
        "switched_poses": [int(k) for k in np.flatnonzero(np.any(sets != 0, axis=0))],
    }

    coords = {"axis": ["x", "y", "z"], "angle": ["yaw", "roll", "pitch"], "point": np.arange(len(X_t)),
              "random_point": np.arange(len(X_r)), "pose": np.arange(1, len(poses) + 1),
              "trial": np.arange(ac.n_trials), "component": ["dx", "dy", "dz", "dxyz"]}

    # ---- dynamic test
    if cfg.dynamic.enabled:
        dc = cfg.dynamic
        t = np.arange(n_dyn) / dc.frame_rate_hz
        axis = np.asarray(dc.spin_axis, dtype=float) / np.linalg.norm(dc.spin_axis)
        R = matrix_from_quat(quat_from_axis_angle(axis, np.deg2rad(dc.spin_rate_deg_s) * t))
        c_t = centre + np.asarray(dc.drift_mm_s) / 1e3 * t[:, None]
        Pd = c_t[:, None, :] + np.einsum("tij,pj->tpi", R, _led_body(dc.arm_mm / 1e3, ac.abc_angle_deg))
        uv = rig.true_pixels(Pd)  # (T, K, C, 2)
        settings = TrackerSettings(accel_psd_m2_s3=dc.accel_psd_m2_s3, angle_sigma_rad=dc.angle_sigma_urad * 1e-6,
                                   overlap_px=dc.overlap_px)
        n_lit = min(6, n_dyn - 1)
        lit = []
        for f in range(n_lit):
            on = np.arange(3) == f % 3
            lit.append((f % 3, t[f], rig_detections(rig, Pd[f], rng=rng_dyn, lit=on, method=method)))
        K = 3
        est = np.full((n_dyn, K, 3), np.nan)
        measured = np.zeros((n_dyn, K), bool)
        n_planes = np.zeros((n_dyn, K), int)
        dropped = np.zeros((n_dyn, K), int)
        identity_ok = np.ones(n_dyn, bool)
        wrong_assoc = np.zeros(n_dyn, int)
        status = "ok"
        try:
            state = initialise_tracks(cams, K, lit, settings=settings)
        except ValueError as exc:
            status = f"initialisation failed: {exc}"
            state = None
        done += n_lit
        progress(done, total)
        for f in range(n_lit, n_dyn):
            if state is None:
                break
            det = rig_detections(rig, Pd[f], rng=rng_dyn, method=method)
            res = track_frame(cams, state, det, t[f], settings=settings)
            state = res.state
            est[f] = state.position_W
            measured[f] = res.ok
            n_planes[f] = res.n_planes
            dropped[f] = res.overlapped.sum(axis=(1, 2))
            d = np.linalg.norm(state.position_W[:, None, :] - Pd[f][None], axis=-1)
            identity_ok[f] = bool(np.all(np.argmin(d, axis=1) == np.arange(K)))
            for c in range(rig.n_cameras):
                for ch in range(2):
                    pos = det[c][ch].position_px
                    for k in range(K):
                        j = res.spot_index[k, c, ch]
                        if j >= 0 and j != int(np.argmin(np.abs(pos - uv[f, k, c, ch]))):
                            wrong_assoc[f] += 1
            done += 1
            if f % 20 == 0 or f == n_dyn - 1:
                progress(done, total)
        crossings = 0
        for i in range(K):
            for j in range(i + 1, K):
                crossings += int(np.sum(np.diff(np.sign(uv[:, i] - uv[:, j]), axis=0) != 0))
        track_err = np.linalg.norm(est - Pd, axis=-1) * 1e3
        coords.update({"time_s": t, "target": ["a", "b", "c"], "camera": [1, 2], "channel": ["u", "v"]})
        data.update({
            "dyn_true_mm": (("time_s", "target", "axis"), Pd * 1e3),
            "dyn_estimate_mm": (("time_s", "target", "axis"), est * 1e3),
            "dyn_track_error_mm": (("time_s", "target"), track_err),
            "dyn_uv_true_px": (("time_s", "target", "camera", "channel"), uv),
            "dyn_measured": (("time_s", "target"), measured.astype(np.int8)),
            "dyn_n_planes": (("time_s", "target"), n_planes),
            "dyn_dropped_channels": (("time_s", "target"), dropped),
            "dyn_identity_ok": (("time_s",), identity_ok.astype(np.int8)),
            "dyn_wrong_associations": (("time_s",), wrong_assoc),
        })
        after = slice(n_lit, n_dyn)
        summary.update({
            "dynamic_status": status,
            "dynamic_frames": n_dyn,
            "dynamic_spot_crossings": crossings,
            "dynamic_identity_swaps": int(np.sum(~identity_ok[after])),
            "dynamic_wrong_associations": int(np.sum(wrong_assoc)),
            "dynamic_dropped_channels": int(np.sum(dropped)),
            "dynamic_coasting_target_frames": int(np.sum(~measured[after])),
            "dynamic_track_error_max_mm": float(np.nanmax(track_err[after])) if n_dyn > n_lit else float("nan"),
            "dynamic_track_error_rms_mm": float(np.sqrt(np.nanmean(track_err[after] ** 2)))
            if n_dyn > n_lit else float("nan"),
        })
    progress(total, total)
    ds = xr.Dataset({k: xr.DataArray(v[1], dims=v[0]) for k, v in data.items()},
                    coords={k: v for k, v in coords.items() if any(k in d[0] for d in data.values())})
    units = {"_mm": "mm", "_deg": "deg", "_px": "px"}
    for name in ds.data_vars:
        for suffix, unit in units.items():
            if name.endswith(suffix):
                ds[name].attrs["units"] = unit
    ds.attrs["angle_noise_single_scan_urad"] = summary["angle_noise_single_scan_urad"]
    ds.attrs["angle_noise_averaged_urad"] = summary["angle_noise_averaged_urad"]
    ds.attrs["attitude_error"] = ("rotation angle of R_est R_true^T first (no gimbal-lock amplification); "
                                  "yaw/roll/pitch are the paper's reading")
    ds.attrs["euler_sequence"] = "3-1-2 (yaw z, roll x, pitch y), corrected 004 eq 9-11 (flag P004-3)"
    return ScenarioResult(ds, summary)
