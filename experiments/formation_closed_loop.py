"""One 003 scenario end to end (ARCHITECTURE §3): truth → observers → observation → registration → EKF.

Truth
    The target tumbles torque-free (:func:`attitude.rigid_body.propagate_torque_free`) with
    attitude ``q_NT``; the Hill frame H turns at the orbit rate n about N's z axis,
    ``R_NH(t) = R_z(n t)`` (:func:`filters.hill_frame_rotation`), so the target's attitude in the
    observation frame is ``q_HT = q_NH⁻¹ ⊗ q_NT``.  Observers sit at fixed points of H (the symmetric
    n-view cone of 003 §3.1, station-kept) or follow Clohessy–Wiltshire orbits
    (:func:`orbits.cw.propagate`).  The Sun is fixed in N (its H direction turns with the orbit);
    the target is in Earth's shadow when :func:`orbits.environment.illumination_fraction` says so.
Each epoch
    the selected observers' cameras point at the
    target, the epoch is observed and triangulated, associated with the previous epoch and
    registered (:mod:`experiments.formation_pipeline`); the increment (with its covariance) updates
    the EKF/MEKF by stochastic cloning (:meth:`filters.AttitudeEKF.update_increment`).  An epoch
    without a usable increment (shadow, too few observers, changed observer set, failed
    registration) only propagates the filter, and its reason is recorded.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import xarray as xr
from scipy.optimize import linear_sum_assignment

from attitude.quaternion import (
    matrix_from_quat,
    quat_angle_between,
    quat_conjugate,
    quat_from_matrix,
    quat_multiply,
)
from experiments.formation_config import Config
from experiments.formation_ekf import criterion, make_filter, truth_history
from experiments.formation_pipeline import (
    Frame,
    load_target,
    make_camera,
    observe_epoch,
    reconstruct,
    register_frames,
)
from experiments.sweep import Metric, SweepCell, child_seeds
from filters import convergence_time, hill_frame_rotation
from formation.constraints import ObservationConstraints, evaluate
from formation.geometry import look_at, symmetric_views
from formation.reconfiguration import drift_free_slot_states, plan
from formation.selection import select_observers
from orbits.cw import apply_impulse, mean_motion, propagate, two_impulse_transfer
from orbits.environment import illumination_fraction
from orbits.two_body import R_EARTH_M

__all__ = ["observer_states", "constraints", "ObserverPlan", "plan_observers", "closed_loop",
           "closed_loop_cell", "closed_loop_sweep_cell", "AU_M"]

AU_M = 1.495978707e11


def orbit_rate(cfg: Config) -> float:
    """Mean motion n of the target's circular orbit, rad/s."""
    return float(mean_motion(R_EARTH_M + 1e3 * cfg.formation.orbit_altitude_km))


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
    return [s.name for s in f.spacecraft], propagate(x0, t_s, orbit_rate(cfg))


def constraints(cfg: Config, target_radius_m: float) -> ObservationConstraints:
    """003 §1.2 observation constraints of the config (:class:`formation.constraints.ObservationConstraints`)."""
    f = cfg.formation
    return ObservationConstraints(
        fov_rad=float(np.deg2rad(cfg.camera.fov_deg)), target_radius_m=float(target_radius_m),
        d_max_m=f.d_max_m, d_min_form="tan", d_min_lambda=f.d_min_lambda,
        pointing_max_rad=float(np.deg2rad(f.max_pointing_deg)),
        axis_angle_min_rad=float(np.deg2rad(f.axis_angle_min_deg)),
        axis_angle_max_rad=float(np.deg2rad(f.axis_angle_max_deg)), comm_range_m=f.max_comm_range_m,
        sun_exclusion_rad=float(np.deg2rad(f.sun_exclusion_deg)), keep_out_radius_m=f.keep_out_radius_m)


@dataclass(frozen=True)
class ObserverPlan:
    """Observers over the run.

    Attributes
    ----------
    names : list of str
    x_H : ndarray (S, T, 6)
        CW states (after any reconfiguration), m and m/s.
    active : ndarray (T, S) bool
        Selected observers (:func:`formation.selection.select_observers`).
    reason : ndarray (T,) object
        Why no set was selected at an epoch ("" otherwise).
    dv_m_s : ndarray (S,)
        Δv spent by each observer in the reconfiguration.
    reconfiguration : dict
        Start time, duration, Δv, solver status and success of the reconfiguration (empty if none).
    """

    names: list[str]
    x_H: np.ndarray
    active: np.ndarray
    reason: np.ndarray
    dv_m_s: np.ndarray
    reconfiguration: dict


