"""The ``closed_loop`` study: one 003 scenario end to end, built from the config's parts.

The truth (:func:`closed_loop.tumbling_target`), the observers (the symmetric n-view cone of
003 §3.1, station-kept, or candidates on Clohessy–Wiltshire orbits selected and reconfigured by
:func:`closed_loop.plan_observers`) and the loop (:class:`closed_loop.ClosedLoop` with the config's
observer, registrar and estimator) come from the config; this module runs them and turns the
:class:`closed_loop.ClosedLoopResult` into the stored dataset and summary.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import xarray as xr

from attitude.quaternion import (
    matrix_from_quat,
    quat_angle_between,
    quat_conjugate,
    quat_multiply,
    rotvec_from_quat,
)
from closed_loop import (
    ClosedLoopResult,
    ObserverPlan,
    Reconfiguration,
    Snapshot,
    TumblingTarget,
    initial_estimate,
    plan_observers,
    tumbling_target,
)
from closed_loop.smoothing_loop import SmootherStart, SmoothingLoop
from experiments.scenarios.formation.config import Config
from experiments.scenarios.formation.parts import (
    criterion,
    load_target,
    make_camera,
    make_estimator,
    make_loop,
    observation_constraints,
    orbit_radius_m,
    orbit_rate_rad_s,
)
from experiments.sweep import Metric, SweepCell, child_seeds
from filters import convergence_time
from formation.geometry import symmetric_views
from orbits.cw import propagate
from vision.camera import PinholeCamera
from vision.target import Target

__all__ = ["truth", "observer_states", "observer_plan", "closed_loop", "closed_loop_cell", "closed_loop_sweep_cell"]


def truth(cfg: Config) -> TumblingTarget:
    """The configured target tumbling on its orbit, with the Sun (``observation.sun_H``, fixed in N)."""
    return tumbling_target(cfg.time.epochs(), cfg.target.q_NT0, cfg.omega0_rad_s(), cfg.inertia(),
                           orbit_radius_m=orbit_radius_m(cfg), sun_N=np.asarray(cfg.observation.sun_H, dtype=float))


def observer_states(cfg: Config, t_s: np.ndarray) -> tuple[list[str], np.ndarray]:
    """Names and CW states ``x_SiT_H (S, T, 6)`` of the candidate observers (m, m/s).

    The symmetric cone is station-kept (zero velocity in H); CW candidates coast on their orbits.
    """
    f = cfg.formation
    if f.geometry == "symmetric":
        r = symmetric_views(int(f.n_views), float(f.distance_m), float(f.axis_angle_deg)).r_CT_H
        x = np.concatenate([r, np.zeros_like(r)], -1)
        return [f"view {i}" for i in range(len(r))], np.broadcast_to(x[:, None, :], (len(r), t_s.size, 6)).copy()
    x0 = np.array([[*s.r_H_m, *s.v_H_m_s] for s in f.spacecraft])
    return [s.name for s in f.spacecraft], propagate(x0, t_s, orbit_rate_rad_s(cfg))


def observer_plan(cfg: Config, t_s: np.ndarray, target_radius_m: float, sun_H: np.ndarray,
                  illumination: np.ndarray) -> ObserverPlan:
    """The observers of ``[formation]`` over the run.

    The symmetric cone is the formation itself: all its views are active.  CW candidates are
    selected at every epoch (:func:`closed_loop.plan_observers`), with one reconfiguration into the
    cone of ``max_active`` views at ``distance_m`` / ``axis_angle_deg`` when ``reconfigure`` is set.
    """
    names, x = observer_states(cfg, t_s)
    f = cfg.formation
    if f.geometry == "symmetric":
        return ObserverPlan.all_active(names, x)
    rc = None
    if f.reconfigure:
        k = min(f.max_active, len(names))
        rc = Reconfiguration(slots_r_H=symmetric_views(k, float(f.distance_m), float(f.axis_angle_deg)).r_CT_H,
                             duration_s=f.reconfiguration_time_s, dv_max_m_s=f.dv_max_m_s,
                             keep_out_radius_m=f.keep_out_radius_m)
    return plan_observers(names, x, t_s, observation_constraints(cfg, target_radius_m), sun_H, illumination,
                          n_rad_s=orbit_rate_rad_s(cfg), max_active=f.max_active, min_active=f.min_active, reconfiguration=rc)


def closed_loop(cfg: Config, seed_seq: np.random.SeedSequence, *,
                progress: Callable[[int, int], None] | None = None,
                snapshot: bool = True) -> tuple[xr.Dataset, dict]:
    """Run the scenario once; returns the time-series dataset and a summary.

    Streams (children of ``seed_seq``): initial filter estimate, observations (one per epoch, split
    per camera inside the observation), registration.
    """
    tr = truth(cfg)
    t = tr.t_s
    T = t.size
    camera = make_camera(cfg)
    target = load_target(cfg)
    plan = observer_plan(cfg, t, target.radius_m, tr.sun_H, tr.illumination)
    r = plan.x_H[..., :3]

    s_init, s_obs, s_reg = child_seeds(seed_seq, 3)
    loop = make_loop(cfg, camera, target)
    e = cfg.estimator
    state0 = initial_estimate(make_estimator(cfg), tr.q_NT[0], tr.omega_TN_T_rad_s[0],
                              sigma_q=e.sigma_q_known if e.initial_attitude_known else e.sigma_q,
                              sigma_omega_rad_s=np.deg2rad(e.sigma_omega_deg_s), rng=np.random.default_rng(s_init),
                              t_s=t[0], attitude_known=e.initial_attitude_known)
    if isinstance(loop, SmoothingLoop):
        state0 = SmootherStart.from_filter_state(make_estimator(cfg), state0, attitude_defined=e.initial_attitude_known)
    res = loop.run(t, tr.q_HT, tr.R_NH, tr.sun_H, tr.illumination, r, state0,
                   rng_observe=np.random.default_rng(s_obs), rng_register=np.random.default_rng(s_reg),
                   active=plan.active, inactive_reason=plan.failure_reason, snapshot_from=T // 2 if snapshot else None,
                   progress=progress)
    return _dataset(cfg, tr, plan, res, camera, target)


def _dataset(cfg: Config, tr: TumblingTarget, plan: ObserverPlan, res: ClosedLoopResult, camera: PinholeCamera,
             target: Target) -> tuple[xr.Dataset, dict]:
    t, q_NT, w_T = tr.t_s, tr.q_NT, tr.omega_TN_T_rad_s
    att_err = np.degrees(quat_angle_between(res.q_NT_est, q_NT))
    rate_err = np.degrees(np.linalg.norm(res.omega_TN_T_est_rad_s - w_T, axis=-1))
    crit = criterion(cfg)
    conv, tconv = convergence_time(t, np.deg2rad(att_err), np.deg2rad(rate_err), criterion=crit)
    # body-frame error components (estimate to truth), the quantities the filter's sigmas describe
    att_err_T = np.degrees(rotvec_from_quat(quat_multiply(quat_conjugate(res.q_NT_est), q_NT)))
    rate_err_T = np.degrees(res.omega_TN_T_est_rad_s - w_T)
    ds = xr.Dataset(
        {
            "q_NT_true": (("time_s", "quat_component"), q_NT),
            "q_NT_est": (("time_s", "quat_component"), res.q_NT_est),
            "omega_true_deg_s": (("time_s", "axis"), np.degrees(w_T), {"units": "deg/s"}),
            "omega_est_deg_s": (("time_s", "axis"), np.degrees(res.omega_TN_T_est_rad_s), {"units": "deg/s"}),
            "attitude_error_deg": ("time_s", att_err, {"units": "deg"}),
            "rate_error_deg_s": ("time_s", rate_err, {"units": "deg/s"}),
            "attitude_error_T_deg": (("time_s", "axis"), att_err_T,
                                     {"units": "deg", "long_name": "rotation vector from estimate to truth, body axes"}),
            "rate_error_T_deg_s": (("time_s", "axis"), rate_err_T,
                                   {"units": "deg/s", "long_name": "estimated minus true body rate, body axes"}),
            "attitude_sigma_deg": (("time_s", "axis"), np.degrees(res.attitude_sigma_T_rad),
                                   {"units": "deg", "long_name": "filter 1-sigma of the attitude error, body axes"}),
            "rate_sigma_deg_s": (("time_s", "axis"), np.degrees(res.omega_sigma_T_rad_s),
                                 {"units": "deg/s", "long_name": "filter 1-sigma of the rate error, body axes"}),
            "increment_error_deg": ("time_s", res.increment_error_deg,
                                    {"units": "deg", "long_name": "registered increment vs truth"}),
            "increment_sigma_deg": ("time_s", res.increment_sigma_deg,
                                    {"units": "deg", "long_name": "increment sigma given to the filter"}),
            "active": (("time_s", "spacecraft"), res.active),
            "r_H_m": (("spacecraft", "time_s", "axis"), plan.x_H[..., :3], {"units": "m"}),
            "v_H_m_s": (("spacecraft", "time_s", "axis"), plan.x_H[..., 3:], {"units": "m/s", "long_name": "velocity in H (rotating frame)"}),
            "dv_m_s": ("spacecraft", plan.dv_m_s, {"units": "m/s", "long_name": "reconfiguration delta-v"}),
            "illumination": ("time_s", tr.illumination, {"units": "1"}),
            "n_tracks": ("time_s", res.n_tracks, {"units": "1"}),
            "n_points": ("time_s", res.n_points, {"units": "1"}),
            "n_matches": ("time_s", res.n_matches, {"units": "1"}),
            "measurement_ok": ("time_s", res.ok, {"long_name": "an increment updated the filter"}),
            "failure_reason": ("time_s", res.failure_reason.astype(str),
                               {"long_name": "why no increment updated the filter"}),
        },
        coords={"time_s": ("time_s", t, {"units": "s"}), "spacecraft": plan.names,
                "quat_component": ["q0", "q1", "q2", "q3"], "axis": ["x", "y", "z"]},
        attrs={"study": "closed_loop", "observation_mode": cfg.observation.mode,
               "registration": cfg.estimator.registration, "filter": cfg.estimator.filter,
               "threshold_attitude_deg": crit.attitude_deg, "threshold_rate_deg_s": crit.rate_deg_s,
               "converged": int(bool(conv)), "convergence_time_s": float(tconv)},
    )
    ds = ds.merge(_consistency_dataset(tr, res))
    if res.snapshot is not None:
        attrs = dict(ds.attrs)
        ds = ds.merge(_snapshot_dataset(camera, target, tr.q_HT, res.snapshot))
        ds.attrs = {**attrs, "snapshot_time_s": float(t[res.snapshot.epoch])}
    tail = t >= t[-1] - crit.hold_s
    inc_err, n_tracks = res.increment_error_deg, res.n_tracks
    used = np.isfinite(inc_err)
    summary = {
        "observation_mode": cfg.observation.mode,
        "epochs": int(t.size),
        "epochs_with_increment": int(used.sum()),
        "converged": bool(conv),
        "convergence_time_s": float(tconv),
        "final_rms_attitude_error_deg": float(np.sqrt(np.nanmean(att_err[tail] ** 2))),
        "final_rms_rate_error_deg_s": float(np.sqrt(np.nanmean(rate_err[tail] ** 2))),
        "median_increment_error_deg": float(np.nanmedian(inc_err)) if used.any() else float("nan"),
        "median_tracks_per_observed_epoch": float(np.median(n_tracks[n_tracks > 0])) if (n_tracks > 0).any() else 0.0,
        "epochs_without_observer_set": int(np.sum(~plan.active.any(axis=1))),
        "reconfiguration": plan.reconfiguration,
        **_consistency_summary(cfg, res, ds),
    }
    return ds, summary


def _nees(err: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """``eᵀ C⁻¹ e`` per epoch (NaN where the covariance is missing or not positive definite)."""
    out = np.full(len(err), np.nan)
    ok = np.all(np.isfinite(cov), axis=(1, 2)) & np.all(np.isfinite(err), axis=1)
    ok[ok] = np.all(np.linalg.eigvalsh(0.5 * (cov[ok] + np.swapaxes(cov[ok], 1, 2))) > 0, axis=-1)
    if ok.any():
        out[ok] = np.einsum("ti,ti->t", err[ok], np.linalg.solve(cov[ok], err[ok][..., None])[..., 0])
    return out


def _consistency_dataset(tr: TumblingTarget, res: ClosedLoopResult) -> xr.Dataset:
    """Per-epoch NEES of the attitude and the rate (3 dof each) and the registrations' bookkeeping."""
    e_T = rotvec_from_quat(quat_multiply(quat_conjugate(res.q_NT_est), tr.q_NT))
    T = len(tr.t_s)
    nan = np.full((T, 3, 3), np.nan)
    vars_ = {
        "nees_attitude": ("time_s", _nees(e_T, res.attitude_cov_T_rad2 if res.attitude_cov_T_rad2 is not None else nan),
                          {"long_name": "attitude NEES (3 dof) against the estimator's covariance"}),
        "nees_rate": ("time_s", _nees(res.omega_TN_T_est_rad_s - tr.omega_TN_T_rad_s,
                                      res.omega_cov_T_rad2_s2 if res.omega_cov_T_rad2_s2 is not None else nan),
                      {"long_name": "rate NEES (3 dof) against the estimator's covariance"}),
    }
    if res.n_links is not None:
        vars_["n_links"] = ("time_s", res.n_links, {"long_name": "registrations accepted at the epoch"})
    if res.n_rejected is not None:
        vars_["n_rejected"] = ("time_s", res.n_rejected, {"long_name": "registrations refused (evidence or gate)"})
    if res.closure is not None:
        vars_["closure"] = ("time_s", res.closure.astype(str),
                            {"long_name": "tied to a keyframe older than the previous epoch by"})
    return xr.Dataset(vars_, coords={"time_s": tr.t_s})


