"""Triangulation NEES on rendered data, with the truth point's own error accounted for.

A rendered track has no exact "true" 3-D point: :func:`vision.rendered.label_tracks` takes the
surface point seen through the keypoint of the track's first view, ``X_f``, which carries that
keypoint's localisation error ``e_f`` lifted onto the surface, ``X_f = X* + L e_f`` (``L = ∂X_f/∂uv_f``,
3×2, from two ray casts ±½ px about the keypoint).  The triangulated point ``X̂ = X* + G e`` shares
``e_f`` with it, so ``X̂ − X_f`` has the covariance

    S = C + σ_f² L Lᵀ − σ_f² (G_f Lᵀ + L G_fᵀ),    G_f = C J_fᵀ / σ_f²,

not the triangulation covariance ``C`` (``J_f`` is the projection Jacobian of view f).  The plain
statistic ``(X̂ − X_f)ᵀ C⁻¹ (X̂ − X_f)`` has expectation 3 for tracks of two views but ≈ 5 for tracks
of three (the first view's error counted twice): that is part of the rendered "NEES 4–6" of issue 16.
:func:`track_nees` returns both; the consistent one is ``(X̂ − X_f)ᵀ S⁺ (X̂ − X_f)`` scaled by
``3 / rank S`` (S has rank 2 for a two-view track: the first view's error along the epipolar line
cancels), so that its mean is 3 when the σ model is right.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from attitude.quaternion import matrix_from_quat
from vision.camera import PinholeCamera
from vision.observation import Observation
from vision.render import cast_body_points
from vision.target import Target

__all__ = ["TrackNees", "first_view_lift", "nees_with_truth_error", "projection_jacobian", "track_nees"]

#: half-step of the finite-difference lift, px
_LIFT_STEP_PX = 0.5


@dataclass(frozen=True)
class TrackNees:
    """NEES of the valid, correct points of one frame.

    Attributes
    ----------
    index : ndarray (m,) int
        Track indices.
    nees : ndarray (m,)
        ``3 / rank(S) · dᵀ S⁺ d`` (mean 3 under the σ model, module docstring).
    nees_plain : ndarray (m,)
        ``dᵀ C⁻¹ d`` against the first view's surface point (the figure before issue 16's fix).
    expected_plain : ndarray (m,)
        ``tr(C⁻¹ S)``, the plain statistic's expectation under the σ model.
    n_views : ndarray (m,) int
        Views the triangulation used.
    """

    index: np.ndarray
    nees: np.ndarray
    nees_plain: np.ndarray
    expected_plain: np.ndarray
    n_views: np.ndarray

    @staticmethod
    def concat(parts: Sequence[TrackNees]) -> TrackNees:
        """The points of several frames together (``index`` is then per frame, not unique)."""
        if not parts:
            z = np.zeros(0)
            return TrackNees(z.astype(int), z, z, z, z.astype(int))
        return TrackNees(*(np.concatenate([getattr(p, k) for p in parts]) for k in
                           ("index", "nees", "nees_plain", "expected_plain", "n_views")))


def first_view_lift(obs: Observation, target: Target, q_HT: np.ndarray, index: np.ndarray) -> np.ndarray:
    """``∂X_f/∂uv_f`` (k, 3, 2) in H of the tracks ``index``: how the truth point moves on the surface
    with its first view's keypoint (NaN where a ray misses the target)."""
    idx = np.asarray(index, dtype=int)
    L = np.full((idx.size, 3, 2), np.nan)
    if idx.size == 0:
        return L
    R_HT = matrix_from_quat(np.asarray(q_HT, dtype=float))
    first = np.argmax(obs.seen[idx], axis=1)
    h = _LIFT_STEP_PX
    for f in np.unique(first):
        sel = np.nonzero(first == f)[0]
        uv = obs.uv_px[idx[sel], f]
        steps = np.array([[-h, 0.0], [h, 0.0], [0.0, -h], [0.0, h]])
        pts = (uv[None, :, :] + steps[:, None, :]).reshape(-1, 2)
        K = obs.K[f]
        cam = PinholeCamera(width=obs.image_size[0], height=obs.image_size[1], fx=K[0, 0], fy=K[1, 1],
                            cx=K[0, 2], cy=K[1, 2])
        X_T, _ = cast_body_points(cam, obs.T_CW[f], target, q_HT, pts)
        X_H = (X_T @ R_HT.T).reshape(4, sel.size, 3)
        L[sel, :, 0] = (X_H[1] - X_H[0]) / (2 * h)
        L[sel, :, 1] = (X_H[3] - X_H[2]) / (2 * h)
    return L


