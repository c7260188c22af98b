"""003 Experiment A (Figs 5–6): the registration error of one (distance, axis angle, views) cell.

For each trial a random initial attitude is followed by ``steps`` equal increments Δθ (a rotation
vector in H, applied on the left as in 003 eq 32); every epoch is observed by the symmetric cone,
triangulated, associated with the previous one and registered (the :mod:`closed_loop` parts the
config names).  The metric is 003 eq (33), ``e_Δθ = ‖mean_k Δθ̂_k − Δθ‖``, with the per-step RMS
error and the Cramér–Rao bound of the same geometry beside it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import xarray as xr

from attitude.quaternion import (
    matrix_from_quat,
    quat_from_matrix,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    rotvec_from_quat,
)
from closed_loop import Frame, GeometricObserver, reconstruct_many
from experiments.scenarios.formation.config import Config
from experiments.scenarios.formation.parts import (
    load_target,
    make_camera,
    make_observer,
    make_registrar,
    symmetric_T_CW,
)
from experiments.sweep import Metric, SweepCell, cell_seed_sequences, child_seeds
from reconstruction.accuracy import attitude_increment_crlb
from vision.observation import Observation

__all__ = ["random_attitudes", "error_map_trials", "error_map_cell", "error_map_sweep_cell", "error_map_run"]


def random_attitudes(rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    """Uniformly distributed attitudes (normalised 4-D Gaussian), ``(4,)`` or ``(n, 4)``."""
    q = rng.normal(size=(4,) if n is None else (n, 4))
    return quat_normalize(q)


def _same_surface_points(prev: Observation, curr: Observation, tol_px: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """Tracks of two epochs that see the same surface point (truth only): indices ``(i_prev, i_curr)``.

    Two correctly matched tracks are the same point when their true body points lie within
    ``tol_px`` pixel footprints of each other at the cameras' range: the geometric mode's features
    coincide exactly; a rendered keypoint found again one 0.87° step later lands within 0.1–1.3 px
    of its first body point (correct associations at 40 and 80 m), a wrong one tens of pixels away;
    2 px is the truth tolerance of :func:`vision.rendered.label_tracks`.
    Each track of ``curr`` is paired at most once, with its nearest ``prev`` track.
    """
    from scipy.spatial import cKDTree

    ia, ib = np.flatnonzero(prev.feature_id >= 0), np.flatnonzero(curr.feature_id >= 0)
    if ia.size == 0 or ib.size == 0:
        return ia[:0], ib[:0]
    range_m = float(np.median(np.linalg.norm(prev.T_CW[:, :3, 3], axis=-1)))
    tol_m = tol_px * range_m / float(np.min(prev.K[:, 0, 0]))
    d_m, j = cKDTree(curr.X_T_true[ib]).query(prev.X_T_true[ia], distance_upper_bound=tol_m)
    keep = np.isfinite(d_m)
    ia, j, d_m = ia[keep], j[keep], d_m[keep]
    order = np.lexsort((d_m, j))
    first = np.ones(order.size, bool)
    first[1:] = j[order][1:] != j[order][:-1]
    return ia[order[first]], ib[j[order[first]]]


def _crlb_deg(prev: Frame, curr: Frame, q_HT: np.ndarray, dq_H: np.ndarray, T_CW: np.ndarray) -> float:
    """Cramér–Rao bound of one increment for the surface points tracked at both epochs, each epoch
    with the views that see the point then (``visible`` and ``visible_next``) and each keypoint's σ
    (:attr:`vision.observation.Observation.sigma_uv_px`: the configured σ, or the calibrated σ per
    keypoint size)."""
    ip, ic = _same_surface_points(prev.obs, curr.obs)
    if ip.size < 3:
        return float("nan")
    X_W = prev.obs.X_T_true[ip] @ matrix_from_quat(q_HT).T
    b = attitude_increment_crlb(X_W, prev.obs.K, T_CW, pixel_sigma_px=prev.obs.sigma_uv_px[ip],
                                pixel_sigma_px_next=curr.obs.sigma_uv_px[ic], visible=prev.obs.seen[ip],
                                visible_next=curr.obs.seen[ic], R_delta=matrix_from_quat(dq_H))
    return float(np.degrees(b.rms_angle_rad)) if bool(b.ok) else float("nan")


def error_map_trials(cfg: Config, seeds: Sequence[np.random.SeedSequence]) -> dict[str, np.ndarray]:
    """Experiment A at one (distance, axis angle, views): one trial per seed.

    Each trial: a uniformly random initial attitude ``q_HT0``, then ``steps`` increments
    ``Δq = exp(Δθ/2)`` applied on the left (H frame, 003 eq 32), observed, triangulated, associated
    and registered.  Three streams per trial (children of its seed): the initial attitude, the
    observations of all its epochs, and the registration (RANSAC).

    Returns
    -------
    dict of (trials,) arrays
        ``e_dtheta_deg`` (003 eq 33), ``step_rms_deg`` (RMS over steps of the rotation angle of
        ``ΔR̂ ΔRᵀ``), ``crlb_deg`` (Cramér–Rao RMS bound of one increment at the first step, for the
        surface points tracked at both epochs, each epoch with its own view sets),
        ``n_tracks``, ``n_matches``, ``n_inliers`` (medians over the epochs / steps),
        ``failed_steps``, and ``failure_reason``.
    """
    observer = make_observer(cfg, make_camera(cfg), load_target(cfg))
    registrar = make_registrar(cfg)
    T_CW = symmetric_T_CW(cfg)
    dtheta = np.deg2rad(np.asarray(cfg.error_map.step_deg, dtype=float))
    dq = quat_from_rotvec(dtheta)
    dR = matrix_from_quat(dq)
    steps = cfg.error_map.steps
    M = len(seeds)
    out = {k: np.full(M, np.nan) for k in ("e_dtheta_deg", "step_rms_deg", "crlb_deg", "n_tracks",
                                           "n_matches", "n_inliers", "failed_steps")}
    reasons = np.array([""] * M, dtype=object)
    sun = np.asarray(cfg.observation.sun_H, dtype=float)
    streams = [child_seeds(ss, 3) for ss in seeds]          # per trial: attitude, observations, registration
    qs_all = np.empty((M, steps + 1, 4))
    for t, (s_att, _, _) in enumerate(streams):
        qs_all[t, 0] = random_attitudes(np.random.default_rng(s_att))
        for k in range(steps):
            qs_all[t, k + 1] = quat_normalize(quat_multiply(dq, qs_all[t, k]))
    for t0 in range(0, M, _TRIALS_PER_BATCH):
        batch = range(t0, min(M, t0 + _TRIALS_PER_BATCH))
        frames_of = _observed_frames(observer, T_CW, qs_all[batch.start:batch.stop], sun,
                                     [streams[t][1] for t in batch])
        incs_of = _registered_steps(registrar, frames_of, [streams[t][2] for t in batch])
        for t, frames, incs in zip(batch, frames_of, incs_of, strict=True):
            out["crlb_deg"][t] = _crlb_deg(frames[0], frames[1], qs_all[t, 0], dq, T_CW)
            _trial_metrics(incs, [f.obs.n_tracks for f in frames], dR, dtheta, out, reasons, t)
    out["failure_reason"] = reasons
    return out


#: trials observed, triangulated and registered together (the calibrated geometric mode batches their
#: ray casting; the associations of all their steps run in one pass)
_TRIALS_PER_BATCH = 20


def _observed_frames(observer, T_CW: np.ndarray, qs: np.ndarray, sun_H: np.ndarray,
                     obs_seeds: Sequence[np.random.SeedSequence]) -> list[list[Frame]]:
    """Observe and triangulate the epochs ``qs (R, E, 4)`` of R trials, trial r with the stream ``obs_seeds[r]``.

    The geometric observer takes the trials in one call (:meth:`closed_loop.GeometricObserver.observe_trials`,
    each trial as its own :meth:`observe_epochs` call would); the rendered one epoch by epoch.  All
    the epochs are triangulated in one batch (:func:`closed_loop.reconstruct_many`).
    """
    R, E = qs.shape[:2]
    if isinstance(observer, GeometricObserver):
        sun_E = np.broadcast_to(sun_H / np.linalg.norm(sun_H), (R, E, 3))
        obs = observer.observe_trials(np.broadcast_to(T_CW, (R, E, *T_CW.shape)), qs, sun_E,
                                      rngs=[np.random.default_rng(s) for s in obs_seeds])
    else:
        obs = []
        for r in range(R):
            rngs = np.random.default_rng(obs_seeds[r]).spawn(E)
            obs.append([observer.observe(T_CW, qs[r, k], sun_H, rng=rngs[k]) for k in range(E)])
    flat = reconstruct_many([o for trial in obs for o in trial])
    return [flat[r * E:(r + 1) * E] for r in range(R)]


def _registered_steps(registrar, frames_of: list[list[Frame]],
                      reg_seeds: Sequence[np.random.SeedSequence]) -> list[list]:
    """The increments of every step of R trials (``frames_of[r]``: trial r's epochs), registered with
    one :meth:`closed_loop.registrars.Registrar.register_pairs` call (the associations of all the
    steps in one pass; the fits trial by trial, step by step, each trial from its own stream
    ``reg_seeds[r]``, as :meth:`~closed_loop.registrars.Registrar.register` step by step would give)."""
    flat = [f for frames in frames_of for f in frames]
    pairs, rngs, start = [], [], 0
    for frames, s_reg in zip(frames_of, reg_seeds, strict=True):
        rng = np.random.default_rng(s_reg)
        pairs += [(start + k - 1, start + k) for k in range(1, len(frames))]
        rngs += [rng] * (len(frames) - 1)
        start += len(frames)
    incs = registrar.register_pairs(flat, pairs, rngs=rngs, with_covariance=False)
    out, start = [], 0
    for frames in frames_of:
        out.append(incs[start:start + len(frames) - 1])
        start += len(frames) - 1
    return out


def _trial_metrics(incs: list, tracks: list[int], dR: np.ndarray, dtheta: np.ndarray,
                   out: dict[str, np.ndarray], reasons: np.ndarray, t: int) -> None:
    """Write row ``t`` of ``out`` / ``reasons`` from the trial's step increments ``incs`` and its
    tracks per epoch."""
    steps = len(incs)
    est, errs, inliers, matches = [], [], [], []
    why = ""
    for inc in incs:
        matches.append(inc.n_matches)
        if inc.ok:
            inliers.append(inc.n_inliers)
            est.append(rotvec_from_quat(quat_from_matrix(inc.R_H)))
            errs.append(np.linalg.norm(rotvec_from_quat(quat_from_matrix(inc.R_H @ dR.T))))
        else:
            why = why or inc.failure_reason
    out["n_tracks"][t] = np.median(tracks)
    out["n_matches"][t] = np.median(matches) if matches else 0
    out["failed_steps"][t] = steps - len(est)
    if not est:
        reasons[t] = f"every step failed; first: {why}"
        return
    out["n_inliers"][t] = np.median(inliers)
    out["e_dtheta_deg"][t] = np.degrees(np.linalg.norm(np.mean(est, axis=0) - dtheta))
    out["step_rms_deg"][t] = np.degrees(np.sqrt(np.mean(np.square(errs))))


def error_map_cell(cfg: Config, seeds: Sequence[np.random.SeedSequence]) -> dict[str, np.ndarray]:
    """Sweep cell of Experiment A (:func:`error_map_trials`), plus the filter-driven convergence.

    With ``error_map.filter_runs > 0`` the EKF of 003 Experiments B–D is run ``filter_runs`` times
    with measurements whose attitude-angle error is this cell's median measured error
    (``error_map.filter_error``: the per-step RMS by default, or e_Δθ) — the paper's way of
    producing Figs 11–12 from Figs 5–6 — giving the fraction of converged runs and the median
    convergence time of the cell.
    """
    out = error_map_trials(cfg, seeds)
    runs = cfg.error_map.filter_runs
    frac = tmed = e_used = np.nan
    if runs > 0:
        from experiments.scenarios.formation.ekf import monte_carlo, role_generator, truth_history

        stat = out["step_rms_deg" if cfg.error_map.filter_error == "step_rms" else "e_dtheta_deg"]
        e = stat[np.isfinite(stat)]
        if e.size:
            e_used = float(np.median(e))
            t, q, w = truth_history(cfg)
            mc = monte_carlo(cfg, t, q, w, e_deg=e_used, window=None, runs=runs, rng=role_generator(seeds, 2))
            frac = mc.fraction_converged
            tmed = mc.median_convergence_time_s
    out["filter_measurement_error_deg"] = np.asarray(e_used)
    out["filter_fraction_converged"] = np.asarray(frac)
    out["filter_median_convergence_time_s"] = np.asarray(tmed)
    return out


def error_map_sweep_cell(cfg: Config) -> SweepCell:
    """The sweep cell of Experiment A (:func:`error_map_cell`) with its metrics."""
    return SweepCell(
        fn=error_map_cell,
        metrics={
            "e_dtheta_deg": Metric("deg", long_name="003 eq (33): |mean estimated increment - commanded|"),
            "step_rms_deg": Metric("deg", long_name="RMS over steps of the increment's rotation error"),
            "crlb_deg": Metric("deg", long_name="Cramer-Rao RMS bound of one increment"),
            "n_tracks": Metric("1", long_name="median multi-view tracks per epoch"),
            "n_matches": Metric("1", long_name="median associated pairs per step"),
            "n_inliers": Metric("1", long_name="median registration inliers per step"),
            "failed_steps": Metric("1", long_name="steps whose registration failed"),
            "filter_measurement_error_deg": Metric("deg", per_trial=False,
                                                   long_name="EKF measurement error: the cell's median error statistic"),
            "filter_fraction_converged": Metric("1", per_trial=False,
                                                long_name="fraction of EKF runs converged"),
            "filter_median_convergence_time_s": Metric("s", per_trial=False,
                                                       long_name="median convergence time of the EKF runs"),
        },
        name="error_map",
    )


def error_map_run(cfg: Config, *, progress: Callable[[int, int], None] | None = None) -> tuple[xr.Dataset, dict]:
    """The ``error_map`` study: one cell of Experiment A with ``trials`` initial attitudes.

    Returns the per-trial dataset (the cell's metrics over ``trial``) and a summary of medians.
    """
    cell = error_map_sweep_cell(cfg)
    seeds = cell_seed_sequences(cfg.seed, {}, cfg.trials)
    if progress:
        progress(0, 1)
    out = cell.fn(cfg, seeds)
    if progress:
        progress(1, 1)
    data = {}
    for name, m in cell.metrics.items():
        dims = ("trial",) if m.per_trial else ()
        data[name] = (dims, np.asarray(out[name], dtype=float), {"units": m.units, "long_name": m.long_name})
    data["failure_reason"] = ("trial", np.asarray(out["failure_reason"]).astype(str))
    f = cfg.formation
    ds = xr.Dataset(data, coords={"trial": np.arange(cfg.trials)},
                    attrs={"study": "error_map", "distance_m": f.distance_m, "axis_angle_deg": f.axis_angle_deg,
                           "n_views": f.n_views, "registration": cfg.estimator.registration,
                           "observation_mode": cfg.observation.mode})
    e = ds.e_dtheta_deg.values
    summary = {
        "distance_m": f.distance_m, "axis_angle_deg": f.axis_angle_deg, "n_views": f.n_views,
        "median_e_dtheta_deg": float(np.nanmedian(e)) if np.isfinite(e).any() else float("nan"),
        "median_step_rms_deg": float(np.nanmedian(ds.step_rms_deg.values)),
        "median_crlb_deg": float(np.nanmedian(ds.crlb_deg.values)),
        "failed_trials": int((ds.failure_reason.values != "").sum()),
    }
    return ds, summary
