"""The working envelope of the 000 TOF pose: the ``envelope`` sweep cell and its maps.

One cell is one (``target.distance_m``, ``target.off_boresight_deg``) point; each trial renders one
SR4000 frame (:func:`vision.tof.render_tof_frame`) of the plate at ``R_true = Rot(a_φ, θ) R(attitude_deg)``
with ``θ`` the off-boresight angle and ``a_φ = (cos φ, sin φ, 0)_S`` an axis in the image plane at a
random azimuth ``φ`` per trial, and runs :func:`chaser.tof.estimate_tof_pose`.  Per trial: attitude
and position error against the truth, the Cramér–Rao bound of that pose from the markers it was
made from (:func:`chaser.tof.bound.tof_pose_bound` with :func:`chaser.tof.bound.sr4000_marker_noise`;
NaN for a frame not found) and the pipeline's ``failure_reason``; a pose more than :data:`WRONG_MATCH_DEG` off the truth is a failure
"wrong match".  :func:`envelope_figures` draws the maps from the stored sweep.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import xarray as xr

from experiments.scenarios.tof.config import Config
from experiments.sweep import Metric, SweepCell

__all__ = ["WRONG_MATCH_DEG", "envelope_cell", "envelope_sweep_cell", "envelope_figures", "reason_class",
           "REASON_CLASSES"]

#: a found pose with an attitude error above this is counted as a wrong match (deg)
WRONG_MATCH_DEG = 5.0
#: failure classes of the availability map, in plotting order
REASON_CLASSES = ("saturation", "markers below confidence", "too few markers", "wrong match", "other")


def reason_class(reason: str) -> str:
    """The failure class of a pipeline ``failure_reason`` text (``""`` for a found frame)."""
    if not reason:
        return ""
    if "saturat" in reason:
        return "saturation"
    if "confidence" in reason:
        return "markers below confidence"
    if "wrong match" in reason:
        return "wrong match"
    if "too few" in reason or "no marker candidates" in reason or "darker than" in reason or "collinear" in reason:
        return "too few markers"
    return "other"


def _rot(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle_rad) * K + (1.0 - np.cos(angle_rad)) * K @ K


def envelope_cell(cfg: Config, seeds: list[np.random.SeedSequence]) -> dict[str, np.ndarray]:
    """One envelope cell: a frame per trial, its pose errors, its bound and its failure reason."""
    from attitude.matrix import rotation_angle
    from chaser.tof import ExtractionSettings, MatchSettings, estimate_tof_pose
    from chaser.tof.bound import sr4000_marker_noise, tof_pose_bound
    from experiments.scenarios.tof.experiment import _R_from_pyr_deg
    from vision.tof import CooperativeTarget, default_marker_plate, render_tof_frame, sr4000

    camera, plate = sr4000(), default_marker_plate()
    target = CooperativeTarget(plate=plate, standoff_m=cfg.target.standoff_m,
                               body_reflectivity=cfg.target.body_reflectivity)
    r_true = np.array([*cfg.target.lateral_offset_m, cfg.target.distance_m])
    tilt = np.radians(cfg.target.off_boresight_deg)
    n = len(seeds)
    out = {k: np.full(n, np.nan) for k in ("attitude_error_deg", "position_error_mm", "bound_attitude_deg",
                                           "bound_position_mm", "n_detected", "n_matched")}
    reason = np.full(n, "", dtype=object)
    for t, s in enumerate(seeds):
        rng = np.random.default_rng(s)
        phi = rng.uniform(0.0, 2.0 * np.pi)
        R_true = _rot(np.array([np.cos(phi), np.sin(phi), 0.0]), tilt) @ _R_from_pyr_deg(cfg.target.attitude_deg)
        mn = sr4000_marker_noise(camera, plate, R_true, r_true, ambient_dn=cfg.camera.ambient_dn,
                                  centre_estimator=cfg.pipeline.centre_estimator)
        frame = render_tof_frame(camera, target, R_true, r_true, rng=rng, supersample=cfg.camera.supersample,
                                 ambient_dn=cfg.camera.ambient_dn)
        res = estimate_tof_pose(frame, camera, plate, matcher=cfg.pipeline.matcher,
                                match_settings=MatchSettings(alpha_m=cfg.pipeline.alpha_m),
                                extraction=ExtractionSettings(range_estimator=cfg.pipeline.range_estimators[0],
                                                              centre_estimator=cfg.pipeline.centre_estimator),
                                gate_factor=cfg.pipeline.gate_factor, weighting=cfg.pipeline.weighting,
                                pose_estimator=cfg.pipeline.pose_estimator)
        out["n_detected"][t] = res.detections.n
        out["n_matched"][t] = res.n_matched
        if not res.ok:
            reason[t] = res.failure_reason
            continue
        att = float(np.degrees(rotation_angle(res.R_SC @ R_true.T)))
        if att > WRONG_MATCH_DEG:
            reason[t] = f"wrong match (attitude error {att:.1f} deg > {WRONG_MATCH_DEG:g} deg)"
            continue
        out["attitude_error_deg"][t] = att
        lab = res.labels[res.labels >= 0]                  # the bound of the markers the pose was made from
        b = tof_pose_bound(R_true, r_true, plate.markers_C[lab], camera, mn.sigma_px[lab], mn.sigma_range_m[lab])
        out["bound_attitude_deg"][t] = b.attitude_sigma_deg
        out["bound_position_mm"][t] = b.position_sigma_m * 1e3
        out["position_error_mm"][t] = float(np.linalg.norm(res.r_CS_S - r_true) * 1e3)
    out["failure_reason"] = reason
    return out


def envelope_sweep_cell(cfg: Config) -> SweepCell:
    """The ``envelope`` cell with its metrics (NaN errors for frames not found)."""
    return SweepCell(
        fn=envelope_cell,
        metrics={
            "attitude_error_deg": Metric("deg", long_name="rotation angle of R_est R_true^T"),
            "position_error_mm": Metric("mm", long_name="|r_est - r_true| of the plate origin"),
            "bound_attitude_deg": Metric("deg", long_name="Cramer-Rao bound sqrt(tr P_theta) of the pose"),
            "bound_position_mm": Metric("mm", long_name="Cramer-Rao bound sqrt(tr P_r) of the pose"),
            "n_detected": Metric("1", long_name="key points extracted"),
            "n_matched": Metric("1", long_name="key points matched to the model"),
        },
        name="envelope",
    )


def _cell_stats(ds: xr.Dataset) -> dict[str, xr.DataArray]:
    found = (ds["failure_reason"] == "")
    rms = {k: np.sqrt((ds[k] ** 2).mean("trial", skipna=True)) for k in
           ("attitude_error_deg", "position_error_mm")}
    bound = {k: np.sqrt((ds[k] ** 2).mean("trial", skipna=True)) for k in ("bound_attitude_deg", "bound_position_mm")}
    return {"found": found.mean("trial"), "att": rms["attitude_error_deg"], "pos": rms["position_error_mm"],
            "ratio": rms["attitude_error_deg"] / bound["bound_attitude_deg"],
            "batt": bound["bound_attitude_deg"]}


def envelope_table(ds: xr.Dataset) -> list[dict]:
    """Per cell: distance, tilt, found fraction, RMS errors, RMS bound and the failure counts by class."""
    st = _cell_stats(ds)
    rows = []
    for d in ds["distance_m"].values:
        for a in ds["off_boresight_deg"].values:
            sel = dict(distance_m=d, off_boresight_deg=a)
            reasons = Counter(reason_class(str(r)) for r in ds["failure_reason"].sel(sel).values)
            reasons.pop("", None)
            rows.append({"distance_m": float(d), "off_boresight_deg": float(a),
                         "found": float(st["found"].sel(sel)), "rms_attitude_deg": float(st["att"].sel(sel)),
                         "rms_position_mm": float(st["pos"].sel(sel)), "bound_attitude_deg": float(st["batt"].sel(sel)),
                         "failures": dict(reasons)})
    return rows


def envelope_figures(ds: xr.Dataset, fig_dir: Path, *, format: str = "png") -> list[Path]:
    """Maps over (distance, off-boresight angle): RMS attitude and position error, fraction found,
    RMS attitude error / bound, and the failures per class (one panel each, counts in the cells)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from experiments.plotting import check_format, figure_path, plot_map, save

    check_format(format)
    x, y = "distance_m", "off_boresight_deg"
    xl, yl = "distance [m]", "off-boresight angle [deg]"
    st = _cell_stats(ds)
    xv, ys = ds[x].values, ds[y].values
    xs = np.arange(len(xv), dtype=float)          # one column per distance (the grid is not uniform)

    def m(da):
        return da.transpose(y, x).values

    def ticks(axs):
        for ax in np.ravel(axs):
            ax.set_xticks(xs, [f"{v:g}" for v in xv])

    paths = []
    fig, axes = plt.subplots(2, 2, figsize=(12, 8.5), layout="constrained")
    plot_map(m(st["att"]), xs, ys, ax=axes[0, 0], vmin=0.0, vmax=0.5, cmap="viridis", xlabel=xl, ylabel=yl,
             title="RMS attitude error", cbar_label="attitude error [deg]", annotate=True, fmt="{:.3f}")
    plot_map(m(st["pos"]), xs, ys, ax=axes[0, 1], vmin=0.0, vmax=5.0, cmap="viridis", xlabel=xl, ylabel=yl,
             title="RMS position error", cbar_label="position error [mm]", annotate=True, fmt="{:.2f}")
    plot_map(m(100 * st["found"]), xs, ys, ax=axes[1, 0], vmin=0.0, vmax=100.0, cmap="cividis", xlabel=xl,
             ylabel=yl, title="frames found", cbar_label="found [%]", annotate=True, fmt="{:.0f}")
    plot_map(m(st["ratio"]), xs, ys, ax=axes[1, 1], vmin=0.0, vmax=5.0, cmap="viridis", xlabel=xl, ylabel=yl,
             title="RMS attitude error / Cramer-Rao bound", cbar_label="error / bound [1]", annotate=True,
             fmt="{:.1f}")
    ticks(axes)
    fig.suptitle(f"000 TOF pose envelope (SR4000 model), {ds.sizes['trial']} frames per cell")
    paths.append(save(fig, figure_path(fig_dir, "tof_envelope", format)))

    cls = np.vectorize(reason_class, otypes=[object])(ds["failure_reason"].values.astype(str))
    r_ax = ds["failure_reason"].dims.index("trial")
    fig, axes = plt.subplots(2, 3, figsize=(14, 8), layout="constrained")
    axes[1, 2].set_axis_off()
    for ax, c in zip(axes.ravel(), REASON_CLASSES, strict=False):
        frac = 100.0 * (cls == c).mean(axis=r_ax)
        da = xr.DataArray(frac, dims=[d for d in ds["failure_reason"].dims if d != "trial"])
        plot_map(m(da), xs, ys, ax=ax, vmin=0.0, vmax=100.0, cmap="cividis", xlabel=xl, ylabel=yl, title=c,
                 annotate=True, fmt="{:.0f}", colorbar=False)
    ticks(axes.ravel()[:len(REASON_CLASSES)])
    fig.colorbar(axes[0, 0].collections[0], ax=axes.ravel().tolist(), label="frames lost [%]")
    fig.suptitle("why frames are lost, by failure class (pipeline failure_reason)")
    paths.append(save(fig, figure_path(fig_dir, "tof_envelope_failures", format)))
    return paths
