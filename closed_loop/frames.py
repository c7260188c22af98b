"""Frames: an epoch's observation with its triangulated cloud (003 §2.1, multi-view triangulation)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from attitude.batch import cross_product_matrices
from reconstruction.triangulation import Triangulation, triangulate, triangulate_from_observation
from vision.observation import Observation

__all__ = ["Frame", "reconstruct", "reconstruct_many"]


@dataclass(frozen=True)
class Frame:
    """An epoch's observation and its triangulated cloud.

    Attributes
    ----------
    obs : vision.observation.Observation
        Multi-view tracks of the epoch.
    tri : reconstruction.triangulation.Triangulation
        One point per track, in the frame of the cameras' poses (H), m.
    """

    obs: Observation
    tri: Triangulation

    @property
    def ok(self) -> bool:
        """The observation succeeded and at least one point was triangulated."""
        return bool(self.obs.ok and np.all(self.tri.ok))

    @property
    def failure_reason(self) -> str:
        """``""`` when :attr:`ok`, else why the observation or the triangulation failed."""
        if not self.obs.ok:
            return str(self.obs.failure_reason)
        return "" if self.ok else str(self.tri.failure_reason)

    def orientation_information_H(self, points: np.ndarray | None = None) -> np.ndarray:
        """Fisher information (6, 6) of a rigid motion ``[δθ, δt]`` of the cloud, or of its tracks ``points``.

        ``Σᵢ Jᵢᵀ Cᵢ⁻¹ Jᵢ`` with ``Jᵢ = [−[Xᵢ×], I]`` over the valid points (about the origin of H,
        m and rad), the information the frame's points hold on a motion ``Xᵢ ← Xᵢ + δθ × Xᵢ + δt``
        of the whole cloud.
        """
        info = self._point_information
        if points is None:
            return info.sum(axis=0)
        return info[np.unique(np.asarray(points, dtype=int))].sum(axis=0)

    @cached_property
    def _point_information(self) -> np.ndarray:
        """Per track ``Jᵢᵀ Cᵢ⁻¹ Jᵢ`` (M, 6, 6), zero for invalid points (computed once per frame)."""
        v = np.asarray(self.tri.valid, bool) & np.all(np.isfinite(self.tri.X_W), -1)
        out = np.zeros((v.size, 6, 6))
        S = cross_product_matrices(self.tri.X_W[v])  # [X×]
        J = np.concatenate([-S, np.broadcast_to(np.eye(3), S.shape)], axis=2)  # (N, 3, 6)
        out[v] = np.einsum("nki,nkl,nlj->nij", J, np.linalg.inv(self.tri.cov_W[v]), J)
        return out

    def rotation_covariance_H(self, points: np.ndarray | None = None) -> np.ndarray:
        """Covariance of the orientation of the triangulated cloud, or of the tracks ``points`` of it (rad², H).

        The Cramér–Rao bound of the rotation ``δθ`` of a rigid motion of the cloud estimated from its
        own points with their covariances, the translation marginalised:
        ``[I⁻¹]_θθ`` of :meth:`orientation_information_H`.  It is the part of every registration's
        error that this frame's point noise contributes and that all the frame's registrations
        share (NaN with fewer than 3 valid points).

        ``points`` (track indices) restricts it to the points registrations confirmed: a false match
        placed at a wrong depth adds rotation information about the weakly seen axes that no
        registration has (in the 300 s smoother runs the whole-cloud value was 1.6× too small in
        trace, up to 7×, and the frames' NEES 6.1 instead of 3).
        """
        info = self.orientation_information_H(points)
        if np.linalg.matrix_rank(info, tol=1e-12 * max(np.trace(info), 1e-300)) < 6:
            return np.full((3, 3), np.nan)
        return np.linalg.inv(info)[:3, :3]

    def subset_excess_covariance_H(self, used: np.ndarray, share: np.ndarray) -> np.ndarray:
        """Covariance (rad², H) of ``e(used) − e(share)``: the orientation errors of two point subsets of the cloud.

        A registration that fitted the tracks ``used`` of this frame carries the frame's noise as
        the orientation error of that subset; the graph holds the frame's error as that of
        ``share``.  With GLS estimates ``e_X = I_X⁻¹ Jᵀ W n`` their difference has covariance
        ``C_u + C_s − C_u I_∩ C_s − C_s I_∩ C_u`` (``I_∩`` the information of the common points),
        which is ``C_u − C_s`` when ``used ⊆ share`` and zero when they are equal.
        """
        I_u, I_s = self.orientation_information_H(used), self.orientation_information_H(share)
        I_c = self.orientation_information_H(np.intersect1d(used, share))
        try:
            C_u, C_s = np.linalg.inv(I_u), np.linalg.inv(I_s)
        except np.linalg.LinAlgError:
            return np.full((3, 3), np.nan)
        cross = C_u @ I_c @ C_s
        V = C_u + C_s - cross - cross.T
        return 0.5 * (V + V.T)[:3, :3]


def reconstruct(obs: Observation) -> Frame:
    """Triangulate an observation (an empty or failed observation gives a flagged frame)."""
    return Frame(obs=obs, tri=triangulate_from_observation(obs))


def reconstruct_many(observations: Sequence[Observation]) -> list[Frame]:
    """:func:`reconstruct` for several epochs of the same cameras in one batched triangulation.

    The tracks of all the epochs are stacked into one batch (no padding: epochs, or trials, with
    very different track counts cost their tracks only), solved in one call of
    :func:`reconstruction.triangulation.triangulate`, and sliced back per epoch; an epoch none of
    whose tracks triangulates is solved again alone for its failure reason.
    """
    good = [o for o in observations if o.ok and o.n_tracks > 0]
    if len(good) < 2 or any(o.n_views != good[0].n_views for o in good):
        return [reconstruct(o) for o in observations]
    per_track = any(o.track_sigma_px is not None for o in good)
    uv = np.concatenate([o.uv_px for o in good])
    sigma = np.concatenate([np.broadcast_to(o.sigma_uv_px, o.uv_px.shape[:2]) for o in good])
    batch = triangulate(uv, good[0].K, good[0].T_CW,
                        pixel_sigma_px=sigma if per_track else good[0].pixel_sigma_px)
    frames: list[Frame] = []
    start = 0
    for o in observations:
        if not (o.ok and o.n_tracks > 0):
            frames.append(reconstruct(o))
            continue
        sl = slice(start, start + o.n_tracks)
        start += o.n_tracks
        n_valid = int(np.sum(batch.valid[sl]))
        if n_valid == 0:
            frames.append(reconstruct(o))
            continue
        tri = Triangulation(
            X_W=batch.X_W[sl], cov_W=batch.cov_W[sl], valid=batch.valid[sl], failure_code=batch.failure_code[sl],
            views_used=batch.views_used[sl], n_views=batch.n_views[sl],
            rms_reprojection_px=batch.rms_reprojection_px[sl], chi2=batch.chi2[sl],
            n_valid=np.asarray(n_valid), ok=True, failure_reason="")
        frames.append(Frame(obs=o, tri=tri))
    return frames