def _consistency_summary(cfg: Config, res: ClosedLoopResult, ds: xr.Dataset) -> dict:
    """NEES, closures, gaps and the inertia estimate for the summary."""
    from scipy.stats import chi2

    na, nw = ds["nees_attitude"].values[1:], ds["nees_rate"].values[1:]
    lo, hi = chi2.ppf([0.025, 0.975], 3)
    out: dict = {
        "mean_nees_attitude": float(np.nanmean(na)) if np.isfinite(na).any() else float("nan"),
        "mean_nees_rate": float(np.nanmean(nw)) if np.isfinite(nw).any() else float("nan"),
        "fraction_epochs_nees_attitude_in_95pct": float(np.mean((na >= lo) & (na <= hi))) if na.size else float("nan"),
        "gaps": [dict(g) for g in res.gaps],
    }
    if res.closure is not None:
        out["closures_by_descriptors"] = int(np.sum(res.closure == "descriptors"))
        out["closures_by_geometry"] = int(np.sum(res.closure == "geometry"))
        out["keyframes"] = int(res.n_keyframes)
    if res.n_rejected is not None:
        out["registrations_refused"] = int(np.sum(res.n_rejected))
    if res.inertia is not None and cfg.estimator.estimate_inertia:
        from closed_loop.torque_free_factor import InertiaShape

        true = InertiaShape.from_tensor(cfg.inertia())
        est = res.inertia
        m_true, m_est = true.principal_moments(), est.principal_moments()
        axes_deg = _principal_axes_error_deg(est.J_T, true.J_T)
        out["inertia_ratios_estimated"] = m_est[1:].tolist()
        out["inertia_ratios_true"] = m_true[1:].tolist()
        out["inertia_ratio_error_pct"] = (100 * (m_est[1:] / m_true[1:] - 1)).tolist()
        out["principal_axes_error_deg"] = axes_deg
    return out