def _select(cfg: Config, con: ObservationConstraints, x: np.ndarray, sun_H: np.ndarray, lit: np.ndarray):
    r = np.swapaxes(x[..., :3], 0, 1)  # (T, S, 3)
    ev = evaluate(con, r, sun_H=sun_H, target_lit=lit > 0)
    f = cfg.formation
    k = min(f.max_active, r.shape[1])
    tl = select_observers(ev, r, k)
    active = tl.active.copy()
    short = tl.short.copy()
    if f.min_active < k and short.any():
        tl2 = select_observers(ev, r, f.min_active)
        use = short & ~tl2.short
        active[use] = tl2.active[use]
        short &= tl2.short
    reason = np.where(short, np.where(lit > 0, "no observer set satisfies the 003 §1.2 constraints",
                                      "target in Earth shadow"), "")
    return active, short, reason.astype(object)


def _with_impulses(x0: np.ndarray, times: np.ndarray, dv: np.ndarray, t_rel: np.ndarray, n: float) -> np.ndarray:
    """CW states ``(m, len(t_rel), 6)`` of spacecraft starting at ``x0 (m, 6)`` with impulses ``dv (m, M, 3)``
    at ``times (M,)`` (applied at the node; ``t_rel >= 0``)."""
    states = [apply_impulse(x0, dv[:, 0])]
    for j in range(1, len(times)):
        prev = propagate(states[-1], np.array([times[j] - times[j - 1]]), n)[:, 0]
        states.append(apply_impulse(prev, dv[:, j]))
    out = np.empty((x0.shape[0], t_rel.size, 6))
    seg = np.searchsorted(times, t_rel, side="right") - 1
    for j in np.unique(seg):
        sel = seg == j
        out[:, sel] = propagate(states[j], t_rel[sel] - times[j], n)
    return out


def plan_observers(cfg: Config, t: np.ndarray, target_radius_m: float, sun_H: np.ndarray,
                   lit: np.ndarray) -> ObserverPlan:
    """Selection over the whole run, with one minimum-fuel reconfiguration when no set qualifies.

    The symmetric cone is the formation itself: all its views are active.  For CW candidates the
    observers are selected at every epoch; at the first epoch (in sunlight) where no set of
    ``min_active`` qualifies, ``max_active`` candidates (chosen by the Hungarian assignment on the
    two-impulse cost) are moved by :func:`formation.reconfiguration.plan` to the slots of the
    symmetric cone at ``distance_m`` / ``axis_angle_deg`` within ``reconfiguration_time_s``, and
    the selection is repeated on the new trajectories.
    """
    names, x = observer_states(cfg, t)
    S = len(names)
    dv = np.zeros(S)
    if cfg.formation.geometry == "symmetric":
        return ObserverPlan(names, x, np.ones((t.size, S), bool), np.array([""] * t.size, dtype=object), dv, {})
    con = constraints(cfg, target_radius_m)
    active, short, reason = _select(cfg, con, x, sun_H, lit)
    info: dict = {}
    f = cfg.formation
    gap = np.flatnonzero(short & (lit > 0))
    if f.reconfigure and gap.size:
        k0 = int(gap[0])
        n = orbit_rate(cfg)
        k = min(f.max_active, S)
        slots_r = symmetric_views(k, float(f.distance_m), float(f.axis_angle_deg)).r_CT_H
        slots = drift_free_slot_states(slots_r, n)
        x0 = x[:, k0]
        tr = two_impulse_transfer(x0[:, None, :], slots[None, :, :], f.reconfiguration_time_s, n)
        cost = np.where(tr.ok, tr.total_dv_m_s, 1e9)
        rows, _ = linear_sum_assignment(cost)
        movers = np.sort(rows)
        others = np.setdiff1d(np.arange(S), movers)
        p = plan(x0[movers], slots, n=n, tf_s=f.reconfiguration_time_s, dv_max_m_s=f.dv_max_m_s,
                 keep_out_radius_m=f.keep_out_radius_m, others_x0_H=x0[others] if others.size else None)
        info = {"start_s": float(t[k0]), "duration_s": f.reconfiguration_time_s,
                "movers": [names[i] for i in movers], "dv_total_m_s": p.dv_total_m_s,
                "solver_status": p.status, "success": bool(p.success)}
        if p.success:
            x = x.copy()
            x[movers, k0:] = _with_impulses(x0[movers], p.impulse_times_s, p.impulses_H, t[k0:] - t[k0], n)
            dv[movers] = p.dv_per_spacecraft_m_s
            active, short, reason = _select(cfg, con, x, sun_H, lit)
            during = (t >= t[k0]) & (t < t[k0] + f.reconfiguration_time_s)
            reason = np.where(short & during, "reconfiguring", reason).astype(object)
    return ObserverPlan(names, x, active, reason, dv, info)


