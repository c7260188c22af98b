"""The closed loop with a target model and a factor-graph smoother (``map`` + ``smoother``).

Each epoch: the smoother gets the new epoch through the torque-free dynamics
(:class:`closed_loop.smoother.AttitudeSmoother`); the active observers see the target; the frame
is registered to the previous epoch (003 §1.5, as in :class:`closed_loop.loop.ClosedLoop`) and, with
a target model (:class:`closed_loop.target_model.TargetModel`), to the keyframes it sees the same
faces of, by descriptors within the viewpoint window.  After a gap (no accepted registration for
``reacquire_after_s``: an eclipse, a lost observer set) every keyframe is tried, by descriptors
within the window and by geometry (:func:`closed_loop.reacquisition.register_by_geometry`) beyond it.

Every registration passes the registrar's evidence checks (:mod:`closed_loop.evidence`) and the
smoother's χ² gate against the predicted attitude before it becomes a factor; a refused one is
counted and its reason kept.  The estimate recorded at each epoch is iSAM2's online estimate with
its marginal covariance.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from attitude.quaternion import matrix_from_quat, quat_angle_between, quat_from_matrix
from closed_loop.frames import Frame
from closed_loop.loop import (
    INITIAL_EPOCH,
    SET_CHANGED,
    ClosedLoopResult,
    Snapshot,
    observe_epoch,
    observer_tracks,
)
from closed_loop.observers import Observer
from closed_loop.reacquisition import register_by_geometry
from closed_loop.registrars import Registrar, RegistrationIncrement
from closed_loop.smoother import AttitudeSmoother, SmootherSettings
from closed_loop.target_model import ModelSettings, TargetModel
from filters import AttitudeFilter, FilterState

__all__ = ["SmoothingLoop", "SmootherStart"]

NO_LINK = "no registration accepted"

#: σ of the first attitude when the first frame defines the body frame, rad (four orders below a frame's error)
DEFINED_ATTITUDE_SIGMA_RAD = 1e-7


@dataclass(frozen=True)
class SmootherStart:
    """The smoother's prior at the first epoch.

    Attributes
    ----------
    q_NT : ndarray (4,)
    cov_attitude_T : ndarray (3, 3)
        Body-frame rotation-vector covariance, rad².
    omega_TN_T_rad_s : ndarray (3,)
    cov_omega : ndarray (3, 3)
        (rad/s)².
    """

    q_NT: np.ndarray
    cov_attitude_T: np.ndarray
    omega_TN_T_rad_s: np.ndarray
    cov_omega: np.ndarray

    @classmethod
    def from_filter_state(cls, estimator: AttitudeFilter, state: FilterState, *,
                          attitude_defined: bool = False) -> SmootherStart:
        """The prior a filter would start from (:func:`closed_loop.initial_estimate`), as the smoother's.

        ``attitude_defined``: the first frame defines the body frame (flag P003-14a,
        docs/papers.md#p003-14a), so the first attitude has no error, only the σ
        :data:`DEFINED_ATTITUDE_SIGMA_RAD` that keeps the prior finite.  A filter's start σ there
        (``estimator.sigma_q_known``) would stay in every later covariance while the error has
        no such part: in the 300 s runs it left the average NEES at 1.1 instead of 3.
        """
        C = estimator.tangent_covariance(state)[0]
        cov_a = DEFINED_ATTITUDE_SIGMA_RAD ** 2 * np.eye(3) if attitude_defined else C[:3, :3]
        return cls(q_NT=state.q_NT[0], cov_attitude_T=cov_a, omega_TN_T_rad_s=state.omega_TN_T[0],
                   cov_omega=C[3:6, 3:6])


@dataclass(frozen=True)
class SmoothingLoop:
    """Observer, registrar, optional target model and the gtsam smoother (module docstring).

    Attributes
    ----------
    observer : closed_loop.observers.Observer
    registrar : closed_loop.registrars.Registrar
        The fit used for every descriptor registration (and its evidence thresholds).
    J_prior_kg_m2 : ndarray (3, 3)
        The inertia the smoother starts from (held fixed unless ``settings.estimate_inertia``).
    settings : closed_loop.smoother.SmootherSettings
    model : closed_loop.target_model.ModelSettings or None
        ``None``: register to the previous epoch only (the smoother replaces the filter).
    min_observers : int
    """

    observer: Observer
    registrar: Registrar
    J_prior_kg_m2: np.ndarray
    settings: SmootherSettings = field(default_factory=SmootherSettings)
    model: ModelSettings | None = field(default_factory=ModelSettings)
    min_observers: int = 2

    def run(self, t_s: np.ndarray, q_HT: np.ndarray, R_NH: np.ndarray, sun_H: np.ndarray, illumination: np.ndarray,
            r_H: np.ndarray, start: SmootherStart, *, rng_observe: np.random.Generator,
            rng_register: np.random.Generator, active: np.ndarray | None = None,
            inactive_reason: Sequence[str] | None = None, snapshot_from: int | None = None,
            progress: Callable[[int, int], None] | None = None) -> ClosedLoopResult:
        """Run over ``T`` epochs; the arguments are those of :meth:`closed_loop.ClosedLoop.run`, with
        the smoother's prior ``start`` in place of a filter state."""
        T = len(t_s)
        r_H, active = observer_tracks(T, r_H, active)
        S = r_H.shape[0]
        obs_rngs = rng_observe.spawn(T)
        sm = AttitudeSmoother(J_prior_kg_m2=np.asarray(self.J_prior_kg_m2, float), settings=self.settings)
        sm.start(float(t_s[0]), matrix_from_quat(start.q_NT), start.cov_attitude_T, start.omega_TN_T_rad_s,
                 start.cov_omega)
        model = TargetModel(self.model) if self.model is not None else None
        rec = _Records(T, S)
        prev: Frame | None = None
        prev_active: np.ndarray | None = None
        snap: Snapshot | None = None
        last_link_s = float(t_s[0])
        if progress:
            progress(0, T)
        for k in range(T):
            if k > 0:
                sm.add_epoch(float(t_s[k]))
            act = active[k]
            rec.active[k] = act
            why = "" if inactive_reason is None else str(inactive_reason[k])
            frame = None
            if act.sum() >= self.min_observers:
                frame, T_CW = observe_epoch(self.observer, r_H[act, k], q_HT[k], sun_H[k], float(illumination[k]),
                                            obs_rngs[k])
                rec.n_tracks[k] = frame.obs.n_tracks
                rec.n_points[k] = int(np.sum(frame.tri.n_valid))
                if snapshot_from is not None and k >= snapshot_from and snap is None and frame.ok:
                    snap = Snapshot(k, T_CW, frame, np.flatnonzero(act), sun_H[k])
                why = why or frame.failure_reason
            if k == 0:
                if model is not None and frame is not None:
                    model.add(0, frame, R_NH[0], r_H[act, 0])
            elif frame is not None and frame.ok:
                reacquire = t_s[k] - last_link_s > (self.model.reacquire_after_s if self.model else np.inf)
                links, reasons, best_kf = self._links(k, frame, prev, prev_active, act, model, sm, R_NH, r_H[act, k],
                                                      q_HT, reacquire, rng_register, rec)
                if links:
                    last_link_s = float(t_s[k])
                elif reasons:
                    why = why or reasons[0]
                if model is not None and model.wants(frame, best_kf):
                    model.add(k, frame, R_NH[k], r_H[act, k])
            if k > 0:
                sm.update()
            rec.ok[k] = rec.n_links[k] > 0
            rec.reason[k] = INITIAL_EPOCH if k == 0 else ("" if rec.ok[k] else (why or NO_LINK))
            R, w = sm.estimate(k)
            rec.q[k] = quat_from_matrix(R)
            rec.w[k] = w
            rec.cov_a[k], rec.cov_w[k] = sm.covariance_T(k)
            prev, prev_active = frame, act
            if progress:
                progress(k + 1, T)
        gap_s = self.model.reacquire_after_s if self.model is not None else 0.0
        rec.gaps = _gaps(np.asarray(t_s, float), rec.n_links, rec.closure, gap_s)
        return rec.result(snap, sm.inertia(), len(model.keyframes) if model is not None else 0)

    def _links(self, k, frame, prev, prev_active, act, model, sm, R_NH, r_CT_H, q_HT, reacquire, rng, rec):
        """Register the epoch to the previous one and to keyframes; add the accepted ones to ``sm``."""
        links: list[tuple[int, RegistrationIncrement, str]] = []
        reasons: list[str] = []
        best_kf = 0
        tries: list[tuple[int, Frame, np.ndarray, str]] = []
        if prev is not None and prev.ok and np.array_equal(act, prev_active):
            tries.append((k - 1, prev, R_NH[k - 1], "previous"))
        elif prev is not None:
            reasons.append(SET_CHANGED)
        if model is not None:
            cands = model.candidates(k, R_NH[k], r_CT_H, sm.estimate(k)[0], lambda j: sm.estimate(j)[0], t_s=sm.times[k],
                                     everything=reacquire, exclude=(k - 1,))
            for kf, angle in cands:
                mode = "descriptors" if angle <= model.settings.viewpoint_window_deg else "geometry"
                tries.append((kf.epoch, kf.frame, kf.R_NH, mode))
        accepted: list[tuple] = []
        R_k, _ = sm.estimate(k)  # the prediction: no update within the epoch
        for j, other, R_NH_j, mode in tries:
            dR_H_pred = R_NH[k].T @ (R_k @ sm.estimate(j)[0].T) @ R_NH_j
            if mode == "geometry":
                inc = register_by_geometry(other, frame, dR_H_pred, rng=rng, evidence=self.registrar.evidence)
            else:
                inc = self.registrar.register(other, frame, rng=rng, view_agnostic=mode != "previous",
                                              R0=dR_H_pred)
            if mode == "previous":
                rec.n_matches[k] = inc.n_matches
            if not inc.usable:
                reasons.append(inc.failure_reason)
                rec.n_rejected[k] += int(inc.n_matches > 0)
                continue
            dR_N = R_NH[k] @ inc.R_H @ R_NH_j.T
            cov_N = R_NH[k] @ inc.cov_rotvec_H @ R_NH[k].T
            gate = sm.gate(j, k, dR_N, cov_N)
            if not gate.accepted:
                reasons.append(f"innovation chi2 {gate.chi2:.3g} above {gate.threshold:.3g}")
                rec.n_rejected[k] += 1
                continue
            accepted.append((j, other, R_NH_j, dR_N, cov_N, inc, mode))
        # each frame's share (its cloud's orientation error, common to its registrations) over the points
        # registrations confirmed: this epoch's inliers for the new frame, the first link's for an older one
        _add_share(sm, rec.share, k, frame, R_NH[k], [inc.inliers_curr for *_, inc, _ in accepted])
        for j, other, R_NH_j, dR_N, cov_N, inc, mode in accepted:
            _add_share(sm, rec.share, j, other, R_NH_j, [inc.inliers_prev])
            rem, fit = _remainder(cov_N, dR_N, (frame, R_NH[k], inc.inliers_curr, rec.share.get(k)),
                                  (other, R_NH_j, inc.inliers_prev, rec.share.get(j)))
            if mode == "previous":  # the fit's excess enters this increment and the next alike
                sm.add_relative(j, k, dR_N, cov_N, remainder_N=rem, symmetric_N=fit)
            else:
                sm.add_relative(j, k, dR_N, cov_N, remainder_N=rem + fit, inflation=model.settings.closure_inflation)
            links.append((j, inc, mode))
            rec.n_links[k] += 1
            if mode != "previous":
                model.linked(j, sm.times[k])
                best_kf = max(best_kf, inc.n_inliers)
                rec.closure[k] = rec.closure[k] or mode
            else:
                true = matrix_from_quat(q_HT[k]) @ matrix_from_quat(q_HT[k - 1]).T
                rec.inc_err[k] = np.degrees(quat_angle_between(quat_from_matrix(inc.R_H), quat_from_matrix(true)))
                rec.inc_sigma[k] = np.degrees(np.sqrt(np.trace(inc.cov_rotvec_H)))
        return links, reasons, best_kf


def _add_share(sm: AttitudeSmoother, shares: dict, k: int, frame: Frame, R_NH_k: np.ndarray,
               inliers: list[np.ndarray]) -> None:
    """Give epoch ``k``'s frame its cloud-orientation share in ``sm`` (once) over the union of ``inliers``
    (kept in ``shares``: epoch → track indices, the frames that have one)."""
    if k in shares or not inliers:
        return
    pts = np.unique(np.concatenate(inliers))
    cf = frame.rotation_covariance_H(pts)
    if np.all(np.isfinite(cf)):
        sm.add_frame(k, R_NH_k @ cf @ R_NH_k.T)
        shares[k] = pts


def _remainder(cov_N: np.ndarray, dR_N: np.ndarray, curr: tuple, prev: tuple) -> tuple[np.ndarray, np.ndarray]:
    """The parts of a registration's error that the frames' shares do not hold (N, rad²): the subsets' and the fit's.

    The registration's error is the difference of the orientation errors of the point subsets it
    used, plus whatever the fit adds beyond them; the graph holds each frame's error over its share
    (:meth:`closed_loop.frames.Frame.subset_excess_covariance_H`).  Each side is
    ``(frame, R_NH, used tracks, share tracks or None)``; the earlier side is carried by ``dR_N``.
    Returns the two subsets' excess over the shares and the fit's excess over the subsets'
    own orientation errors (``cov_N`` less both, clipped at zero): the latter enters consecutive
    increments with the same sign (:mod:`closed_loop.smoother`, curr views).
    """
    parts = []
    for (frame, R_NH, used, share), carry in ((curr, np.eye(3)), (prev, dR_N)):
        C_used = frame.rotation_covariance_H(used)
        V = C_used if share is None else frame.subset_excess_covariance_H(used, share)
        A = carry @ R_NH
        parts.append((A @ C_used @ A.T, A @ V @ A.T))
    fit_excess = cov_N - parts[0][0] - parts[1][0]
    m, U = np.linalg.eigh(0.5 * (fit_excess + fit_excess.T))
    return parts[0][1] + parts[1][1], (U * np.maximum(m, 0.0)) @ U.T


def _gaps(t_s: np.ndarray, n_links: np.ndarray, closure: np.ndarray, min_s: float) -> list[dict]:
    """Runs of epochs without an accepted registration lasting more than ``min_s``, and how each closed.

    A gap closes at the first later epoch registered to a keyframe (``"descriptors"`` or
    ``"geometry"``, at ``closed_at_s``); without one it is ``"not re-acquired"`` (the estimate
    after it is tied to the past by the dynamics alone).
    """
    gaps: list[dict] = []
    k, T = 1, len(t_s)
    while k < T:
        if n_links[k] > 0:
            k += 1
            continue
        a = k
        while k < T and n_links[k] == 0:
            k += 1
        if t_s[k - 1] - t_s[a - 1] <= min_s:
            continue
        c = next((i for i in range(k, T) if closure[i]), None)
        gaps.append({"start_s": float(t_s[a]), "end_s": float(t_s[k - 1]),
                     "closed_by": str(closure[c]) if c is not None else "not re-acquired",
                     "closed_at_s": float(t_s[c]) if c is not None else float("nan")})
    return gaps


class _Records:
    """Per-epoch histories of a :class:`SmoothingLoop` run."""

    def __init__(self, T: int, S: int):
        self.q = np.full((T, 4), np.nan)
        self.w = np.full((T, 3), np.nan)
        self.cov_a = np.full((T, 3, 3), np.nan)
        self.cov_w = np.full((T, 3, 3), np.nan)
        self.active = np.zeros((T, S), bool)
        self.n_tracks = np.zeros(T)
        self.n_points = np.zeros(T)
        self.n_matches = np.zeros(T)
        self.inc_err = np.full(T, np.nan)
        self.inc_sigma = np.full(T, np.nan)
        self.ok = np.zeros(T, bool)
        self.reason = np.empty(T, dtype=object)
        self.n_links = np.zeros(T, int)
        self.n_rejected = np.zeros(T, int)
        self.closure = np.full(T, "", dtype=object)
        self.gaps: list[dict] = []
        self.share: dict[int, np.ndarray] = {}

    def result(self, snap: Snapshot | None, inertia, n_keyframes: int) -> ClosedLoopResult:
        sig_a = np.sqrt(np.clip(np.diagonal(self.cov_a, axis1=1, axis2=2), 0.0, None))
        sig_w = np.sqrt(np.clip(np.diagonal(self.cov_w, axis1=1, axis2=2), 0.0, None))
        return ClosedLoopResult(
            q_NT_est=self.q, omega_TN_T_est_rad_s=self.w, attitude_sigma_T_rad=sig_a, omega_sigma_T_rad_s=sig_w,
            active=self.active, n_tracks=self.n_tracks, n_points=self.n_points, n_matches=self.n_matches,
            increment_error_deg=self.inc_err, increment_sigma_deg=self.inc_sigma, ok=self.ok,
            failure_reason=self.reason, snapshot=snap, attitude_cov_T_rad2=self.cov_a,
            omega_cov_T_rad2_s2=self.cov_w, n_links=self.n_links, n_rejected=self.n_rejected,
            closure=self.closure, gaps=tuple(self.gaps), inertia=inertia, n_keyframes=n_keyframes)
