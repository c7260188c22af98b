"""The closed loop of 003: observe → triangulate → register → filter, epoch after epoch.

:class:`ClosedLoop` is built from parts (an :class:`~closed_loop.observers.Observer`, a
:class:`~closed_loop.registrars.Registrar` and a :class:`filters.AttitudeFilter`) and run on plain
arrays: the true attitude of the target in H, the Hill frame, the observers' positions and which of
them are active, the Sun direction and the illumination per epoch, and the filter's initial state.
Each epoch the active observers' cameras point at the target (:func:`formation.quality.camera_poses_at_target`),
the epoch is observed and triangulated, registered against the previous epoch when the observer set
is unchanged, and the increment (with its covariance) updates the filter by stochastic cloning
(:meth:`filters.AttitudeEKF.update_increment`).  An epoch without a usable increment (shadow, too
few observers, changed observer set, failed registration) only propagates the filter, and the
reason is recorded.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from attitude.quaternion import matrix_from_quat, quat_angle_between, quat_from_matrix
from closed_loop.frames import Frame, reconstruct
from closed_loop.observers import Observer
from closed_loop.registrars import Registrar
from filters import AttitudeFilter, FilterState
from formation.quality import camera_poses_at_target

__all__ = ["ClosedLoop", "ClosedLoopResult", "Snapshot", "observer_tracks", "observe_epoch"]

INITIAL_EPOCH = "initial epoch"
SET_CHANGED = "observer set changed"
NO_COVARIANCE = "increment covariance unavailable"
NO_PREVIOUS = "previous epoch not observed"


def observer_tracks(T: int, r_H: np.ndarray, active: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """The observers' positions ``(S, T, 3)`` (station-kept ``(S, 3)`` broadcast) and the active mask
    ``(T, S)`` (default: all), checked against each other."""
    r_H = np.asarray(r_H, dtype=float)
    if r_H.ndim == 2:
        r_H = np.broadcast_to(r_H[:, None, :], (r_H.shape[0], T, 3))
    S = r_H.shape[0]
    active = np.ones((T, S), bool) if active is None else np.asarray(active, dtype=bool)
    if active.shape != (T, S) or r_H.shape != (S, T, 3):
        raise ValueError(f"active: expected shape ({T}, {S}) and r_H ({S}, {T}, 3), got {active.shape} "
                         f"and {r_H.shape}")
    return r_H, active


def observe_epoch(observer: Observer, r_CT_H: np.ndarray, q_HT: np.ndarray, sun_H: np.ndarray,
                  illumination: float, rng: np.random.Generator) -> tuple[Frame, np.ndarray]:
    """One epoch seen by the active observers at ``r_CT_H (n, 3)``, pointed at the target, and
    triangulated: ``(frame, T_CW)``."""
    T_CW = camera_poses_at_target(r_CT_H)
    obs = observer.observe(T_CW, q_HT, sun_H, rng=rng, sun_visible_fraction=illumination)
    return reconstruct(obs), T_CW


@dataclass(frozen=True)
class Snapshot:
    """One observed epoch kept for figures.

    Attributes
    ----------
    epoch : int
        Index of the epoch.
    T_CW : ndarray (n, 4, 4)
        The active cameras' poses, H → C.
    frame : closed_loop.frames.Frame
        Its observation and triangulated cloud.
    observers : ndarray (n,) int
        Indices of the active observers.
    sun_H : ndarray (3,)
        Direction to the Sun in H.
    """

    epoch: int
    T_CW: np.ndarray
    frame: Frame
    observers: np.ndarray
    sun_H: np.ndarray


@dataclass(frozen=True)
class ClosedLoopResult:
    """Histories of one closed-loop run (T epochs, S observers).

    Attributes
    ----------
    q_NT_est : ndarray (T, 4)
        Estimated attitude after each epoch's update, scalar-first.
    omega_TN_T_est_rad_s : ndarray (T, 3)
        Estimated body rate, rad/s.
    attitude_sigma_T_rad : ndarray (T, 3)
        The filter's 1σ of its attitude error per body axis after each epoch's update, rad: square
        roots of the diagonal of the attitude block of ``estimator.tangent_covariance`` (NaN when
        the filter failed).
    omega_sigma_T_rad_s : ndarray (T, 3)
        The filter's 1σ of its body-rate error per body axis, rad/s (the rate block, likewise).
    active : ndarray (T, S) bool
        Observers used at each epoch.
    n_tracks, n_points, n_matches : ndarray (T,)
        Multi-view tracks, triangulated points and associated pairs per epoch.
    increment_error_deg : ndarray (T,)
        Angle between the registered and the true increment (NaN where none was used).
    increment_sigma_deg : ndarray (T,)
        ``sqrt(trace(cov))`` of the increment given to the filter (NaN where none).
    ok : ndarray (T,) bool
        An increment updated the filter at the epoch.
    failure_reason : ndarray (T,) object
        ``""`` where ok, else why not (``"initial epoch"`` at the first).
    snapshot : Snapshot or None
        The first observed epoch at or after the requested one.
    attitude_cov_T_rad2, omega_cov_T_rad2_s2 : ndarray (T, 3, 3) or None
        The estimator's covariance of its body-frame attitude error and of its rate error (the
        filter's tangent blocks; the smoother's marginals).
    n_links : ndarray (T,) or None
        Relative rotations accepted at each epoch (smoother: previous epoch, keyframes, closures).
    n_rejected : ndarray (T,) or None
        Registrations refused at each epoch (evidence or the innovation gate).
    closure : ndarray (T,) object or None
        How the epoch was tied to a keyframe older than the previous epoch: ``"descriptors"``,
        ``"geometry"`` or ``""``.
    gaps : tuple of dict
        Each run of epochs without an accepted registration (smoother): ``start_s``, ``end_s``,
        ``closed_by`` (``"descriptors"``, ``"geometry"``, ``"not re-acquired"``), ``closed_at_s``.
    inertia : closed_loop.torque_free_factor.InertiaShape or None
        The smoother's estimate of the inertia shape at the end.
    n_keyframes : int
        Keyframes in the target model at the end.
    """

    q_NT_est: np.ndarray
    omega_TN_T_est_rad_s: np.ndarray
    attitude_sigma_T_rad: np.ndarray
    omega_sigma_T_rad_s: np.ndarray
    active: np.ndarray
    n_tracks: np.ndarray
    n_points: np.ndarray
    n_matches: np.ndarray
    increment_error_deg: np.ndarray
    increment_sigma_deg: np.ndarray
    ok: np.ndarray
    failure_reason: np.ndarray
    snapshot: Snapshot | None = None
    attitude_cov_T_rad2: np.ndarray | None = None
    omega_cov_T_rad2_s2: np.ndarray | None = None
    n_links: np.ndarray | None = None
    n_rejected: np.ndarray | None = None
    closure: np.ndarray | None = None
    gaps: tuple[dict, ...] = ()
    inertia: object | None = None
    n_keyframes: int = 0


@dataclass(frozen=True)
class ClosedLoop:
    """The 003 estimation loop, composed of swappable parts.

    Attributes
    ----------
    observer : closed_loop.observers.Observer
        How the active cameras see the target.
    registrar : closed_loop.registrars.Registrar
        How consecutive epochs are registered.
    estimator : filters.AttitudeFilter
        The filter (:class:`filters.AttitudeEKF` or :class:`filters.MEKF`) with the target's inertia.
    min_observers : int
        Fewest active observers with which an epoch is observed.

    Examples
    --------
    >>> loop = ClosedLoop(observer=GeometricObserver(camera, target), registrar=MLRegistrar(),
    ...                   estimator=AttitudeEKF(J_kg_m2=J))            # doctest: +SKIP
    >>> result = loop.run(truth.t_s, truth.q_HT, truth.R_NH, truth.sun_H, truth.illumination, r_H, state0,
    ...                   rng_observe=rng1, rng_register=rng2)        # doctest: +SKIP
    """

    observer: Observer
    registrar: Registrar
    estimator: AttitudeFilter
    min_observers: int = 2

    def run(self, t_s: np.ndarray, q_HT: np.ndarray, R_NH: np.ndarray, sun_H: np.ndarray, illumination: np.ndarray,
            r_H: np.ndarray, initial_state: FilterState, *, rng_observe: np.random.Generator,
            rng_register: np.random.Generator, active: np.ndarray | None = None,
            inactive_reason: Sequence[str] | None = None, snapshot_from: int | None = None,
            progress: Callable[[int, int], None] | None = None) -> ClosedLoopResult:
        """Run the loop over ``T`` epochs.

        Parameters
        ----------
        t_s : ndarray (T,)
            Epochs, s.
        q_HT : ndarray (T, 4)
            True attitude of the target in H (what the cameras see), scalar-first.
        R_NH : ndarray (T, 3, 3)
            Hill frame in N at each epoch (``v_N = R_NH v_H``).
        sun_H : ndarray (T, 3)
            Direction to the Sun in H.
        illumination : ndarray (T,)
            Visible fraction of the Sun from the target (0 in Earth's shadow).
        r_H : ndarray (S, T, 3) or (S, 3)
            Observers' positions relative to the target, H, m (``(S, 3)``: station-kept).
        initial_state : filters.FilterState
            The filter's state at ``t_s[0]`` (a batch of one; cloned here).
        rng_observe : numpy.random.Generator
            Observation stream; ``rng_observe.spawn(T)`` gives one generator per epoch.
        rng_register : numpy.random.Generator
            Registration stream, used in epoch order.
        active : ndarray (T, S) bool, optional
            Observers in use at each epoch (default: all of them at every epoch).
        inactive_reason : sequence of str (T,), optional
            Why no observer set is available at an epoch (``""`` where one is).
        snapshot_from : int, optional
            Keep the first successfully observed epoch at or after this index.
        progress : callable ``(done, total)``, optional

        Returns
        -------
        ClosedLoopResult
        """
        T = len(t_s)
        r_H, active = observer_tracks(T, r_H, active)
        S = r_H.shape[0]
        obs_rngs = rng_observe.spawn(T)
        filt = self.estimator
        state = filt.clone(initial_state)
        q_est = np.full((T, 4), np.nan)
        w_est = np.full((T, 3), np.nan)
        cov = np.full((T, 6, 6), np.nan)
        used = np.zeros((T, S), bool)
        n_tracks = np.zeros(T)
        n_points = np.zeros(T)
        n_matches = np.zeros(T)
        inc_err = np.full(T, np.nan)
        inc_sigma = np.full(T, np.nan)
        ok = np.zeros(T, bool)
        reason = np.empty(T, dtype=object)
        prev: Frame | None = None
        prev_active: np.ndarray | None = None
        snap: Snapshot | None = None
        if progress:
            progress(0, T)
        for k in range(T):
            if k > 0:
                state = filt.predict(state, t_s[k] - t_s[k - 1])
            act = active[k]
            why = "" if inactive_reason is None else str(inactive_reason[k])
            used[k] = act
            frame = None
            if act.sum() >= self.min_observers:
                frame, T_CW = observe_epoch(self.observer, r_H[act, k], q_HT[k], sun_H[k], float(illumination[k]),
                                            obs_rngs[k])
                n_tracks[k] = frame.obs.n_tracks
                n_points[k] = int(np.sum(frame.tri.n_valid))
                if snapshot_from is not None and k >= snapshot_from and snap is None and frame.ok:
                    snap = Snapshot(k, T_CW, frame, np.flatnonzero(act), sun_H[k])
                why = why or frame.failure_reason
            z = None
            if k > 0 and frame is not None and prev is not None and np.array_equal(act, prev_active):
                inc = self.registrar.register(prev, frame, rng=rng_register)
                n_matches[k] = inc.n_matches
                z = inc.measurement(R_NH[k - 1], R_NH[k])
                if z is not None:
                    true = matrix_from_quat(q_HT[k]) @ matrix_from_quat(q_HT[k - 1]).T
                    inc_err[k] = np.degrees(quat_angle_between(quat_from_matrix(inc.R_H), quat_from_matrix(true)))
                    inc_sigma[k] = np.degrees(np.sqrt(np.trace(inc.cov_rotvec_H)))
                else:
                    why = why or inc.failure_reason or NO_COVARIANCE
            elif k > 0 and frame is not None:
                why = why or (SET_CHANGED if prev is not None else NO_PREVIOUS)
            if k > 0:
                state = filt.update_increment(state, z)
            ok[k] = z is not None
            reason[k] = INITIAL_EPOCH if k == 0 else ("" if ok[k] else why)
            q_est[k] = state.q_NT[0]
            w_est[k] = state.omega_TN_T[0]
            cov[k] = filt.tangent_covariance(state)[0][:6, :6]
            prev, prev_active = frame, act
            if progress:
                progress(k + 1, T)
        sigma = np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None))
        return ClosedLoopResult(q_NT_est=q_est, omega_TN_T_est_rad_s=w_est, attitude_sigma_T_rad=sigma[:, :3],
                                omega_sigma_T_rad_s=sigma[:, 3:], active=used, n_tracks=n_tracks,
                                n_points=n_points, n_matches=n_matches, increment_error_deg=inc_err,
                                increment_sigma_deg=inc_sigma, ok=ok, failure_reason=reason, snapshot=snap,
                                attitude_cov_T_rad2=cov[:, :3, :3], omega_cov_T_rad2_s2=cov[:, 3:, 3:],
                                n_links=ok.astype(int))