def _principal_axes_error_deg(J_est: np.ndarray, J_true: np.ndarray) -> list[float]:
    """Angle between each estimated and true principal axis (sorted by moment; sign-free), deg."""
    _, Ve = np.linalg.eigh(J_est)
    _, Vt = np.linalg.eigh(J_true)
    c = np.abs(np.sum(Ve * Vt, axis=0)).clip(0, 1)
    return np.degrees(np.arccos(c)).tolist()


def _snapshot_dataset(camera: PinholeCamera, target: Target, q_HT: np.ndarray, snap: Snapshot) -> xr.Dataset:
    """One epoch's images (re-rendered noiselessly for the figure), tracks, reconstructed cloud with each
    point's σ, and each track's true point in H (NaN for a false match)."""
    from vision.render import render

    imgs = []
    for T_CW in snap.T_CW:
        rr = render(camera, T_CW, target, q_HT[snap.epoch], snap.sun_H / np.linalg.norm(snap.sun_H), rng=0)
        imgs.append(rr.image.astype(np.uint8) if rr.image.dtype == np.uint8 else
                    np.clip(rr.image / max(1, rr.image.max()) * 255, 0, 255).astype(np.uint8))
    obs, tri = snap.frame.obs, snap.frame.tri
    X_true_H = np.asarray(obs.X_T_true, dtype=float) @ matrix_from_quat(q_HT[snap.epoch]).T
    sigma_m = np.sqrt(np.clip(np.trace(np.asarray(tri.cov_W, dtype=float), axis1=-2, axis2=-1), 0.0, None))
    return xr.Dataset(
        {
            "snapshot_image": (("snapshot_view", "image_y", "image_x"), np.stack(imgs)),
            "snapshot_uv_px": (("snapshot_track", "snapshot_view", "uv"), obs.uv_px),
            "snapshot_track_correct": ("snapshot_track", obs.feature_id >= 0),
            "snapshot_X_W_m": (("snapshot_track", "axis"), tri.X_W, {"units": "m"}),
            "snapshot_point_valid": ("snapshot_track", np.asarray(tri.valid, bool)),
            "snapshot_X_true_H_m": (("snapshot_track", "axis"), X_true_H,
                                    {"units": "m", "long_name": "true point of each track in H (NaN: false match)"}),
            "snapshot_sigma_m": ("snapshot_track", sigma_m,
                                 {"units": "m", "long_name": "sqrt(trace) of the point's triangulation covariance"}),
        },
        coords={"snapshot_view": np.asarray(snap.observers), "uv": ["u", "v"]},
    )