def _camera_poses(r_H: np.ndarray) -> np.ndarray:
    """Cameras at ``r_H (n, 3)`` looking at the target's centre, image up towards +z_H (else +x_H)."""
    up = np.where(np.abs(r_H[:, 2:3]) > 0.99 * np.linalg.norm(r_H, axis=1, keepdims=True),
                  np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))
    return look_at(r_H, np.zeros(3), up)


def closed_loop(cfg: Config, seed_seq: np.random.SeedSequence, *,
                progress: Callable[[int, int], None] | None = None,
                snapshot: bool = True) -> tuple[xr.Dataset, dict]:
    """Run the scenario once; returns the time-series dataset and a summary.

    Streams (``seed_seq.spawn``): initial filter estimate, observations (one per epoch, split per
    camera inside the observation), registration.
    """
    t, q_NT, w_T = truth_history(cfg)
    T = t.size
    n = orbit_rate(cfg)
    R_NH = hill_frame_rotation(t, n)
    q_NH = quat_from_matrix(R_NH)
    q_HT = quat_multiply(quat_conjugate(q_NH), q_NT)
    camera = make_camera(cfg)
    target = load_target(cfg)
    sun_N = np.asarray(cfg.observation.sun_H, dtype=float)
    sun_N = sun_N / np.linalg.norm(sun_N)
    r_chief_N = (R_NH @ np.array([R_EARTH_M + 1e3 * cfg.formation.orbit_altitude_km, 0.0, 0.0]))
    lit = illumination_fraction(r_chief_N, sun_N * AU_M)
    sun_H = np.einsum("tji,j->ti", R_NH, sun_N)
    obs_plan = plan_observers(cfg, t, target.radius_m, sun_H, lit)
    names = obs_plan.names
    r = obs_plan.x_H[..., :3]
    S = len(names)

    s_init, s_obs, s_reg = child_seeds(seed_seq, 3)
    obs_rngs = np.random.default_rng(s_obs).spawn(T)
    reg_rng = np.random.default_rng(s_reg)
    filt = make_filter(cfg)
    g = np.random.default_rng(s_init)
    sw = np.deg2rad(cfg.estimator.sigma_omega_deg_s)
    if cfg.estimator.initial_attitude_known:  # FLAG P003-14a: the first frame defines the body frame
        sq = cfg.estimator.sigma_q_known
        q0 = q_NT[0].copy()
    else:  # 003 eq (35)
        sq = cfg.estimator.sigma_q
        q0 = q_NT[0] + g.normal(size=4) * sq
    w0 = w_T[0] + g.normal(size=3) * sw
    state = filt.clone(filt.initial_state(q0, w0, filt.initial_covariance(sigma_q=sq, sigma_omega_rad_s=sw),
                                          t_s=t[0]))

    q_est = np.full((T, 4), np.nan)
    w_est = np.full((T, 3), np.nan)
    active = np.zeros((T, S), bool)
    n_tracks = np.zeros(T)
    n_points = np.zeros(T)
    n_matches = np.zeros(T)
    inc_err = np.full(T, np.nan)
    inc_sigma = np.full(T, np.nan)
    status = np.empty(T, dtype=object)
    prev: Frame | None = None
    prev_active: np.ndarray | None = None
    snap = None
    snap_k = T // 2
    if progress:
        progress(0, T)
    for k in range(T):
        if k > 0:
            state = filt.predict(state, t[k] - t[k - 1])
        act, why = obs_plan.active[k], str(obs_plan.reason[k])
        active[k] = act
        frame = None
        if act.sum() >= 2:
            sun_k = sun_H[k]
            cfg_k = cfg.model_copy(update={"observation": cfg.observation.model_copy(update={"sun_H": sun_k.tolist()})})
            T_CW = _camera_poses(r[act, k])
            obs = observe_epoch(cfg_k, camera, T_CW, target, q_HT[k], rng=obs_rngs[k],
                                sun_visible_fraction=float(lit[k]))
            frame = reconstruct(obs)
            n_tracks[k] = obs.n_tracks
            n_points[k] = int(np.sum(frame.tri.n_valid))
            if snapshot and k >= snap_k and snap is None and frame.ok:
                snap = (k, T_CW, frame, np.flatnonzero(act), sun_k)
            why = why or ("" if frame.ok else (obs.status if not obs.ok else str(frame.tri.failure_reason)))
        dq = None
        cov = np.eye(3)
        if k > 0 and frame is not None and prev is not None and np.array_equal(act, prev_active):
            inc = register_frames(cfg, prev, frame, rng=reg_rng)
            n_matches[k] = inc.n_matches
            if inc.ok and np.all(np.isfinite(inc.cov_rotvec_H)):
                dq = quat_from_matrix(inc.R_H)
                cov = inc.cov_rotvec_H
                true = matrix_from_quat(q_HT[k]) @ matrix_from_quat(q_HT[k - 1]).T
                inc_err[k] = np.degrees(quat_angle_between(dq, quat_from_matrix(true)))
                inc_sigma[k] = np.degrees(np.sqrt(np.trace(cov)))
            else:
                why = why or inc.failure_reason or "increment covariance unavailable"
        elif k > 0 and frame is not None and prev is not None:
            why = why or "observer set changed"
        if k > 0:
            meas = None if dq is None else dq[None]
            state = filt.update_increment(state, meas, cov[None], R_NH[k - 1], R_NH[k])
        status[k] = why if (k > 0 and dq is None) else ("" if k > 0 else "initial epoch")
        q_est[k] = state.q_NT[0]
        w_est[k] = state.omega_TN_T[0]
        prev, prev_active = frame, act
        if progress:
            progress(k + 1, T)

    att_err = np.degrees(quat_angle_between(q_est, q_NT))
    rate_err = np.degrees(np.linalg.norm(w_est - w_T, axis=-1))
    crit = criterion(cfg)
    conv, tconv = convergence_time(t, np.deg2rad(att_err), np.deg2rad(rate_err), criterion=crit)
    ds = xr.Dataset(
        {
            "q_NT_true": (("time_s", "quat_component"), q_NT),
            "q_NT_est": (("time_s", "quat_component"), q_est),
            "omega_true_deg_s": (("time_s", "axis"), np.degrees(w_T), {"units": "deg/s"}),
            "omega_est_deg_s": (("time_s", "axis"), np.degrees(w_est), {"units": "deg/s"}),
            "attitude_error_deg": ("time_s", att_err, {"units": "deg"}),
            "rate_error_deg_s": ("time_s", rate_err, {"units": "deg/s"}),
            "increment_error_deg": ("time_s", inc_err, {"units": "deg",
                                                        "long_name": "registered increment vs truth"}),
            "increment_sigma_deg": ("time_s", inc_sigma, {"units": "deg",
                                                          "long_name": "increment sigma given to the filter"}),
            "active": (("time_s", "spacecraft"), active),
            "r_H_m": (("spacecraft", "time_s", "axis"), r, {"units": "m"}),
            "dv_m_s": ("spacecraft", obs_plan.dv_m_s, {"units": "m/s", "long_name": "reconfiguration delta-v"}),
            "illumination": ("time_s", lit, {"units": "1"}),
            "n_tracks": ("time_s", n_tracks, {"units": "1"}),
            "n_points": ("time_s", n_points, {"units": "1"}),
            "n_matches": ("time_s", n_matches, {"units": "1"}),
            "measurement_status": ("time_s", status.astype(str)),
        },
        coords={"time_s": ("time_s", t, {"units": "s"}), "spacecraft": names,
                "quat_component": ["q0", "q1", "q2", "q3"], "axis": ["x", "y", "z"]},
        attrs={"study": "closed_loop", "observation_mode": cfg.observation.mode,
               "registration": cfg.estimator.registration, "filter": cfg.estimator.filter,
               "threshold_attitude_deg": crit.attitude_deg, "threshold_rate_deg_s": crit.rate_deg_s,
               "converged": int(bool(conv)), "convergence_time_s": float(tconv)},
    )
    if snap is not None:
        attrs = dict(ds.attrs)
        ds = ds.merge(_snapshot_dataset(cfg, camera, target, q_HT, *snap))
        ds.attrs = {**attrs, "snapshot_time_s": float(t[snap[0]])}
    tail = t >= t[-1] - crit.hold_s
    used = np.isfinite(inc_err)
    summary = {
        "observation_mode": cfg.observation.mode,
        "epochs": int(T),
        "epochs_with_increment": int(used.sum()),
        "converged": bool(conv),
        "convergence_time_s": float(tconv),
        "final_rms_attitude_error_deg": float(np.sqrt(np.nanmean(att_err[tail] ** 2))),
        "final_rms_rate_error_deg_s": float(np.sqrt(np.nanmean(rate_err[tail] ** 2))),
        "median_increment_error_deg": float(np.nanmedian(inc_err)) if used.any() else float("nan"),
        "median_tracks_per_observed_epoch": float(np.median(n_tracks[n_tracks > 0])) if (n_tracks > 0).any() else 0.0,
        "epochs_without_observer_set": int(np.sum(~obs_plan.active.any(axis=1))),
        "reconfiguration": obs_plan.reconfiguration,
    }
    return ds, summary


