"""The target model: keyframes of the target's triangulated surface, in its own body frame.

The first frame defines the body frame T (flag P003-14a, docs/papers.md#p003-14a).  Each keyframe
keeps an epoch's :class:`closed_loop.frames.Frame` (points with descriptors and covariances in H at
that epoch) and where the observers were; with the smoother's attitude estimate of that epoch its
points are the model in T (:meth:`TargetModel.points_T`).  A new epoch is registered to the
keyframes it sees the same faces of (:meth:`TargetModel.candidates`), which ties the estimate to
epochs long past instead of only to the previous one (loop closure).

Keyframes are chosen by information, not age: an epoch becomes one when no keyframe explains
most of its points (its best keyframe registration kept fewer than ``new_keyframe_overlap`` of
its triangulated points) or when no keyframe was within reach of its viewpoint.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from closed_loop.frames import Frame

__all__ = ["Keyframe", "ModelSettings", "TargetModel", "viewing_direction_T"]


@dataclass(frozen=True)
class ModelSettings:
    """How the target model is built and used.

    Attributes
    ----------
    viewpoint_window_deg : float
        Largest change of viewpoint (on the target, between the observers' mean directions) over
        which descriptors are trusted to associate (rendered SIFT: ≈ 30°); beyond it a keyframe
        is registered by geometry only.
    max_links : int
        Keyframe registrations tried per epoch (the oldest and the nearest in viewpoint).
    new_keyframe_overlap : float
        An epoch whose best keyframe registration kept fewer than this fraction of its points
        becomes a keyframe.
    reacquire_after_s : float
        After this long without an accepted registration the target is re-acquired: every
        keyframe is tried, by descriptors within the window and by geometry beyond it.
    relink_after_s : float
        A keyframe closes the loop at most once in this time: closures to one keyframe share its
        points' noise, which the graph would otherwise count again at every closure.
    refresh_epochs : int
        The keyframes' viewing directions on the target are recomputed from the smoother's
        estimate every this many epochs.
    reacquire_tries : int
        Keyframes tried per epoch while re-acquiring (the nearest in predicted viewpoint).
    closure_inflation : float
        Factor on a closure's own covariance (beyond the two frames' shares) in the smoother.
    """

    viewpoint_window_deg: float = 30.0
    max_links: int = 2
    new_keyframe_overlap: float = 0.5
    reacquire_after_s: float = 5.0
    relink_after_s: float = 10.0
    refresh_epochs: int = 10
    reacquire_tries: int = 4
    closure_inflation: float = 1.0


@dataclass(frozen=True)
class Keyframe:
    """One epoch kept in the model.

    Attributes
    ----------
    epoch : int
    frame : closed_loop.frames.Frame
    R_NH : ndarray (3, 3)
        Hill frame at the epoch.
    dir_H : ndarray (3,)
        Mean unit direction from the target to the active observers, H.
    """

    epoch: int
    frame: Frame
    R_NH: np.ndarray
    dir_H: np.ndarray


def viewing_direction_T(dir_H: np.ndarray, R_NH: np.ndarray, R_NT: np.ndarray) -> np.ndarray:
    """The observers' mean direction ``dir_H`` expressed on the target: ``R_NTᵀ R_NH dir_H``."""
    return R_NT.T @ (R_NH @ dir_H)