# ----------------------------------------------------------------------------- sweep cell


def closed_loop_cell(cfg: Config, seeds: Sequence[np.random.SeedSequence]) -> dict[str, np.ndarray]:
    """Sweep cell: the closed loop once per trial seed (coarse grids; every epoch is observed).

    Besides each trial's figures, the Monte Carlo consistency of the cell: at every epoch the NEES
    averaged over the trials, and the fraction of epochs where that average lies in its 95 % band
    ``χ²₃ₙ(0.025, 0.975) / n`` (the same value in every trial of the cell).
    """
    from scipy.stats import chi2

    keys = ("converged", "convergence_time_s", "final_attitude_error_deg", "final_rate_error_deg_s",
            "median_increment_error_deg", "epochs_with_increment", "mean_nees_attitude", "mean_nees_rate",
            "inertia_ratio_error_pct", "principal_axes_error_deg", "avg_nees_attitude_in_band",
            "avg_nees_rate_in_band")
    out = {k: np.full(len(seeds), np.nan) for k in keys}
    nees_a, nees_w = [], []
    for i, ss in enumerate(seeds):
        ds, s = closed_loop(cfg, ss, snapshot=False)
        out["converged"][i] = float(s["converged"])
        out["convergence_time_s"][i] = s["convergence_time_s"]
        out["final_attitude_error_deg"][i] = s["final_rms_attitude_error_deg"]
        out["final_rate_error_deg_s"][i] = s["final_rms_rate_error_deg_s"]
        out["median_increment_error_deg"][i] = s["median_increment_error_deg"]
        out["epochs_with_increment"][i] = s["epochs_with_increment"]
        out["mean_nees_attitude"][i] = s["mean_nees_attitude"]
        out["mean_nees_rate"][i] = s["mean_nees_rate"]
        if "inertia_ratio_error_pct" in s:
            out["inertia_ratio_error_pct"][i] = float(np.max(np.abs(s["inertia_ratio_error_pct"])))
            out["principal_axes_error_deg"][i] = float(np.max(s["principal_axes_error_deg"]))
        nees_a.append(ds["nees_attitude"].values[1:])
        nees_w.append(ds["nees_rate"].values[1:])
    n = len(seeds)
    lo, hi = chi2.ppf([0.025, 0.975], 3 * n) / n
    for key, arr in (("avg_nees_attitude_in_band", nees_a), ("avg_nees_rate_in_band", nees_w)):
        avg = np.mean(np.asarray(arr), axis=0)
        out[key][:] = float(np.mean((avg >= lo) & (avg <= hi)))
    return out


