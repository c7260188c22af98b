"""Multi-target recognition and tracking with cylindrical-imaging cameras (paper 004 §3.2).

A constant-velocity Kalman filter per target (``filterpy``); its prediction is back-projected
through the extrinsics and the inverse RBF; each CCD associates spots to targets by nearest
neighbour; initial identities come from lighting the targets in turn (flag P004-10,
docs/papers.md#p004-10).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import predict as kf_predict
from filterpy.kalman import update as kf_update
from numpy.typing import ArrayLike

from chaser.cylindrical.intersection import CalibratedCamera, intersect_planes, measure_points
from vision.cylindrical import LineSpots

__all__ = [
    "TrackerSettings",
    "TrackState",
    "FrameTrack",
    "initialise_tracks",
    "track_predict",
    "track_frame",
]


@dataclass(frozen=True)
class TrackerSettings:
    """Settings of the multi-target recognition of 004 §3.2.

    004 gives no values; the defaults follow flag P004-10 (docs/papers.md#p004-10).

    Attributes
    ----------
    accel_psd_m2_s3 : float
        White-acceleration spectral density of the constant-velocity model (m²/s³).
    angle_sigma_rad : float
        Angle noise per channel (rad), for the measurement covariance of the triangulated points.
    gate_sigma : float
        Association gate in standard deviations of the predicted pixel coordinate.
    min_gate_px : float
        Smallest gate (px).
    overlap_px : float
        Two predicted spots closer than this on a CCD are treated as overlapped: that channel is
        dropped for both targets (004 §3.2 step 8).
    max_fwhm_px : float or None
        A detected spot wider than this is a merge of several spots and is not used.
    init_velocity_sigma_m_s : float
        Prior standard deviation of the velocity of a new track.
    """

    accel_psd_m2_s3: float = 1.0e-4
    angle_sigma_rad: float = 2.0e-6
    gate_sigma: float = 3.0
    min_gate_px: float = 3.0
    overlap_px: float = 15.0
    max_fwhm_px: float | None = 9.0
    init_velocity_sigma_m_s: float = 1.0

    def __post_init__(self) -> None:
        for name in ("accel_psd_m2_s3", "angle_sigma_rad", "gate_sigma", "min_gate_px",
                     "init_velocity_sigma_m_s"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name}: must be positive, got {v!r}")
        if self.overlap_px < 0:
            raise ValueError(f"overlap_px: must be >= 0, got {self.overlap_px!r}")


@dataclass(frozen=True, eq=False)
class TrackState:
    """Constant-velocity Kalman states of K targets, each at its own time.

    Attributes
    ----------
    t_s : (K,) ndarray
        Time of each state (s).
    x : (K, 6) ndarray
        ``[X, Y, Z, Ẋ, Ẏ, Ż]`` in the world frame (m, m/s).
    P : (K, 6, 6) ndarray
        Covariances.
    initialised : (K,) bool ndarray
    """

    t_s: np.ndarray
    x: np.ndarray
    P: np.ndarray
    initialised: np.ndarray

    @classmethod
    def empty(cls, n_targets: int) -> TrackState:
        """States of ``n_targets`` targets, none initialised (NaN states)."""
        if int(n_targets) != n_targets or n_targets < 1:
            raise ValueError(f"n_targets: must be a positive integer, got {n_targets!r}")
        K = int(n_targets)
        return cls(np.zeros(K), np.full((K, 6), np.nan), np.full((K, 6, 6), np.nan), np.zeros(K, bool))

    @property
    def position_W(self) -> np.ndarray:
        """Positions ``(K, 3)`` in the world frame (m)."""
        return self.x[:, :3]


@dataclass(frozen=True, eq=False)
class FrameTrack:
    """Result of one frame of :func:`track_frame`.

    Attributes
    ----------
    state : TrackState
        Filter states after the update (time ``t_s`` for every target).
    X_W : (K, 3) ndarray
        Triangulated target positions of this frame (m); NaN where a target had fewer than three
        independent planes (its state then only coasts).
    ok : (K,) bool ndarray
        The target was measured in this frame (triangulated and used to update its filter).
    failure_reason : (K,) ndarray of str
        "" where ``ok``; otherwise why the target was not measured (from :func:`intersect_planes`).
    n_planes : (K,) int ndarray
    spot_index : (K, C, 2) int ndarray
        Index of the associated spot in the detection list of each CCD, −1 when dropped.
    uv_pred_px : (K, C, 2) ndarray
        Back-projected predictions (px).
    overlapped : (K, C, 2) bool ndarray
        Channel dropped because spots overlapped (predicted closer than ``overlap_px``, one spot
        claimed by two targets, or a merged spot).
    """

    state: TrackState
    X_W: np.ndarray
    ok: np.ndarray
    failure_reason: np.ndarray
    n_planes: np.ndarray
    spot_index: np.ndarray
    uv_pred_px: np.ndarray
    overlapped: np.ndarray


_H = np.hstack([np.eye(3), np.zeros((3, 3))])


def _transition(dt: float, q: float) -> tuple[np.ndarray, np.ndarray]:
    F = np.eye(6)
    F[:3, 3:] = dt * np.eye(3)
    Q = Q_discrete_white_noise(dim=2, dt=max(dt, 0.0), var=q, block_size=3, order_by_dim=False)
    return F, Q


def track_predict(state: TrackState, t_s: float, *, settings: TrackerSettings = TrackerSettings()) -> TrackState:
    """Constant-velocity prediction of every initialised target to time ``t_s`` (``filterpy.kalman.predict``).

    Returns a new state; targets not yet initialised are left as they are.
    """
    x = state.x.copy()
    P = state.P.copy()
    t = state.t_s.copy()
    for k in np.flatnonzero(state.initialised):
        dt = float(t_s - state.t_s[k])
        if dt < 0:
            raise ValueError(f"t_s: {t_s!r} is before the state time {state.t_s[k]!r} of target {k}")
        if dt > 0:
            F, Q = _transition(dt, settings.accel_psd_m2_s3)
            x[k], P[k] = kf_predict(x[k], P[k], F, Q)
        t[k] = t_s
    return TrackState(t, x, P, state.initialised.copy())


def _update(state: TrackState, k: int, X: np.ndarray, cov: np.ndarray, t_s: float,
            settings: TrackerSettings) -> TrackState:
    x = state.x.copy()
    P = state.P.copy()
    t = state.t_s.copy()
    init = state.initialised.copy()
    if not init[k]:
        x[k] = np.concatenate([X, np.zeros(3)])
        P[k] = np.zeros((6, 6))
        P[k][:3, :3] = cov
        P[k][3:, 3:] = np.eye(3) * settings.init_velocity_sigma_m_s**2
        init[k] = True
    else:
        x[k], P[k] = kf_update(x[k], P[k], X, cov, _H)
    t[k] = t_s
    return TrackState(t, x, P, init)


def _positions(spots: LineSpots | ArrayLike) -> tuple[np.ndarray, np.ndarray | None]:
    """Spot centres (px) of one CCD and their widths (None when only centres were given)."""
    if isinstance(spots, LineSpots):
        return np.asarray(spots.position_px, dtype=float), np.asarray(spots.fwhm_px, dtype=float)
    arr = np.asarray(spots, dtype=float).reshape(-1)
    return arr, None


def initialise_tracks(
    cameras: Sequence[CalibratedCamera],
    n_targets: int,
    lit_frames: Sequence[tuple[int, float, Sequence]],
    *,
    settings: TrackerSettings = TrackerSettings(),
) -> TrackState:
    """Initial identification by sequential lighting (004 §3.2 step 3).

    Parameters
    ----------
    cameras : sequence of CalibratedCamera
    n_targets : int
    lit_frames : sequence of ``(target_index, t_s, detections)``
        Frames in which only ``target_index`` is lit; ``detections`` is, per camera, a pair of spot
        lists (``LineSpots`` or arrays of centres, px) for CCD1 and CCD2.  The brightest/only spot of
        each CCD is that target's.  Repeating the sequence gives the tracks a velocity.

    Returns
    -------
    TrackState
        Raises ``ValueError`` if a target never got a 3-D fix.
    """
    state = TrackState.empty(n_targets)
    for target, t_s, det in lit_frames:
        if not 0 <= int(target) < n_targets:
            raise ValueError(f"lit_frames: target index {target!r} outside [0, {n_targets})")
        uv = np.full((len(cameras), 2), np.nan)
        for c, pair in enumerate(det):
            for k in range(2):
                pos, _ = _positions(pair[k])
                if isinstance(pair[k], LineSpots) and len(pos) > 1:
                    pos = pos[[int(np.argmax(pair[k].peak_dn))]]
                if pos.size == 1:
                    uv[c, k] = pos[0]
        fix = measure_points(cameras, uv[None], angle_sigma_rad=settings.angle_sigma_rad)
        if not fix.ok[0]:
            continue
        state = track_predict(state, t_s, settings=settings) if state.initialised[target] else state
        state = _update(state, int(target), fix.X_W[0], fix.covariance_m2[0], t_s, settings)
    if not np.all(state.initialised):
        missing = np.flatnonzero(~state.initialised).tolist()
        raise ValueError(f"lit_frames: targets {missing} were never located during sequential lighting")
    return state


def _pixel_jacobian(cam: CalibratedCamera, X: np.ndarray, h: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """Back-projected pixels ``(K, 2)`` and their Jacobian ``(K, 2, 3)`` (finite differences)."""
    pts = np.concatenate([X[:, None, :], X[:, None, :] + h * np.eye(3)[None]], axis=1)  # (K, 4, 3)
    uv = cam.pixels_from_world(pts)
    J = (uv[:, 1:, :] - uv[:, :1, :]) / h  # (K, 3, 2)
    return uv[:, 0, :], np.swapaxes(J, -1, -2)


def track_frame(
    cameras: Sequence[CalibratedCamera],
    state: TrackState,
    detections: Sequence[Sequence],
    t_s: float,
    *,
    settings: TrackerSettings = TrackerSettings(),
) -> FrameTrack:
    """One frame of multi-target recognition and measurement (004 §3.2 steps 5–9).

    1. Predict every target to ``t_s`` (constant-velocity KF).
    2. Back-project the predictions into every camera: eq (15), eq (1)–(2), inverse RBF.
    3. On each CCD separately (the measurement is 1-D, flag P004-10c) associate each target with
       the nearest detected spot inside its gate (``gate_sigma`` × the predicted pixel standard
       deviation from ``P``, at least ``min_gate_px``).  The channel is dropped for targets whose
       predictions lie closer than ``overlap_px``, that claim the same spot, or whose spot is wider
       than ``max_fwhm_px`` (overlap, step 8).
    4. Map each camera's ``(u, v)`` to ``(α, β)`` with the RBF (a dropped coordinate is replaced by its
       prediction, and the angle of the dropped channel is not used), intersect the planes, and
       update the filter of each target with at least three independent planes.

    Parameters
    ----------
    cameras : sequence of CalibratedCamera
    state : TrackState
        All targets initialised.
    detections : per camera, (spots of CCD1, spots of CCD2)
        ``LineSpots`` or arrays of spot centres (px).
    t_s : float
        Frame time (s).
    """
    if not np.all(state.initialised):
        raise ValueError("state: every target must be initialised (see initialise_tracks)")
    C = len(cameras)
    if len(detections) != C:
        raise ValueError(f"detections: expected one entry per camera ({C}), got {len(detections)}")
    pred = track_predict(state, t_s, settings=settings)
    K = pred.x.shape[0]
    Xp = pred.x[:, :3]
    Pp = pred.P[:, :3, :3]
    uv_pred = np.full((K, C, 2), np.nan)
    gate = np.full((K, C, 2), settings.min_gate_px)
    for c, cam in enumerate(cameras):
        uvc, J = _pixel_jacobian(cam, Xp)
        uv_pred[:, c, :] = uvc
        var = np.einsum("kai,kij,kaj->ka", J, Pp, J)
        gate[:, c, :] = np.maximum(settings.gate_sigma * np.sqrt(np.maximum(var, 0.0)), settings.min_gate_px)
    spot_index = np.full((K, C, 2), -1, dtype=int)
    overlapped = np.zeros((K, C, 2), dtype=bool)
    uv_meas = np.full((K, C, 2), np.nan)
    for c in range(C):
        for ch in range(2):
            pos, fwhm = _positions(detections[c][ch])
            p = uv_pred[:, c, ch]
            finite = np.isfinite(p)
            dp = np.abs(p[:, None] - p[None, :])
            np.fill_diagonal(dp, np.inf)
            close = np.any(np.where(finite[:, None] & finite[None, :], dp < settings.overlap_px, False), axis=1)
            claim = np.full(K, -1)
            if pos.size:
                dist = np.abs(p[:, None] - pos[None, :])
                j = np.argmin(np.where(np.isfinite(dist), dist, np.inf), axis=1)
                dj = dist[np.arange(K), j]
                claim = np.where(finite & (dj <= gate[:, c, ch]), j, -1)
            counts = np.bincount(claim[claim >= 0], minlength=max(pos.size, 1))
            shared = (claim >= 0) & (counts[np.maximum(claim, 0)] > 1)
            wide = np.zeros(K, bool)
            if fwhm is not None and settings.max_fwhm_px is not None and pos.size:
                wide = (claim >= 0) & (fwhm[np.maximum(claim, 0)] > settings.max_fwhm_px)
            drop = close | shared | wide
            overlapped[:, c, ch] = drop
            use = (claim >= 0) & ~drop
            spot_index[:, c, ch] = np.where(use, claim, -1)
            uv_meas[use, c, ch] = pos[claim[use]]
    # angles per camera: the RBF needs both coordinates; a dropped one is replaced by its prediction
    ab = np.full((K, C, 2), np.nan)
    for c, cam in enumerate(cameras):
        have = np.isfinite(uv_meas[:, c, :])
        filled = np.where(have, uv_meas[:, c, :], uv_pred[:, c, :])
        a = cam.angles_from_pixels(filled)
        ab[:, c, :] = np.where(have, a, np.nan)
    R = np.stack([cam.R_CW for cam in cameras])
    t = np.stack([cam.t_CW for cam in cameras])
    fix = intersect_planes(R, t, ab, angle_sigma_rad=settings.angle_sigma_rad)
    new = pred
    for k in np.flatnonzero(fix.ok):
        new = _update(new, int(k), fix.X_W[k], fix.covariance_m2[k], t_s, settings)
    return FrameTrack(new, fix.X_W, fix.ok.copy(), fix.failure_reason, fix.n_planes, spot_index, uv_pred,
                      overlapped)
