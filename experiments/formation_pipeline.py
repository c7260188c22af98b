"""The 003 measurement pipeline of one epoch pair, and Experiment A (Figs 5–6) as a sweep cell.

Per epoch (ARCHITECTURE §3): observe the target with every active camera (``rendered``:
:func:`vision.rendered.observe`; ``geometric``: :func:`vision.geometric.observe`), triangulate the
multi-view tracks (:func:`reconstruction.triangulation.triangulate_from_observation`); between
consecutive epochs associate the tracks (:func:`reconstruction.association.associate_from_observations`)
and register the matched clouds (:mod:`reconstruction.registration`).  The registration rotation is
the attitude increment of the target in the observation frame H (003 eq 30–32).

Registration methods (``estimator.registration``):

``"kabsch"``
    the paper's weighted rigid registration 003 eq (11)–(13), weights ``1/(W_ρ + ε₀)`` (FLAG P003-4);
``"ransac"``
    the same after a 3-point RANSAC with the covariance chi-square gate (FLAG P003-6's check);
``"ml"``
    covariance-aware maximum likelihood (:func:`reconstruction.registration.fit_rigid_ml`), which
    attains the Cramér–Rao bound of :func:`reconstruction.accuracy.attitude_increment_crlb`.

Experiment A (:func:`error_map_cell`): for each trial a random initial attitude followed by
``steps`` equal increments Δθ (a rotation vector in H, 003 eq 32's left multiplication); the metric
is 003 eq (33), ``e_Δθ = ‖mean_k Δθ̂_k − Δθ‖``, with the per-step RMS error and the Cramér–Rao bound
of the same geometry beside it.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from attitude.quaternion import (
    matrix_from_quat,
    quat_from_matrix,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    rotvec_from_quat,
)
from experiments.formation_config import Config
from experiments.sweep import Metric, SweepCell, child_seeds
from formation.geometry import symmetric_views
from reconstruction.accuracy import attitude_increment_crlb
from reconstruction.association import associate_from_observations
from reconstruction.registration import RigidRegistration, fit_rigid, fit_rigid_ml, fit_rigid_robust
from reconstruction.triangulation import Triangulation, triangulate, triangulate_from_observation
from vision.camera import PinholeCamera
from vision.observation import Observation
from vision.target import Target, fy1_target, load_mesh

__all__ = [
    "load_target",
    "make_camera",
    "observe_epoch",
    "Frame",
    "reconstruct",
    "register_frames",
    "Increment",
    "random_attitudes",
    "error_map_trials",
    "error_map_cell",
    "error_map_sweep_cell",
]


@functools.lru_cache(maxsize=4)
def _target_cached(model: str, unit_m: float, seed: int, path: str) -> Target:
    if model == "fy1":
        return fy1_target(seed=seed)
    return load_mesh(path, unit_m=unit_m, seed=seed)


def load_target(cfg: Config) -> Target:
    """The configured target model (built once per process; :class:`vision.target.Target` is immutable)."""
    t = cfg.target
    path = t.mesh_path()
    return _target_cached(t.model, float(t.mesh_unit_m), int(t.texture_seed), str(path) if path else "")


def make_camera(cfg: Config) -> PinholeCamera:
    c = cfg.camera
    return PinholeCamera.from_fov(c.width_px, c.height_px, fov_x_deg=c.fov_deg)


def observe_epoch(cfg: Config, camera: PinholeCamera, T_CW: np.ndarray, target: Target, q_HT: np.ndarray,
                  *, rng: np.random.Generator, sun_visible_fraction: float = 1.0) -> Observation:
    """One epoch seen by the cameras ``T_CW (n, 4, 4)`` in the configured observation mode."""
    o = cfg.observation
    sun = np.asarray(o.sun_H, dtype=float)
    sun = sun / np.linalg.norm(sun)
    if o.mode == "rendered":
        from vision.rendered import observe

        return observe(camera, T_CW, target, q_HT, sun, rng=rng, detector=o.detector,
                       pixel_sigma_px=o.pixel_sigma_px, sun_visible_fraction=sun_visible_fraction)
    return observe_epochs_geometric(cfg, camera, T_CW[None], target, np.asarray(q_HT)[None], sun[None],
                                    rng=rng, sun_visible_fraction=sun_visible_fraction)[0]


def observe_epochs_geometric(cfg: Config, camera: PinholeCamera, T_CW: np.ndarray, target: Target,
                             q_HT: np.ndarray, sun_H: np.ndarray, *, rng: np.random.Generator,
                             sun_visible_fraction: float | np.ndarray = 1.0) -> list[Observation]:
    """Geometric-mode observations of E epochs in one call (:func:`vision.geometric.observe_epochs`).

    ``T_CW (E, n, 4, 4)``, ``q_HT (E, 4)``, ``sun_H (E, 3)``; the draws depend on the whole call, so
    a call must cover one trial's epochs only.
    """
    from vision.geometric import observe_epochs

    o = cfg.observation
    return observe_epochs(camera, T_CW, target, q_HT, sun_H, rng=rng, features=_features(cfg, target),
                          pixel_sigma_px=o.pixel_sigma_px, false_match_fraction=o.false_match_fraction,
                          sun_visible_fraction=sun_visible_fraction)


@functools.lru_cache(maxsize=4)
def _features_cached(target: Target, n_features: int):
    from vision.geometric import surface_features

    return surface_features(target, n_features=n_features)


def _features(cfg: Config, target: Target):
    return _features_cached(target, int(cfg.observation.n_features))


@dataclass(frozen=True)
class Frame:
    """An epoch's observation and its triangulated cloud."""

    obs: Observation
    tri: Triangulation

    @property
    def ok(self) -> bool:
        return bool(self.obs.ok and np.all(self.tri.ok))