def _snapshot_dataset(cfg: Config, camera, target, q_HT, k, T_CW, frame: Frame, idx, sun_H) -> xr.Dataset:
    """One epoch's images (re-rendered noiselessly for the figure), tracks and reconstructed cloud."""
    from vision.render import render

    imgs = []
    for T in T_CW:
        rr = render(camera, T, target, q_HT[k], sun_H / np.linalg.norm(sun_H), rng=0)
        imgs.append(rr.image.astype(np.uint8) if rr.image.dtype == np.uint8 else
                    np.clip(rr.image / max(1, rr.image.max()) * 255, 0, 255).astype(np.uint8))
    obs, tri = frame.obs, frame.tri
    return xr.Dataset(
        {
            "snapshot_image": (("snapshot_view", "image_y", "image_x"), np.stack(imgs)),
            "snapshot_uv_px": (("snapshot_track", "snapshot_view", "uv"), obs.uv_px),
            "snapshot_track_correct": ("snapshot_track", obs.feature_id >= 0),
            "snapshot_X_W_m": (("snapshot_track", "axis"), tri.X_W, {"units": "m"}),
            "snapshot_point_valid": ("snapshot_track", np.asarray(tri.valid, bool)),
        },
        coords={"snapshot_view": np.asarray(idx), "uv": ["u", "v"]},
    )