def closed_loop_sweep_cell(cfg: Config) -> SweepCell:
    """The sweep cell of the closed loop (:func:`closed_loop_cell`) with its metrics."""
    return SweepCell(
        fn=closed_loop_cell,
        metrics={
            "converged": Metric("1", long_name="run converged (estimator.convergence_* thresholds)"),
            "convergence_time_s": Metric("s"),
            "final_attitude_error_deg": Metric("deg", long_name="RMS attitude error over the final hold window"),
            "final_rate_error_deg_s": Metric("deg/s", long_name="RMS rate error over the final hold window"),
            "median_increment_error_deg": Metric("deg", long_name="median registered increment error"),
            "epochs_with_increment": Metric("1", long_name="epochs whose increment updated the filter"),
            "mean_nees_attitude": Metric("1", long_name="attitude NEES (3 dof) averaged over the run"),
            "mean_nees_rate": Metric("1", long_name="rate NEES (3 dof) averaged over the run"),
            "inertia_ratio_error_pct": Metric("%", long_name="largest inertia-ratio error (estimated inertia)"),
            "principal_axes_error_deg": Metric("deg", long_name="largest principal-axis error (estimated inertia)"),
            "avg_nees_attitude_in_band": Metric(
                "1", long_name="cell: fraction of epochs whose trial-averaged attitude NEES is in its 95 % band"),
            "avg_nees_rate_in_band": Metric(
                "1", long_name="cell: fraction of epochs whose trial-averaged rate NEES is in its 95 % band"),
        },
        name="closed_loop",
    )
