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
    the qualifying observers are selected (:func:`select_observers`), each camera points at the
    target, the epoch is observed and triangulated, associated with the previous epoch and
    registered (:mod:`experiments.formation_pipeline`); the increment (with its covariance) updates
    the EKF/MEKF by stochastic cloning (:meth:`filters.AttitudeEKF.update_increment`).  An epoch
    without a usable increment (shadow, too few observers, changed observer set, failed
    registration) only propagates the filter, and its reason is recorded.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np
import xarray as xr

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
from formation.geometry import look_at, symmetric_views
from orbits.cw import mean_motion, propagate
from orbits.environment import illumination_fraction
from orbits.two_body import R_EARTH_M

__all__ = ["observer_positions", "min_range_m", "select_observers", "closed_loop", "closed_loop_cell",
           "closed_loop_sweep_cell", "AU_M"]

AU_M = 1.495978707e11


def orbit_rate(cfg: Config) -> float:
    """Mean motion n of the target's circular orbit, rad/s."""
    return float(mean_motion(R_EARTH_M + 1e3 * cfg.formation.orbit_altitude_km))


def observer_positions(cfg: Config, t_s: np.ndarray) -> tuple[list[str], np.ndarray]:
    """Names and positions ``r_SiT_H (S, T, 3)`` of the candidate observers, m."""
    f = cfg.formation
    if f.geometry == "symmetric":
        r = symmetric_views(int(f.n_views), float(f.distance_m), float(f.axis_angle_deg)).r_CT_H
        names = [f"view {i}" for i in range(len(r))]
        return names, np.broadcast_to(r[:, None, :], (len(r), t_s.size, 3)).copy()
    x0 = np.array([[*s.r_H_m, *s.v_H_m_s] for s in f.spacecraft])
    x = propagate(x0, t_s, orbit_rate(cfg))
    return [s.name for s in f.spacecraft], x[..., :3]


def min_range_m(cfg: Config, target_radius_m: float) -> float:
    """``d_min`` of 003 eq (1) with λ = 1.1 (FLAG P003-1), unless the config gives one."""
    if cfg.formation.d_min_m is not None:
        return float(cfg.formation.d_min_m)
    return 1.1 * target_radius_m / np.tan(0.5 * np.deg2rad(cfg.camera.fov_deg))


def select_observers(r_H: np.ndarray, previous: np.ndarray | None, *, d_min_m: float, d_max_m: float,
                     max_comm_range_m: float, max_active: int, min_active: int,
                     axis_angle_range_deg: tuple[float, float] = (2.0, 60.0)) -> tuple[np.ndarray, str]:
    """Observers to activate at one epoch (003 §1.2 constraints ①, ③, ④; ② holds by pointing).

    Qualifying: range in ``(d_min, d_max)``.  Among subsets of ``min_active``..``max_active``
    qualifying observers whose pairwise lines of sight to the target differ by an angle inside
    ``axis_angle_range_deg`` (so the views can be matched) and whose separations are within the
    communication range, keep the previous set if it is still valid, else take the largest set,
    ties broken by the smaller mean range.

    Returns ``(active (S,) bool, reason)`` with ``reason = ""`` when a set was found.
    """
    S = r_H.shape[0]
    d = np.linalg.norm(r_H, axis=-1)
    ok = (d > d_min_m) & (d < d_max_m)
    cand = np.flatnonzero(ok)
    if cand.size < min_active:
        return np.zeros(S, bool), f"{cand.size} observers within range ({d_min_m:.0f}-{d_max_m:.0f} m)"
    u = r_H / d[:, None]
    lo, hi = np.deg2rad(axis_angle_range_deg[0]), np.deg2rad(axis_angle_range_deg[1])

    def valid(sub: tuple[int, ...]) -> bool:
        for i, j in itertools.combinations(sub, 2):
            ang = np.arccos(np.clip(u[i] @ u[j], -1, 1))
            if not lo <= ang <= hi or np.linalg.norm(r_H[i] - r_H[j]) > max_comm_range_m:
                return False
        return True

    if previous is not None and previous.sum() >= min_active and np.all(ok[previous]):
        sub = tuple(np.flatnonzero(previous))
        if len(sub) == min(max_active, cand.size) and valid(sub):
            return previous.copy(), ""
    for size in range(min(max_active, cand.size), min_active - 1, -1):
        best = None
        for sub in itertools.combinations(cand.tolist(), size):
            if valid(sub):
                score = float(np.mean(d[list(sub)]))
                if best is None or score < best[0]:
                    best = (score, sub)
        if best is not None:
            act = np.zeros(S, bool)
            act[list(best[1])] = True
            return act, ""
    return np.zeros(S, bool), "no observer set satisfies the line-of-sight angle and communication constraints"


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
    names, r = observer_positions(cfg, t)
    S = len(names)
    camera = make_camera(cfg)
    target = load_target(cfg)
    d_min = min_range_m(cfg, target.radius_m)
    sun_N = np.asarray(cfg.observation.sun_H, dtype=float)
    sun_N = sun_N / np.linalg.norm(sun_N)
    r_chief_N = (R_NH @ np.array([R_EARTH_M + 1e3 * cfg.formation.orbit_altitude_km, 0.0, 0.0]))
    lit = illumination_fraction(r_chief_N, sun_N * AU_M)
    sun_H = np.einsum("tji,j->ti", R_NH, sun_N)

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
        if cfg.formation.geometry == "symmetric":  # the cone is the formation: every view is active
            act, why = np.ones(S, bool), ""
        else:
            act, why = select_observers(r[:, k], prev_active, d_min_m=d_min, d_max_m=cfg.formation.d_max_m,
                                        max_comm_range_m=cfg.formation.max_comm_range_m,
                                        max_active=cfg.formation.max_active,
                                        min_active=cfg.formation.min_active)
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
        "median_tracks_per_epoch": float(np.median(n_tracks)),
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