def reconstruct(obs: Observation) -> Frame:
    """Triangulate an observation (an empty or failed observation gives a flagged frame)."""
    return Frame(obs=obs, tri=triangulate_from_observation(obs))


def reconstruct_many(observations: Sequence[Observation]) -> list[Frame]:
    """:func:`reconstruct` for several epochs of the same cameras in one batched triangulation.

    The tracks are padded with NaN to a common count (padding rows come back invalid), solved in
    one call of :func:`reconstruction.triangulation.triangulate`, and sliced back per epoch.
    """
    good = [o for o in observations if o.ok and o.n_tracks > 0]
    if len(good) < 2 or any(o.n_views != good[0].n_views for o in good):
        return [reconstruct(o) for o in observations]
    m = max(o.n_tracks for o in good)
    n = good[0].n_views
    uv = np.full((len(good), m, n, 2), np.nan)
    for e, o in enumerate(good):
        uv[e, : o.n_tracks] = o.uv_px
    batch = triangulate(uv, good[0].K, good[0].T_CW, pixel_sigma_px=good[0].pixel_sigma_px)
    frames: list[Frame] = []
    e = 0
    for o in observations:
        if not (o.ok and o.n_tracks > 0):
            frames.append(reconstruct(o))
            continue
        k = o.n_tracks
        sl = (e, slice(0, k))
        n_valid = int(np.sum(batch.valid[sl]))
        tri = Triangulation(
            X_W=batch.X_W[sl], cov_W=batch.cov_W[sl], valid=batch.valid[sl], status=batch.status[sl],
            views_used=batch.views_used[sl], n_views=batch.n_views[sl],
            rms_reprojection_px=batch.rms_reprojection_px[sl], chi2=batch.chi2[sl],
            n_valid=np.asarray(n_valid), ok=n_valid > 0,
            failure_reason="" if n_valid > 0 else str(np.asarray(batch.failure_reason)[e]))
        frames.append(Frame(obs=o, tri=tri))
        e += 1
    return frames


@dataclass(frozen=True)
class Increment:
    """The registered attitude increment between two frames.

    Attributes
    ----------
    R_H : ndarray (3, 3)
        Estimated ΔR in H (NaN when not ok).
    cov_rotvec_H : ndarray (3, 3)
        Covariance of the left rotation-vector error, rad² (from ML, else from the fit's residuals);
        NaN when unavailable.
    n_matches : int
        Associated point pairs.
    n_inliers : int
        Pairs used in the final fit.
    ok : bool
    failure_reason : str
    """

    R_H: np.ndarray
    cov_rotvec_H: np.ndarray
    n_matches: int
    n_inliers: int
    ok: bool
    failure_reason: str


