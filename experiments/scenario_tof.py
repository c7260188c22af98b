"""Scenario kind ``tof_000``: paper 000, TOF-camera pose of a cooperative marker target.

Three studies in one run (each optional but the first):

* ``static`` — the target held at ``target.distance_m`` and ``target.attitude_deg``; ``frames``
  independent TOF frames (:func:`vision.tof.render_tof_frame`, SR4000 model) through the pipeline
  (:func:`chaser.tof.estimate_tof_pose`) once per range estimator; the statistics of 000 Table 1
  (mean, max, min, range of x, y, z, pitch, yaw, roll) plus the RMS errors against the truth;
* ``sweep`` — the same with one Euler angle offset at a time over ``angles_deg``: attitude and
  position error against the angle;
* ``matching`` — the Monte Carlo of SEEDS_SPEC Appendix A.5: ``trials`` random matching problems
  per case (all markers, one missing, one spurious point in the volume or on the plate, both) for
  each matcher, raw and after the pose verification.

Pitch, yaw, roll: 3-2-1 angles of ``R_SC = R_z(yaw) R_y(pitch) R_x(roll)`` (docs/tof.md).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Literal

import numpy as np
import xarray as xr
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

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
from experiments.results import ScenarioResult
from vision.tof import CooperativeTarget, default_marker_plate, render_tof_frame, sr4000

__all__ = ["Config", "run", "plot", "MATCHING_CASES", "MATCHERS", "TABLE1_000", "table1_stats"]

#: 000 Table 1 (static repeatability at 700 mm), as printed.
TABLE1_000 = {
    "mean": [2.19304, -10.4574, 697.6061, -0.38269, -2.65386, -2.52849],
    "max": [2.39902, -10.3149, 699.269, -0.0559321, -2.45633, -2.45434],
    "min": [2.02194, -10.6381, 695.158, -0.646128, -2.85154, -2.61353],
    "range": [0.37708, 0.3232, 4.111, 0.59019, 0.3952, 0.15919],
}
COLUMNS = ("x_mm", "y_mm", "z_mm", "pitch_deg", "yaw_deg", "roll_deg")

#: matching cases: name → keyword arguments of :func:`chaser.tof.random_matching_trials`
MATCHING_CASES = {
    "all_visible": dict(),
    "one_missing": dict(n_missing=1),
    "one_spurious_volume": dict(n_spurious=1, spurious="volume"),
    "one_spurious_plate": dict(n_spurious=1, spurious="plate"),
    "missing_and_spurious": dict(n_missing=1, n_spurious=1, spurious="volume"),
}
MATCHERS = ("mrf", "mrf-literal", "mrf-sinkhorn", "mrf-quadratic", "hungarian")
Estimator = Literal["plane", "mean"]


class CameraConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")
    model: Literal["sr4000"] = "sr4000"
    ambient_dn: float = Field(0.0, ge=0.0, le=1e6, description="ambient light per pixel (DN)")
    supersample: int = Field(3, ge=1, le=6, description="sub-rays per pixel and axis")


class TargetConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")
    distance_m: float = Field(0.7, description="plate origin on the boresight at this z (m)")
    attitude_deg: tuple[float, float, float] = Field((0.0, 0.0, 0.0), description="pitch, yaw, roll (3-2-1)")
    lateral_offset_m: tuple[float, float] = (0.0, 0.0)
    standoff_m: float = Field(0.05, ge=0.0, le=1.0)
    body_reflectivity: float = Field(0.3, ge=0.0, le=1.0)

    @field_validator("distance_m")
    @classmethod
    def _fits(cls, v: float) -> float:
        # the 0.30 m plate must fit in the 38.8 deg undistorted field of view, and stay inside
        # the 5.0 m unambiguous range
        if not 0.45 <= v <= 4.5:
            raise ValueError("must lie in [0.45, 4.5] m (plate inside the SR4000 field of view and range)")
        return v

    @field_validator("attitude_deg")
    @classmethod
    def _angles(cls, v):
        if any(abs(a) > 75.0 for a in v):
            raise ValueError("each angle must lie in [-75, 75] deg (plate facing the camera)")
        return v


class StaticConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")
    frames: int = Field(200, ge=2, le=100_000)


class SweepConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")
    axes: list[Literal["pitch", "yaw", "roll"]] = ["pitch", "yaw", "roll"]
    angles_deg: list[float] = [-60.0, -45.0, -30.0, -15.0, 0.0, 15.0, 30.0, 45.0, 60.0]
    frames_per_angle: int = Field(5, ge=1, le=10_000)

    @field_validator("angles_deg")
    @classmethod
    def _angles(cls, v):
        if not v or any(abs(a) > 75.0 for a in v):
            raise ValueError("needs at least one angle, each in [-75, 75] deg")
        return v


class MatchingConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")
    trials: int = Field(1000, ge=1, le=1_000_000)
    noise_m: float = Field(0.002, ge=0.0, le=0.05, description="isotropic 3-D point noise (1 sigma)")
    cases: list[Literal[tuple(MATCHING_CASES)]] = list(MATCHING_CASES)
    matchers: list[Literal[MATCHERS]] = ["mrf", "mrf-literal", "hungarian"]


class PipelineConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")
    matcher: Literal["mrf", "mrf-sinkhorn", "mrf-literal", "hungarian"] = "mrf"
    alpha_m: float = Field(0.010, gt=0.0, le=0.2, description="distance-consistency threshold alpha")
    gate_factor: float = Field(2.0, gt=0.0, le=20.0, description="verification gate in units of alpha")
    range_estimators: list[Estimator] = ["plane", "mean"]
    weighting: Literal["inverse_variance", "uniform"] = "inverse_variance"

    @field_validator("range_estimators")
    @classmethod
    def _nonempty(cls, v):
        if not v or len(set(v)) != len(v):
            raise ValueError("needs one or more distinct estimators")
        return v


class Config(BaseModel):
    model_config = ConfigDict(extra="forbid")
    kind: Literal["tof_000"]
    title: str = "000 TOF cooperative-marker pose"
    seed: int = Field(0, ge=0)
    camera: CameraConfig = CameraConfig()
    target: TargetConfig = TargetConfig()
    pipeline: PipelineConfig = PipelineConfig()
    static: StaticConfig = StaticConfig()
    sweep: SweepConfig | None = None
    matching: MatchingConfig | None = None

    @model_validator(mode="after")
    def _fov(self):
        half = self.target.distance_m * np.tan(np.arctan(88.0 / 250.0))
        if max(abs(o) for o in self.target.lateral_offset_m) + 0.15 > half:
            raise ValueError("target.lateral_offset_m: the plate leaves the field of view at this distance")
        return self


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


def run(cfg: Config, *, progress: Callable[[int, int], None]) -> ScenarioResult:
    """Run the static study, and the sweep and matching studies when configured."""
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
    n_sweep = 0 if cfg.sweep is None else len(cfg.sweep.axes) * len(cfg.sweep.angles_deg) * cfg.sweep.frames_per_angle
    n_match = 0 if cfg.matching is None else len(cfg.matching.cases)
    total, done = n_static + n_sweep + n_match, 0

    def pose(frame, est):
        return estimate_tof_pose(frame, camera, plate, matcher=cfg.pipeline.matcher, match_settings=st,
                                 extraction=ExtractionSettings(range_estimator=est),
                                 gate_factor=cfg.pipeline.gate_factor, weighting=cfg.pipeline.weighting)

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
    if cfg.sweep is not None:
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

    # ---- matching Monte Carlo (SEEDS_SPEC A.5)
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


def plot(dataset: xr.Dataset, fig_dir: Path) -> list[Path]:
    """Static repeatability traces, sweep errors and matching success rates, from the dataset."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig_dir = Path(fig_dir)
    out: list[Path] = []
    if "example_amplitude_dn" in dataset:
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        im = axes[0].imshow(dataset["example_amplitude_dn"], cmap="gray")
        fig.colorbar(im, ax=axes[0], label="amplitude (DN)")
        im = axes[1].imshow(dataset["example_range_m"], cmap="viridis")
        fig.colorbar(im, ax=axes[1], label="radial range (m)")
        uv = dataset["example_keypoint_uv_px"].values
        for k, (u, v) in enumerate(uv):
            lab = int(dataset["example_keypoint_label"].values[k])
            axes[0].plot(u, v, "r+", ms=10)
            axes[0].annotate(str(lab) if lab >= 0 else "null", (u, v), xytext=(7, -9), textcoords="offset points",
                             color="gold", fontsize=9, fontweight="bold")
        axes[0].set_title("amplitude, key points and MRF labels (frame 0)")
        axes[1].set_title("range image (NaN: no return / low confidence)")
        fig.tight_layout()
        out.append(fig_dir / "tof_frame.png")
        fig.savefig(out[-1], dpi=110)
        plt.close(fig)

    fig, axes = plt.subplots(2, 3, figsize=(12, 6), sharex=True)
    for ax, c in zip(axes.ravel(), COLUMNS, strict=True):
        for est in dataset["estimator"].values:
            ax.plot(dataset["frame"], dataset[c].sel(estimator=est), ".", ms=3, label=str(est))
        ax.set_title(c.replace("_", " / "))
        ax.set_xlabel("frame")
    axes[0, 0].legend(title="range estimator")
    fig.suptitle("000 Table 1 reproduction: static target, repeated frames")
    fig.tight_layout()
    out.append(fig_dir / "tof_static.png")
    fig.savefig(out[-1], dpi=110)
    plt.close(fig)

    if "sweep_attitude_error_deg" in dataset:
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        for est in dataset["estimator"].values:
            for axis in dataset["sweep_axis"].values:
                sel = dict(estimator=est, sweep_axis=axis)
                for ax, var in zip(axes, ("sweep_attitude_error_deg", "sweep_position_error_mm"), strict=True):
                    rms = np.sqrt((dataset[var].sel(sel) ** 2).mean("sweep_frame"))
                    ax.plot(dataset["sweep_angle_deg"], rms, "o-" if est == "plane" else "s--", label=f"{axis}, {est}")
        axes[0].set_ylabel("RMS attitude error (deg)")
        axes[1].set_ylabel("RMS position error (mm)")
        for ax in axes:
            ax.set_xlabel("offset of one Euler angle (deg)")
            ax.set_yscale("log")
        axes[0].legend(fontsize=7)
        fig.tight_layout()
        out.append(fig_dir / "tof_sweep.png")
        fig.savefig(out[-1], dpi=110)
        plt.close(fig)

    if "labels_correct" in dataset:
        cases, matchers = dataset["case"].values, dataset["matcher"].values
        fig, axes = plt.subplots(1, 2, figsize=(12, 4), sharey=True)
        w = 0.8 / len(matchers)
        for ax, var in zip(axes, ("labels_correct", "labels_correct_verified"), strict=True):
            rate = dataset[var].mean("trial")
            for k, m in enumerate(matchers):
                ax.bar(np.arange(len(cases)) + k * w, 100 * rate.sel(matcher=m), w, label=str(m))
            ax.set_xticks(np.arange(len(cases)) + 0.4 - w / 2, [str(c).replace("_", "\n") for c in cases], fontsize=7)
            ax.set_title(var.replace("_", " "))
        axes[0].set_ylabel(f"trials with all labels correct (%), n = {dataset.sizes['trial']}")
        axes[0].legend(fontsize=7)
        fig.tight_layout()
        out.append(fig_dir / "tof_matching.png")
        fig.savefig(out[-1], dpi=110)
        plt.close(fig)
    return out