def projection_jacobian(X_W: np.ndarray, K: np.ndarray, T_CW: np.ndarray) -> np.ndarray:
    """``∂uv/∂X_W`` (m, n, 2, 3) of points X_W (m, 3) in n cameras."""
    R = T_CW[:, :3, :3]
    X_C = np.einsum("nij,mj->mni", R, X_W) + T_CW[None, :, :3, 3]
    p = np.einsum("nij,mnj->mni", K, X_C)
    uv = p[..., :2] / p[..., 2:3]
    Jc = (K[None, :, :2, :] - uv[..., :, None] * K[None, :, 2:3, :]) / p[..., 2, None, None]
    return np.einsum("mnai,nij->mnaj", Jc, R)


def nees_with_truth_error(d_W: np.ndarray, J: np.ndarray, sigma_px: np.ndarray, used: np.ndarray,
                          first: np.ndarray, lift: np.ndarray) -> tuple[np.ndarray, ...]:
    """The statistics of :class:`TrackNees` from the error of each point against its truth point.

    ``d_W`` (m, 3) triangulated minus truth point, ``J`` (m, n, 2, 3) projection Jacobians, ``sigma_px``
    (m, n) σ per view, ``used`` (m, n) views the triangulation used, ``first`` (m,) the view whose
    keypoint defines the truth point, ``lift`` (m, 3, 2) ``∂X_f/∂uv_f``.  Returns ``(nees, nees_plain,
    expected_plain)``.
    """
    w = np.where(used, 1.0 / sigma_px**2, 0.0)
    H = np.einsum("mkai,mk,mkaj->mij", J, w, J)
    C = np.linalg.inv(H)
    ar = np.arange(len(d_W))
    s2f = sigma_px[ar, first] ** 2
    Gf = np.einsum("mij,maj->mia", C, J[ar, first]) * w[ar, first][:, None, None]
    cross = s2f[:, None, None] * Gf @ np.swapaxes(lift, 1, 2)
    S = C + s2f[:, None, None] * lift @ np.swapaxes(lift, 1, 2) - cross - np.swapaxes(cross, 1, 2)
    S = 0.5 * (S + np.swapaxes(S, 1, 2))
    # two used views, one of them the truth's: X̂ − X_f = G_other r_other lies in a plane (rank 2)
    rank = np.where(used[ar, first] & (used.sum(axis=1) == 2), 2, 3)
    lam, V = np.linalg.eigh(S)                                   # ascending
    keep = np.arange(3)[None, :] >= (3 - rank)[:, None]
    z = np.einsum("mji,mj->mi", V, d_W)
    q = np.sum(np.where(keep, z**2 / np.where(keep, lam, 1.0), 0.0), axis=1)
    return 3.0 * q / rank, np.einsum("mi,mij,mj->m", d_W, H, d_W), np.einsum("mij,mji->m", H, S)


def track_nees(obs: Observation, X_W: np.ndarray, valid: np.ndarray, views_used: np.ndarray,
               q_HT: np.ndarray, target: Target) -> TrackNees:
    """NEES of the valid, correct triangulated points of one observation (module docstring).

    ``X_W``, ``valid``, ``views_used`` come from :func:`reconstruction.triangulation.triangulate` on
    ``obs`` with its σ per track and view (``obs.sigma_uv_px``); the truth is ``obs.X_T_true``.
    """
    good = np.asarray(valid, bool) & (obs.feature_id >= 0)
    idx = np.nonzero(good)[0]
    if idx.size == 0:
        return TrackNees.concat([])
    L = first_view_lift(obs, target, q_HT, idx)
    ok = np.all(np.isfinite(L), axis=(1, 2))
    idx, L = idx[ok], L[ok]
    R_HT = matrix_from_quat(np.asarray(q_HT, dtype=float))
    d = X_W[idx] - obs.X_T_true[idx] @ R_HT.T
    use = np.asarray(views_used, bool)[idx]
    J = projection_jacobian(X_W[idx], obs.K, obs.T_CW)
    nees, plain, expected = nees_with_truth_error(d, J, obs.sigma_uv_px[idx], use,
                                                  np.argmax(obs.seen[idx], axis=1), L)
    return TrackNees(index=idx, nees=nees, nees_plain=plain, expected_plain=expected, n_views=use.sum(axis=1))