def _failed_increment(reason: str, n_matches: int = 0) -> Increment:
    return Increment(np.full((3, 3), np.nan), np.full((3, 3), np.nan), n_matches, 0, False, reason)


def register_frames(cfg: Config, prev: Frame, nxt: Frame, *, rng: np.random.Generator,
                    with_covariance: bool = True) -> Increment:
    """Associate two frames' tracks and register the matched clouds (method: ``estimator.registration``).

    ``with_covariance``: when the method gives none (Kabsch, RANSAC), estimate it from the fit's
    residuals (:func:`_residual_rotation_covariance`; needed by the filter, not by the error maps).
    """
    if not prev.ok:
        return _failed_increment(f"previous epoch: {prev.obs.status if not prev.obs.ok else prev.tri.failure_reason}")
    if not nxt.ok:
        return _failed_increment(f"this epoch: {nxt.obs.status if not nxt.obs.ok else nxt.tri.failure_reason}")
    assoc = associate_from_observations(prev.obs, nxt.obs, prev.tri, nxt.tri)
    k = int(assoc.idx_prev.size)
    if not assoc.ok:
        return _failed_increment(f"association: {assoc.failure_reason}", k)
    P = prev.tri.X_W[assoc.idx_prev]
    Q = nxt.tri.X_W[assoc.idx_next]
    cP = prev.tri.cov_W[assoc.idx_prev]
    cQ = nxt.tri.cov_W[assoc.idx_next]
    method = cfg.estimator.registration
    if method == "kabsch":
        w = 1.0 / (prev.tri.weight[assoc.idx_prev] ** -1 + nxt.tri.weight[assoc.idx_next] ** -1)
        reg: RigidRegistration = fit_rigid(P, Q, weights=w)
    elif method == "ransac":
        reg = fit_rigid_robust(P, Q, cov_P=cP, cov_Q=cQ, rng=rng)
    else:
        reg = fit_rigid_ml(P, Q, cP, cQ, rng=rng)
    if not bool(reg.ok):
        return _failed_increment(f"registration: {reg.failure_reason}", k)
    cov = reg.cov[:3, :3]
    if with_covariance and not np.all(np.isfinite(cov)):
        cov = _residual_rotation_covariance(P, Q, reg)
    return Increment(R_H=reg.R, cov_rotvec_H=cov, n_matches=k, n_inliers=int(reg.n_inliers), ok=True,
                     failure_reason="")


def _residual_rotation_covariance(P: np.ndarray, Q: np.ndarray, reg: RigidRegistration) -> np.ndarray:
    """Rotation covariance of a least-squares rigid fit from its own residuals (Kabsch, RANSAC).

    With isotropic residuals of variance ``σ² = Σ‖rᵢ‖² / (3N − 6)`` per axis, the left rotation
    error of the fit has covariance ``σ² (Σᵢ [Q̃ᵢ×]ᵀ [Q̃ᵢ×])⁻¹`` (``Q̃`` the inlier points about their
    centroid).  Unlike the Cramér–Rao bound this describes the estimator actually used: the spread of
    its residuals includes the depth-elongated triangulation errors it does not weight.
    """
    inl = np.asarray(reg.inliers, dtype=bool) & np.all(np.isfinite(P), -1) & np.all(np.isfinite(Q), -1)
    n = int(inl.sum())
    if n < 3:
        return np.full((3, 3), np.nan)
    p, q = P[inl], Q[inl]
    r = q - p @ reg.R.T - reg.t
    sigma2 = float(np.sum(r * r) / max(3 * n - 6, 1))
    qc = q - q.mean(axis=0)
    info = np.sum(qc * qc) * np.eye(3) - qc.T @ qc  # Σ [q̃×]ᵀ[q̃×] = Σ (|q̃|² I − q̃ q̃ᵀ)
    return sigma2 * np.linalg.inv(info)


# ----------------------------------------------------------------------------- Experiment A