# ----------------------------------------------------------------------------- sweep cell


def closed_loop_cell(cfg: Config, seeds) -> dict[str, np.ndarray]:
    """Sweep cell: the closed loop once per trial seed (coarse grids; every epoch is observed)."""
    keys = ("converged", "convergence_time_s", "final_attitude_error_deg", "final_rate_error_deg_s",
            "median_increment_error_deg", "epochs_with_increment")
    out = {k: np.full(len(seeds), np.nan) for k in keys}
    for i, ss in enumerate(seeds):
        _, s = closed_loop(cfg, ss, snapshot=False)
        out["converged"][i] = float(s["converged"])
        out["convergence_time_s"][i] = s["convergence_time_s"]
        out["final_attitude_error_deg"][i] = s["final_rms_attitude_error_deg"]
        out["final_rate_error_deg_s"][i] = s["final_rms_rate_error_deg_s"]
        out["median_increment_error_deg"][i] = s["median_increment_error_deg"]
        out["epochs_with_increment"][i] = s["epochs_with_increment"]
    return out


def closed_loop_sweep_cell(cfg: Config) -> SweepCell:
    return SweepCell(
        fn=closed_loop_cell,
        metrics={
            "converged": Metric("1", long_name="run converged (estimator.convergence_* thresholds)"),
            "convergence_time_s": Metric("s"),
            "final_attitude_error_deg": Metric("deg", long_name="RMS attitude error over the final hold window"),
            "final_rate_error_deg_s": Metric("deg/s", long_name="RMS rate error over the final hold window"),
            "median_increment_error_deg": Metric("deg", long_name="median registered increment error"),
            "epochs_with_increment": Metric("1", long_name="epochs whose increment updated the filter"),
        },
        name="closed_loop",
    )
