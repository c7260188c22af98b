"""The ``envelope`` sweep cell of ``cylindrical_004``: accuracy and availability over the measuring volume.

One cell is one rig (``rig.baseline_m``, ``rig.convergence_deg``, the swept keys): it is calibrated
once (turntable RBF intrinsics, control-point extrinsics in the cube at ``rig.volume_centre_depth_m``,
as in 004 §4), then a three-LED target is placed at every (depth, lateral offset) of ``[envelope]``
in each of the config's attitude poses and measured once per trial (spot noise, ``attitude.n_scans``
scans).  Metrics per position:

* the 3-D point error of the LEDs and its Cramér–Rao bound (:func:`chaser.cylindrical.point_crlb`,
  from the measured per-channel angle noise);
* the attitude error as the rotation angle of ``R̂_OS R_OSᵀ`` (free of any Euler singularity) and as
  the paper's 3-1-2 yaw/roll/pitch (corrected eq 9–11), each with its bound
  (:func:`chaser.cylindrical.attitude_crlb`);
* the scatter over trials about the mean (the noise part, what the bound bounds: the mean is the
  bias of the cell's one calibration) and the fraction of LED fixes available (both cameras see the
  LED inside their calibrated field).

Random streams: trial ``t`` measures with the first child of its seed; the calibration uses the
second child of trial 0's seed, so all trials of a cell share one calibration draw.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from attitude.euler import matrix_from_euler
from chaser.cylindrical import (
    attitude_crlb,
    attitude_from_three_points,
    paper_rig,
    point_crlb,
    rotation_error_vector,
)
from experiments.scenarios.cylindrical.config import Config
from experiments.scenarios.cylindrical.experiment import (
    _calibrate,
    _camera,
    _led_body,
    _measure,
    _wrap_deg,
)
from experiments.sweep import Metric, SweepCell, child_seeds
from vision.cylindrical import measure_spot_centres

__all__ = ["envelope_cell", "envelope_sweep_cell", "ANGLES"]

#: the Euler angles of the corrected eq 9–11, in their order
ANGLES = ("yaw", "roll", "pitch")


def _angle_sigma_rad(rig, cams, centre_W, rng, n_scans, method, repeats=400):
    """Per-channel angle noise ``(C, 2)`` rad: one static LED at ``centre_W`` measured ``repeats`` times."""
    uv = rig.true_pixels(np.broadcast_to(centre_W, (repeats, 3)))
    out = []
    for c, cam in enumerate(cams):
        ab = cam.angles_from_pixels(measure_spot_centres(rig.cameras[c], uv[:, c, :], rng=rng, n_scans=n_scans,
                                                         method=method))
        out.append(np.std(ab, axis=0, ddof=1))
    return np.array(out)


def _scatter(x: np.ndarray) -> np.ndarray:
    """``sqrt(trace cov)`` over the leading trial axis of vectors ``(trials, ..., 3)``; NaN with < 2 finite."""
    n = np.sum(np.all(np.isfinite(x), -1), axis=0)
    with np.errstate(invalid="ignore"):
        var = np.nanvar(x, axis=0, ddof=1).sum(-1)
    return np.where(n >= 2, np.sqrt(var), np.nan)


def envelope_cell(cfg: Config, seeds: Sequence[np.random.SeedSequence]) -> dict[str, np.ndarray]:
    """:func:`_envelope_cell` with the empty-slice warnings of unavailable positions silenced."""
    with warnings.catch_warnings():
        return _envelope_cell(cfg, seeds)


def _envelope_cell(cfg: Config, seeds: Sequence[np.random.SeedSequence]) -> dict[str, np.ndarray]:
    """Evaluate one rig over the positions of ``cfg.envelope`` (see the module docstring).

    Returns
    -------
    dict of arrays
        Per trial: ``point_error_rms_mm`` (depth, offset), ``available`` (depth, offset),
        ``rotation_error_deg`` and the signed ``yaw_error_deg``, ``roll_error_deg``, ``pitch_error_deg``
        (depth, offset, pose).  Per cell: ``point_crlb_mm``, ``point_scatter_mm``, ``rotation_crlb_deg``,
        ``rotation_scatter_deg``, ``{yaw,roll,pitch}_crlb_deg`` and ``_scatter_deg`` (standard deviation
        over trials), and ``angle_sigma_urad``.
    """
    method = cfg.camera.spot_method
    rig = paper_rig(baseline_m=cfg.rig.baseline_m, convergence_deg=cfg.rig.convergence_deg,
                    camera=_camera(cfg.camera))
    centre_cal = np.array([cfg.rig.baseline_m / 2, cfg.rig.volume_centre_depth_m, 0.0])
    rng_cal = np.random.default_rng(child_seeds(seeds[0], 2)[1])
    cams = _calibrate(cfg, rig, centre_cal, rng_cal).cameras
    n_scans = cfg.attitude.n_scans
    sigma = _angle_sigma_rad(rig, cams, centre_cal, rng_cal, n_scans, method)

    ev = cfg.envelope
    D, O = np.meshgrid(np.asarray(ev.depths_m), np.asarray(ev.offsets_m), indexing="ij")
    pos = np.stack([cfg.rig.baseline_m / 2 + O, D, np.zeros_like(D)], -1)  # (nd, no, 3)
    poses = np.asarray(cfg.attitude.poses_deg, dtype=float)
    R_ob = np.swapaxes(matrix_from_euler(np.deg2rad(poses), "312"), -1, -2)  # flag P004-3
    body = _led_body(cfg.attitude.arm_mm / 1e3, cfg.attitude.abc_angle_deg)
    P = pos[:, :, None, None, :] + np.einsum("kij,pj->kpi", R_ob, body)  # (nd, no, pose, led, 3)
    R_true = np.broadcast_to(R_ob, P.shape[:3] + (3, 3))

    T = len(seeds)
    shape = P.shape[:3]
    pt_err = np.full((T,) + shape + (3, 3), np.nan)
    rot_vec = np.full((T,) + shape + (3,), np.nan)
    euler = np.full((T,) + shape + (3,), np.nan)
    avail = np.zeros((T,) + shape[:2])
    for t, ss in enumerate(seeds):
        rng = np.random.default_rng(child_seeds(ss, 2)[0])
        fix = _measure(rig, cams, P, rng, n_scans, method)
        pt_err[t] = fix.X_W - P
        avail[t] = fix.ok.mean(axis=(-1, -2))
        att = attitude_from_three_points(fix.X_W[..., 0, :], fix.X_W[..., 1, :], fix.X_W[..., 2, :])
        good = att.ok
        rot_vec[t] = np.where(good[..., None], rotation_error_vector(np.where(good[..., None, None], att.R_OS,
                                                                               np.eye(3)), R_true), np.nan)
        euler[t] = np.where(good[..., None], _wrap_deg(np.rad2deg(att.yaw_roll_pitch_rad) - poses), np.nan)

    warnings.simplefilter("ignore", RuntimeWarning)  # empty slices where no LED is seen: NaN, as meant
    with np.errstate(invalid="ignore"):
        pt_rms = np.sqrt(np.nanmean(np.sum(pt_err**2, -1), axis=(-1, -2))) * 1e3
    seen = np.all(np.isfinite(rig.true_pixels(P)), axis=(-1, -2))  # (nd, no, pose, led): in both fields
    pb = point_crlb(rig.R_CW, rig.t_CW, P, sigma)
    trace = np.where(seen & pb.ok, np.trace(pb.covariance_m2, axis1=-2, axis2=-1), np.nan)
    with np.errstate(invalid="ignore"):
        pt_crlb = np.sqrt(np.nanmean(trace, axis=(-1, -2))) * 1e3
        pt_scatter = np.sqrt(np.nanmean(_scatter(pt_err) ** 2, axis=(-1, -2))) * 1e3
    cov = np.where(np.isfinite(pb.covariance_m2), pb.covariance_m2, 0.0)
    ab = attitude_crlb(P[..., 0, :], P[..., 1, :], P[..., 2, :], cov[..., 0, :, :], cov[..., 1, :, :],
                       cov[..., 2, :, :])
    all_seen = np.all(seen & pb.ok, axis=-1)
    rot_crlb = np.where(all_seen, np.rad2deg(ab.rotation_rms_rad), np.nan)
    eul_crlb = np.where(all_seen[..., None], np.rad2deg(ab.euler_sigma_rad), np.nan)
    n_ok = np.sum(np.isfinite(euler), axis=0)
    with np.errstate(invalid="ignore"):
        eul_scatter = np.where(n_ok >= 2, np.nanstd(euler, axis=0, ddof=1), np.nan)
    out = {
        "point_error_rms_mm": pt_rms,
        "available": avail,
        "rotation_error_deg": np.rad2deg(np.linalg.norm(rot_vec, axis=-1)),
        "point_crlb_mm": pt_crlb,
        "point_scatter_mm": pt_scatter,
        "rotation_crlb_deg": rot_crlb,
        "rotation_scatter_deg": np.rad2deg(_scatter(rot_vec)),
        "angle_sigma_urad": np.asarray(np.mean(sigma) * 1e6),
        "failure_reason": np.array([""] * T, dtype=object),
    }
    for k, name in enumerate(ANGLES):
        out[f"{name}_error_deg"] = euler[..., k]
        out[f"{name}_crlb_deg"] = eul_crlb[..., k]
        out[f"{name}_scatter_deg"] = eul_scatter[..., k]
    return out


def envelope_sweep_cell(cfg: Config) -> SweepCell:
    """The ``envelope`` sweep cell (:func:`envelope_cell`) with its metrics and position coordinates."""
    pos, pp = ("depth_m", "offset_m"), ("depth_m", "offset_m", "pose")
    return SweepCell(
        fn=envelope_cell,
        metrics={
            "point_error_rms_mm": Metric("mm", pos, long_name="RMS 3-D error of the LEDs over the poses"),
            "available": Metric("1", pos, long_name="fraction of LED fixes with three independent planes"),
            "rotation_error_deg": Metric("deg", pp, long_name="rotation angle of R_est R_true^T"),
            "point_crlb_mm": Metric("mm", pos, per_trial=False, long_name="Cramer-Rao RMS bound of the 3-D error"),
            "point_scatter_mm": Metric("mm", pos, per_trial=False,
                                       long_name="RMS scatter of the 3-D error about its mean over trials"),
            "rotation_crlb_deg": Metric("deg", pp, per_trial=False,
                                        long_name="Cramer-Rao RMS bound of the rotation-angle error"),
            "rotation_scatter_deg": Metric("deg", pp, per_trial=False,
                                           long_name="RMS scatter of the rotation-vector error about its mean"),
            "angle_sigma_urad": Metric("urad", per_trial=False, long_name="per-channel angle noise of the cell"),
            **{f"{a}_{what}_deg": Metric("deg", pp, per_trial=what == "error", long_name=f"{a} (3-1-2, corrected "
                                         f"eq 9-11): {text}")
               for a in ANGLES for what, text in (("error", "signed error"), ("crlb", "Cramer-Rao sigma"),
                                                  ("scatter", "standard deviation over trials"))},
        },
        coords={"depth_m": np.asarray(cfg.envelope.depths_m, dtype=float),
                "offset_m": np.asarray(cfg.envelope.offsets_m, dtype=float),
                "pose": np.arange(1, len(cfg.attitude.poses_deg) + 1)},
        coord_units={"depth_m": "m", "offset_m": "m", "pose": "1"},
        name="envelope",
    )