@dataclass
class TargetModel:
    """Keyframes of the target (module docstring)."""

    settings: ModelSettings = field(default_factory=ModelSettings)
    keyframes: list[Keyframe] = field(default_factory=list)
    last_linked_s: dict[int, float] = field(default_factory=dict)
    _dir_T: dict[int, np.ndarray] = field(default_factory=dict, repr=False)
    _refreshed_at: int = -(10**9)

    def linked(self, epoch: int, t_s: float) -> None:
        """Record that the keyframe of ``epoch`` closed the loop at ``t_s``."""
        self.last_linked_s[epoch] = float(t_s)

    def resting(self, epoch: int, t_s: float) -> bool:
        """The keyframe of ``epoch`` closed the loop less than ``relink_after_s`` ago."""
        last = self.last_linked_s.get(epoch)
        return last is not None and t_s - last < self.settings.relink_after_s

    def add(self, epoch: int, frame: Frame, R_NH: np.ndarray, r_CT_H: np.ndarray) -> Keyframe:
        """Keep ``frame`` as a keyframe; ``r_CT_H (n, 3)`` are the active observers' positions."""
        u = r_CT_H / np.linalg.norm(r_CT_H, axis=-1, keepdims=True)
        d = u.sum(axis=0)
        kf = Keyframe(epoch=epoch, frame=frame, R_NH=np.asarray(R_NH, float), dir_H=d / np.linalg.norm(d))
        self.keyframes.append(kf)
        return kf

    def candidates(self, epoch: int, R_NH: np.ndarray, r_CT_H: np.ndarray, R_NT_now: np.ndarray,
                   R_NT_of: Callable[[int], np.ndarray], *, t_s: float, everything: bool = False,
                   exclude: tuple[int, ...] = ()) -> list[tuple[Keyframe, float]]:
        """Keyframes to register the epoch to, with their change of viewpoint (deg).

        Parameters
        ----------
        epoch : int
        R_NH : ndarray (3, 3)
        r_CT_H : ndarray (n, 3)
            Active observers' positions.
        R_NT_now : ndarray (3, 3)
            Predicted attitude at the epoch.
        R_NT_of : callable
            The current attitude estimate of a keyframe's epoch.
        t_s : float
            Time of the epoch (keyframes that closed the loop within ``relink_after_s`` rest).
        everything : bool
            Re-acquisition: the ``reacquire_tries`` keyframes nearest in viewpoint, whatever the window.
        exclude : tuple of int
            Epochs not to return (the previous epoch, registered anyway).

        Returns
        -------
        list of (Keyframe, float)
            Without ``everything``: at most ``max_links`` within the viewpoint window, the oldest
            first, then the nearest.
        """
        u = r_CT_H / np.linalg.norm(r_CT_H, axis=-1, keepdims=True)
        d = u.sum(axis=0)
        now_T = viewing_direction_T(d / np.linalg.norm(d), R_NH, R_NT_now)
        kfs = [kf for kf in self.keyframes
               if kf.epoch != epoch and kf.epoch not in exclude and not self.resting(kf.epoch, t_s)]
        if not kfs:
            return []
        # the keyframes' directions on the target, with their attitude estimates refreshed every
        # ``refresh_epochs`` (the window is tens of degrees; the estimates move by hundredths)
        if epoch - self._refreshed_at >= self.settings.refresh_epochs:
            self._dir_T.clear()
            self._refreshed_at = epoch
        dirs = np.stack([self._keyframe_dir_T(kf, R_NT_of) for kf in kfs])
        ang = np.degrees(np.arctan2(np.linalg.norm(np.cross(dirs, now_T), axis=-1), dirs @ now_T))
        scored = list(zip(kfs, ang.tolist(), strict=True))
        if everything:
            return sorted(scored, key=lambda s: s[1])[: self.settings.reacquire_tries]
        near = [s for s in scored if s[1] <= self.settings.viewpoint_window_deg]
        if not near:
            return []
        picks = [near[0]]  # the oldest (keyframes are kept in epoch order)
        nearest = min(near, key=lambda s: s[1])
        if nearest[0].epoch != picks[0][0].epoch:
            picks.append(nearest)
        return picks[: self.settings.max_links]

    def _keyframe_dir_T(self, kf: Keyframe, R_NT_of: Callable[[int], np.ndarray]) -> np.ndarray:
        d = self._dir_T.get(kf.epoch)
        if d is None:
            d = self._dir_T[kf.epoch] = viewing_direction_T(kf.dir_H, kf.R_NH, R_NT_of(kf.epoch))
        return d

    def wants(self, frame: Frame, best_inliers: int) -> bool:
        """Whether the frame brings new information: no keyframe kept most of its points."""
        n = int(np.sum(frame.tri.valid))
        return frame.ok and n > 0 and best_inliers < self.settings.new_keyframe_overlap * n

    def points_T(self, R_NT_of: Callable[[int], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """The model's points in the body frame and their covariances: ``(N, 3)`` m, ``(N, 3, 3)`` m².

        Each keyframe's valid points ``X_H`` are carried to T with that epoch's estimate,
        ``X_T = R_NTᵀ R_NH X_H`` (the target's centre is the origin of H).
        """
        X, C = [], []
        for kf in self.keyframes:
            v = np.asarray(kf.frame.tri.valid, bool)
            R_TH = R_NT_of(kf.epoch).T @ kf.R_NH
            X.append(kf.frame.tri.X_W[v] @ R_TH.T)
            C.append(R_TH @ kf.frame.tri.cov_W[v] @ R_TH.T)
        if not X:
            return np.zeros((0, 3)), np.zeros((0, 3, 3))
        return np.concatenate(X), np.concatenate(C)
