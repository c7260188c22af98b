"""Scenario kind ``tof_000``: paper 000, TOF-camera pose of a cooperative marker target.

Three studies in one run (each optional but the first):

* ``static`` — the target held at ``target.distance_m`` and ``target.attitude_deg``; ``frames``
  independent TOF frames (:func:`vision.tof.render_tof_frame`, SR4000 model) through the pipeline
  (:func:`chaser.tof.estimate_tof_pose`) once per range estimator; the statistics of 000 Table 1
  (mean, max, min, range of x, y, z, pitch, yaw, roll) plus the RMS errors against the truth;
* ``sweep`` — the same with one Euler angle offset at a time over ``angles_deg``: attitude and
  position error against the angle;
* ``matching`` — a Monte Carlo of the marker matchers (the check of the 000 matcher in
  docs/tof.md): ``trials`` random matching problems per case (all markers, one missing, one
  spurious point in the volume or on the plate, both) for each matcher, raw and after the pose
  verification.

Pitch, yaw, roll: 3-2-1 angles of ``R_SC = R_z(yaw) R_y(pitch) R_x(roll)`` (docs/tof.md).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import xarray as xr

from attitude.euler import matrix_from_euler
from attitude.matrix import rotation_angle
from chaser.tof import (
    ExtractionSettings,
    MatchSettings,
    estimate_tof_pose,
    match_markers_hungarian,
    match_markers_mrf,
    match_markers_mrf_literal,
    random_matching_trials,
    verify_labels,
)
from experiments.results import ScenarioResult, no_progress
from experiments.scenarios.tof.config import MATCHING_CASES, Config, SweepConfig
from vision.tof import CooperativeTarget, default_marker_plate, render_tof_frame, sr4000

__all__ = ["run", "TABLE1_000", "COLUMNS", "table1_stats"]

#: 000 Table 1 (static repeatability at 700 mm), as printed.
TABLE1_000 = {
    "mean": [2.19304, -10.4574, 697.6061, -0.38269, -2.65386, -2.52849],
    "max": [2.39902, -10.3149, 699.269, -0.0559321, -2.45633, -2.45434],
    "min": [2.02194, -10.6381, 695.158, -0.646128, -2.85154, -2.61353],
    "range": [0.37708, 0.3232, 4.111, 0.59019, 0.3952, 0.15919],
}
COLUMNS = ("x_mm", "y_mm", "z_mm", "pitch_deg", "yaw_deg", "roll_deg")


def _R_from_pyr_deg(pyr_deg) -> np.ndarray:
    p, y, r = np.radians(pyr_deg)
    return matrix_from_euler([y, p, r], "321")


def table1_stats(values: np.ndarray) -> dict[str, list[float]]:
    """Mean, max, min and range (max − min) over the frames of ``values (frames, 6)``, NaN-aware."""
    v = np.asarray(values, dtype=float)
    mx, mn = np.nanmax(v, axis=0), np.nanmin(v, axis=0)
    return {"mean": np.nanmean(v, axis=0).tolist(), "max": mx.tolist(), "min": mn.tolist(),
            "range": (mx - mn).tolist()}


def _pose_row(res, R_true: np.ndarray, r_true: np.ndarray) -> tuple[list[float], float, float]:
    if not res.ok:
        return [np.nan] * 6, np.nan, np.nan
    row = list(res.r_CS_S * 1e3) + list(res.pitch_yaw_roll_deg)
    att = float(np.degrees(rotation_angle(res.R_SC @ R_true.T)))
    pos = float(np.linalg.norm(res.r_CS_S - r_true) * 1e3)
    return row, att, pos


def run(cfg: Config, *, progress: Callable[[int, int], None] | None = None) -> ScenarioResult:
    """Run the static study, and the sweep and matching studies when configured.

    Parameters
    ----------
    cfg : Config
        The validated ``tof_000`` config.
    progress : callable, optional
        ``progress(done, total)`` after each frame or matching case.

    Returns
    -------
    ScenarioResult
        Per-frame poses and errors (``failure_reason`` per estimator and frame), the sweep and
        matching arrays when configured, and the Table 1 summary.
    """
    progress = progress or no_progress
    camera = sr4000()
    plate = default_marker_plate()
    target = CooperativeTarget(plate=plate, standoff_m=cfg.target.standoff_m,
                               body_reflectivity=cfg.target.body_reflectivity)
    st = MatchSettings(alpha_m=cfg.pipeline.alpha_m)
    ests = list(cfg.pipeline.range_estimators)
    seeds = np.random.SeedSequence(cfg.seed).spawn(3)
    r_true = np.array([*cfg.target.lateral_offset_m, cfg.target.distance_m])
    R_true = _R_from_pyr_deg(cfg.target.attitude_deg)

    n_static = cfg.static.frames
    n_sweep = 0 if not isinstance(cfg.sweep, SweepConfig) else len(cfg.sweep.axes) * len(cfg.sweep.angles_deg) * cfg.sweep.frames_per_angle
    n_match = 0 if cfg.matching is None else len(cfg.matching.cases)
    total, done = n_static + n_sweep + n_match, 0

    def pose(frame, est):
        return estimate_tof_pose(frame, camera, plate, matcher=cfg.pipeline.matcher, match_settings=st,
                                 extraction=ExtractionSettings(range_estimator=est, centre_estimator=cfg.pipeline.centre_estimator),
                                 gate_factor=cfg.pipeline.gate_factor, weighting=cfg.pipeline.weighting,
                                 pose_estimator=cfg.pipeline.pose_estimator)

    # ---- static repeatability (000 Table 1)
    vals = np.full((len(ests), n_static, 6), np.nan)
    att = np.full((len(ests), n_static), np.nan)
    pos = np.full((len(ests), n_static), np.nan)
    n_matched = np.zeros((len(ests), n_static), dtype=int)
    reason = np.full((len(ests), n_static), "", dtype=object)
    for i, s in enumerate(seeds[0].spawn(n_static)):
        frame = render_tof_frame(camera, target, R_true, r_true, rng=np.random.default_rng(s),
                                 supersample=cfg.camera.supersample, ambient_dn=cfg.camera.ambient_dn)
        for e, est in enumerate(ests):
            res = pose(frame, est)
            vals[e, i], att[e, i], pos[e, i] = _pose_row(res, R_true, r_true)
            n_matched[e, i], reason[e, i] = res.n_matched, res.failure_reason
            if i == 0 and e == 0:
                example = (frame, res)
        done += 1
        progress(done, total)
    ds = xr.Dataset(
        {c: (("estimator", "frame"), vals[..., k], {"units": c.rsplit("_", 1)[1]}) for k, c in enumerate(COLUMNS)},
        coords={"estimator": ests, "frame": np.arange(n_static)},
    )
    ds["attitude_error_deg"] = (("estimator", "frame"), att, {"units": "deg", "long_name": "rotation angle of R_est R_true^T"})
    ds["position_error_mm"] = (("estimator", "frame"), pos, {"units": "mm"})
    ds["n_matched"] = (("estimator", "frame"), n_matched)
    ds["failure_reason"] = (("estimator", "frame"), reason.astype(str))
    frame0, res0 = example
    ds["example_amplitude_dn"] = (("v_px", "u_px"), frame0.amplitude_dn, {"units": "DN", "long_name": "frame 0 amplitude"})
    ds["example_range_m"] = (("v_px", "u_px"), frame0.range_m, {"units": "m", "long_name": "frame 0 radial range"})
    ds["example_keypoint_uv_px"] = (("keypoint", "uv"), res0.detections.uv_px, {"units": "px"})
    ds["example_keypoint_label"] = (("keypoint",), res0.labels)
    summary: dict = {"distance_m": cfg.target.distance_m, "attitude_deg": list(cfg.target.attitude_deg),
                     "frames": n_static, "camera": camera.name, "euler": "3-2-1, R_SC = Rz(yaw) Ry(pitch) Rx(roll)"}
    for e, est in enumerate(ests):
        summary[f"table1_{est}"] = table1_stats(vals[e])
        summary[f"rms_attitude_error_deg_{est}"] = float(np.sqrt(np.nanmean(att[e] ** 2)))
        summary[f"rms_position_error_mm_{est}"] = float(np.sqrt(np.nanmean(pos[e] ** 2)))
        summary[f"found_fraction_{est}"] = float(np.mean(reason[e] == ""))

    # ---- attitude sweep
    if isinstance(cfg.sweep, SweepConfig):
        sw = cfg.sweep
        sh = (len(ests), len(sw.axes), len(sw.angles_deg), sw.frames_per_angle)
        s_att, s_pos = np.full(sh, np.nan), np.full(sh, np.nan)
        s_seeds = seeds[1].spawn(len(sw.axes) * len(sw.angles_deg))
        for a, axis in enumerate(sw.axes):
            for g, ang in enumerate(sw.angles_deg):
                pyr = np.array(cfg.target.attitude_deg, dtype=float)
                pyr[("pitch", "yaw", "roll").index(axis)] += ang
                R = _R_from_pyr_deg(pyr)
                frame_rng = np.random.default_rng(s_seeds[a * len(sw.angles_deg) + g])
                for j in range(sw.frames_per_angle):
                    frame = render_tof_frame(camera, target, R, r_true, rng=frame_rng,
                                             supersample=cfg.camera.supersample, ambient_dn=cfg.camera.ambient_dn)
                    for e, est in enumerate(ests):
                        _, s_att[e, a, g, j], s_pos[e, a, g, j] = _pose_row(pose(frame, est), R, r_true)
                    done += 1
                    progress(done, total)
        dims = ("estimator", "sweep_axis", "sweep_angle_deg", "sweep_frame")
        ds = ds.assign_coords(sweep_axis=list(sw.axes), sweep_angle_deg=list(sw.angles_deg),
                              sweep_frame=np.arange(sw.frames_per_angle))
        ds["sweep_attitude_error_deg"] = (dims, s_att, {"units": "deg"})
        ds["sweep_position_error_mm"] = (dims, s_pos, {"units": "mm"})
        for e, est in enumerate(ests):
            summary[f"sweep_rms_attitude_error_deg_{est}"] = float(np.sqrt(np.nanmean(s_att[e] ** 2)))
            summary[f"sweep_max_attitude_error_deg_{est}"] = float(np.nanmax(s_att[e]))
            summary[f"sweep_found_fraction_{est}"] = float(np.mean(np.isfinite(s_att[e])))

    # ---- matching Monte Carlo
    if cfg.matching is not None:
        mc = cfg.matching
        model = plate.markers_C
        raw = np.zeros((len(mc.cases), len(mc.matchers), mc.trials), dtype=bool)
        ver = np.zeros_like(raw)
        gate = cfg.pipeline.gate_factor * cfg.pipeline.alpha_m
        for c, (case, s) in enumerate(zip(mc.cases, seeds[2].spawn(len(mc.cases)), strict=True)):
            t = random_matching_trials(plate, mc.trials, noise_m=mc.noise_m, rng=np.random.default_rng(s),
                                       **MATCHING_CASES[case])
            for k, name in enumerate(mc.matchers):
                labels = _match(name, model, t.points_S, st)
                raw[c, k] = np.all(labels == t.truth, axis=-1)
                ver[c, k] = np.all(verify_labels(model, t.points_S, labels, gate_m=gate) == t.truth, axis=-1)
            done += 1
            progress(done, total)
        ds = ds.assign_coords(case=list(mc.cases), matcher=list(mc.matchers), trial=np.arange(mc.trials))
        ds["labels_correct"] = (("case", "matcher", "trial"), raw, {"long_name": "all labels correct, matcher alone"})
        ds["labels_correct_verified"] = (("case", "matcher", "trial"), ver,
                                         {"long_name": "all labels correct after the pose verification"})
        ds.attrs["matching_noise_m"] = mc.noise_m
        summary["matching_trials"] = mc.trials
        summary["matching_success_rate"] = {
            case: {name: {"raw": float(raw[c, k].mean()), "verified": float(ver[c, k].mean())}
                   for k, name in enumerate(mc.matchers)} for c, case in enumerate(mc.cases)}
    ds.attrs["title"] = cfg.title
    ds.attrs["camera"] = camera.name
    ds.attrs["euler_sequence"] = "3-2-1: R_SC = Rz(yaw) Ry(pitch) Rx(roll); yaw about the boresight z_S"
    ds.attrs["truth_r_CS_S_mm"] = (r_true * 1e3).tolist()
    ds.attrs["truth_pitch_yaw_roll_deg"] = list(cfg.target.attitude_deg)
    return ScenarioResult(dataset=ds, summary=summary)


def _match(name: str, model: np.ndarray, points: np.ndarray, st: MatchSettings) -> np.ndarray:
    import dataclasses

    if name == "mrf":
        return match_markers_mrf(model, points, settings=st).labels
    if name == "mrf-sinkhorn":
        return match_markers_mrf(model, points, settings=dataclasses.replace(st, sinkhorn=True)).labels
    if name == "mrf-quadratic":
        return match_markers_mrf(model, points, settings=dataclasses.replace(st, truncation=None)).labels
    if name == "mrf-literal":
        return match_markers_mrf_literal(model, points, alpha_m=st.alpha_m).labels
    return match_markers_hungarian(model, points, alpha_m=st.alpha_m, truncation=st.truncation or 2.0).labels