def random_attitudes(rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    """Uniformly distributed attitudes (normalised 4-D Gaussian), ``(4,)`` or ``(n, 4)``."""
    q = rng.normal(size=(4,) if n is None else (n, 4))
    return quat_normalize(q)


def _views(cfg: Config) -> np.ndarray:
    f = cfg.formation
    return symmetric_views(int(f.n_views), float(f.distance_m), float(f.axis_angle_deg)).T_CW


def _crlb_deg(cfg: Config, frame: Frame, q_HT: np.ndarray, dq_H: np.ndarray, T_CW: np.ndarray) -> float:
    """Cramér–Rao bound of one increment for the true surface points the cameras track."""
    obs = frame.obs
    good = obs.feature_id >= 0
    if good.sum() < 3:
        return float("nan")
    X_W = obs.X_T_true[good] @ matrix_from_quat(q_HT).T
    b = attitude_increment_crlb(X_W, obs.K, T_CW, pixel_sigma_px=obs.pixel_sigma_px,
                                visible=obs.seen[good], R_delta=matrix_from_quat(dq_H))
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
        ``ΔR̂ ΔRᵀ``), ``crlb_deg`` (Cramér–Rao RMS bound of one increment at the first step),
        ``n_tracks``, ``n_matches``, ``n_inliers`` (medians over the epochs / steps),
        ``failed_steps``, and ``failure_reason``.
    """
    camera = make_camera(cfg)
    target = load_target(cfg)
    T_CW = _views(cfg)
    dtheta = np.deg2rad(np.asarray(cfg.error_map.step_deg, dtype=float))
    dq = quat_from_rotvec(dtheta)
    dR = matrix_from_quat(dq)
    steps = cfg.error_map.steps
    M = len(seeds)
    out = {k: np.full(M, np.nan) for k in ("e_dtheta_deg", "step_rms_deg", "crlb_deg", "n_tracks",
                                           "n_matches", "n_inliers", "failed_steps")}
    reasons = np.array([""] * M, dtype=object)
    for t, ss in enumerate(seeds):
        s_att, s_obs, s_reg = child_seeds(ss, 3)
        q0 = random_attitudes(np.random.default_rng(s_att))
        qs = [q0]
        for _ in range(steps):
            qs.append(quat_normalize(quat_multiply(dq, qs[-1])))
        qs = np.array(qs)
        if cfg.observation.mode == "geometric":
            sun = np.asarray(cfg.observation.sun_H, dtype=float)
            sun = np.broadcast_to(sun / np.linalg.norm(sun), (steps + 1, 3))
            observations = observe_epochs_geometric(cfg, camera, np.broadcast_to(T_CW, (steps + 1, *T_CW.shape)),
                                                    target, qs, sun, rng=np.random.default_rng(s_obs))
        else:
            obs_rngs = np.random.default_rng(s_obs).spawn(steps + 1)
            observations = [observe_epoch(cfg, camera, T_CW, target, qs[k], rng=obs_rngs[k])
                            for k in range(steps + 1)]
        reg_rng = np.random.default_rng(s_reg)
        frames = reconstruct_many(observations)
        est, errs, inliers, matches = [], [], [], []
        tracks = [f.obs.n_tracks for f in frames]
        out["crlb_deg"][t] = _crlb_deg(cfg, frames[0], qs[0], dq, T_CW)
        why = ""
        for k in range(1, steps + 1):
            inc = register_frames(cfg, frames[k - 1], frames[k], rng=reg_rng, with_covariance=False)
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
            continue
        out["n_inliers"][t] = np.median(inliers)
        out["e_dtheta_deg"][t] = np.degrees(np.linalg.norm(np.mean(est, axis=0) - dtheta))
        out["step_rms_deg"][t] = np.degrees(np.sqrt(np.mean(np.square(errs))))
    out["failure_reason"] = reasons
    return out


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
        from experiments.formation_ekf import _monte_carlo, role_generator, truth_history

        stat = out["step_rms_deg" if cfg.error_map.filter_error == "step_rms" else "e_dtheta_deg"]
        e = stat[np.isfinite(stat)]
        if e.size:
            e_used = float(np.median(e))
            t, q, w = truth_history(cfg)
            mc = _monte_carlo(cfg, t, q, w, e_deg=e_used, window=None, runs=runs, rng=role_generator(seeds, 2))
            frac = mc.fraction_converged
            tmed = mc.median_convergence_time_s
    out["filter_measurement_error_deg"] = np.asarray(e_used)
    out["filter_fraction_converged"] = np.asarray(frac)
    out["filter_median_convergence_time_s"] = np.asarray(tmed)
    return out


def error_map_sweep_cell(cfg: Config) -> SweepCell:
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
