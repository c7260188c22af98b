"""Predicted accuracy: Cramér–Rao bounds of triangulated points and of the attitude increment.

Model (the geometric observation mode of ``vision.geometric``): M surface points are seen, with
independent Gaussian pixel noise of σ px per coordinate, by calibrated cameras at epoch t and again
at t + Δt after the target moved rigidly, ``X' = ΔR X + Δt``.  Each epoch has its own view set per
point (a point seen by cameras 1 and 2 at t may be seen by 1, 2 and 3, or by 2 alone, at t + Δt).  The unknowns are the motion
``ξ = [δθ, δt]`` and the M point positions (the target is non-cooperative: no model).  The Fisher
information of the motion with the points eliminated (Schur complement) is

.. math:: F = \\sum_i M_i^T (C'_i + ΔR\\, C_i\\, ΔR^T)^{-1} M_i,
          \\qquad M_i = [\\,[ΔR X_i \\times],\\ -I\\,],

where ``C_i = (Σ_{k ∈ V_i} J_kᵀ J_k / σ²)⁻¹`` is point i's triangulation bound at t over the views
``V_i`` that see it then, and ``C'_i`` the same at t + Δt over its views ``V'_i`` then (003 eq (11)–(12)
registers the two triangulated clouds; the points are the nuisance parameters).  Only points seen
in at least two views at both epochs enter (the ones the pipeline triangulates at both).  ``F⁻¹`` bounds the covariance of any unbiased estimate of ``[δθ, δt]`` (δθ: rotation
vector in W, ``ΔR_true = exp([δθ×]) ΔR̂``); it is exactly the covariance returned by
:func:`reconstruction.registration.fit_rigid_ml`, which attains it to first order.

The computation is a few 3×3 and 6×6 products per point, vectorised over any leading axes, so a
formation planner can score thousands of observer subsets in one call.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from attitude.batch import cross_product_matrices
from reconstruction._geometry import (
    as_float,
    check_intrinsics,
    check_points,
    check_poses,
    check_positive,
    project,
    scalar_or_array,
    sym3_inv,
)

__all__ = ["AttitudeIncrementBound", "point_covariance", "attitude_increment_crlb"]


@dataclass(frozen=True)
class AttitudeIncrementBound:
    """Cramér–Rao bound of the inter-frame motion (batch axes ``...``).

    Attributes
    ----------
    cov : ndarray (..., 6, 6)
        Bound on the covariance of ``[δθ (rad), δt (m)]``; NaN when not ok.
    cov_rotation : ndarray (..., 3, 3)
        Rotation block (δθ marginal), rad².
    rms_angle_rad : ndarray (...,)
        ``sqrt(tr cov_rotation)``: the smallest achievable RMS of the attitude-increment error
        ``‖δθ‖``, rad.
    n_points : ndarray (...,) int
        Points seen in at least two views at both epochs (the ones that carry information).
    ok : bool or ndarray (...,) bool
    failure_reason : str or ndarray (...,) str
    """

    cov: np.ndarray
    cov_rotation: np.ndarray
    rms_angle_rad: np.ndarray
    n_points: np.ndarray
    ok: bool | np.ndarray
    failure_reason: str | np.ndarray

    @property
    def rms_angle_deg(self) -> np.ndarray:
        """``rms_angle_rad`` in degrees."""
        return np.degrees(self.rms_angle_rad)


def _visibility(X_W, K, T, image_size):
    uv, X_C, _ = project(X_W[..., :, None, :], K[..., None, :, :, :], T[..., None, :, :, :])
    vis = X_C[..., 2] > 0
    if image_size is not None:
        w, h = image_size
        vis &= (uv[..., 0] >= 0) & (uv[..., 0] < w) & (uv[..., 1] >= 0) & (uv[..., 1] < h)
    return vis


def _information(X_W, K, T, sigma, vis):
    """Per-point Fisher information ``Σ_k vis J_kᵀ J_k / σ²`` (..., M, 3, 3)."""
    _, _, J = project(X_W[..., :, None, :], K[..., None, :, :, :], T[..., None, :, :, :])
    w = np.where(vis, 1.0 / sigma**2, 0.0)
    JtW = np.swapaxes(J, -1, -2) * w[..., None, None]
    return np.sum(JtW @ J, axis=-3)


def _check_visible(visible, shape, name):
    if visible is None:
        return None
    vis = np.asarray(visible, dtype=bool)
    try:
        return np.broadcast_to(vis, shape)
    except ValueError:
        raise ValueError(f"{name}: shape {vis.shape} does not broadcast to "
                         f"(..., n_points, n_views) = {shape}") from None


def _check_common(X_W, K, T_CW, pixel_sigma_px, visible, image_size):
    X = check_points(X_W, "X_W", allow_nan=False)
    K = check_intrinsics(K)
    T = check_poses(T_CW)
    n = K.shape[-3]
    if T.shape[-3] != n:
        raise ValueError(f"T_CW: expected {n} views like K, got {T.shape}")
    batch = np.broadcast_shapes(X.shape[:-2], K.shape[:-3], T.shape[:-3])
    M = X.shape[-2]
    sigma = check_positive(pixel_sigma_px, "pixel_sigma_px", batch + (M, n))
    vis = _check_visible(visible, batch + (M, n), "visible")
    if image_size is not None:
        if len(image_size) != 2 or min(image_size) <= 0:
            raise ValueError(f"image_size: expected (width, height) > 0, got {image_size!r}")
    X = np.broadcast_to(X, batch + (M, 3))
    K = np.broadcast_to(K, batch + (n, 3, 3))
    T = np.broadcast_to(T, batch + (n, 4, 4))
    return X, K, T, sigma, vis, batch


def point_covariance(X_W: ArrayLike, K: ArrayLike, T_CW: ArrayLike, *, pixel_sigma_px: ArrayLike,
                     visible: ArrayLike | None = None,
                     image_size: tuple[int, int] | None = None) -> np.ndarray:
    """Cramér–Rao bound of each point's triangulated position, ``(Σ_k J_kᵀ J_k / σ²)⁻¹``.

    Parameters
    ----------
    X_W : array_like (..., M, 3)
        True points in W, m.
    K : array_like (..., n, 3, 3)
        Intrinsics, px.
    T_CW : array_like (..., n, 4, 4)
        Camera-from-world poses.
    pixel_sigma_px : float or array_like broadcastable to (..., M, n)
        Pixel noise σ per coordinate, px.
    visible : array_like (..., M, n) bool, optional
        Which views see which point; default: in front of the camera (and inside the image when
        ``image_size`` is given).  Occlusion is the caller's business.
    image_size : (width, height), optional

    Returns
    -------
    ndarray (..., M, 3, 3)
        Covariance bound, m²; NaN for points seen in fewer than two views.
    """
    X, K, T, sigma, vis, _ = _check_common(X_W, K, T_CW, pixel_sigma_px, visible, image_size)
    if vis is None:
        vis = _visibility(X, K, T, image_size)
    A = _information(X, K, T, sigma, vis)
    C, _ = sym3_inv(A)
    return np.where((np.sum(vis, -1) >= 2)[..., None, None], C, np.nan)


def attitude_increment_crlb(X_W: ArrayLike, K: ArrayLike, T_CW: ArrayLike, *,
                            pixel_sigma_px: ArrayLike, visible: ArrayLike | None = None,
                            visible_next: ArrayLike | None = None,
                            pixel_sigma_px_next: ArrayLike | None = None,
                            R_delta: ArrayLike | None = None, t_delta: ArrayLike | None = None,
                            K_next: ArrayLike | None = None, T_CW_next: ArrayLike | None = None,
                            image_size: tuple[int, int] | None = None) -> AttitudeIncrementBound:
    """Cramér–Rao lower bound of the attitude increment between two epochs (see module doc).

    Parameters
    ----------
    X_W : array_like (..., M, 3)
        Target surface points in W at epoch t, m (true positions).
    K : array_like (..., n, 3, 3)
        Intrinsics of the n observers, px.
    T_CW : array_like (..., n, 4, 4)
        Camera-from-world poses at t.
    pixel_sigma_px : float or array_like broadcastable to (..., M, n)
        Pixel noise σ per coordinate, px.
    visible : array_like (..., M, n) bool, optional
        Which views see point i at t.  Default (with ``visible_next`` also omitted): computed per
        epoch (in front, inside the image when ``image_size`` is given).
    visible_next : array_like (..., M, n) bool, optional
        Which views see point i at t + Δt; required with ``visible`` (tracks change view sets
        between epochs: one mask for both put the bound 5–18 % off on rendered data, issue 16).
        Pass ``visible_next=visible`` only where the view sets are known not to change.
    pixel_sigma_px_next : float or array_like broadcastable to (..., M, n), optional
        Pixel noise σ at t + Δt, px (default: ``pixel_sigma_px``; per keypoint when the noise
        depends on the keypoint's scale).
    R_delta : array_like (..., 3, 3), optional
        Motion of the target in W between the epochs (default identity; for increments of a
        degree the bound barely depends on it).
    t_delta : array_like (..., 3), optional
        Translation of the motion, m (default 0).
    K_next, T_CW_next : optional
        Cameras at t + Δt (default: the same as at t).
    image_size : (width, height), optional

    Returns
    -------
    AttitudeIncrementBound
        ``ok=False`` when fewer than 3 points are seen in two views at both epochs, or when they
        are collinear.
    """
    X, K, T, sigma, vis, batch = _check_common(X_W, K, T_CW, pixel_sigma_px, visible, image_size)
    if (visible is None) != (visible_next is None):
        raise ValueError("visible, visible_next: give the visibility of both epochs or of neither "
                         "(pass visible_next=visible where the view sets do not change)")
    vis_next = _check_visible(visible_next, vis.shape if vis is not None else (), "visible_next")
    sigma_next = sigma if pixel_sigma_px_next is None else check_positive(
        pixel_sigma_px_next, "pixel_sigma_px_next", sigma.shape)
    R = np.eye(3) if R_delta is None else as_float(R_delta, "R_delta")
    tv = np.zeros(3) if t_delta is None else as_float(t_delta, "t_delta")
    if R.shape[-2:] != (3, 3) or tv.shape[-1:] != (3,):
        raise ValueError(f"R_delta, t_delta: expected (..., 3, 3) and (..., 3), got {R.shape}, "
                         f"{tv.shape}")
    K2 = K if K_next is None else np.broadcast_to(check_intrinsics(K_next, "K_next"), K.shape)
    T2 = T if T_CW_next is None else np.broadcast_to(check_poses(T_CW_next, "T_CW_next"),
                                                     T.shape)
    RX = (R[..., None, :, :] @ X[..., None])[..., 0]
    Y = RX + tv[..., None, :]
    if vis is None:
        vis1 = _visibility(X, K, T, image_size)
        vis2 = _visibility(Y, K2, T2, image_size)
    else:
        vis1, vis2 = vis, vis_next
    use = (np.sum(vis1, -1) >= 2) & (np.sum(vis2, -1) >= 2)
    C1, _ = sym3_inv(_information(X, K, T, sigma, vis1))
    C2, _ = sym3_inv(_information(Y, K2, T2, sigma_next, vis2))
    Rb = np.broadcast_to(R, batch + (3, 3))[..., None, :, :]
    C = C2 + Rb @ C1 @ np.swapaxes(Rb, -1, -2)
    W, _ = sym3_inv(np.where(use[..., None, None], C, np.eye(3)))
    W = np.where(use[..., None, None], W, 0.0)
    S = cross_product_matrices(RX)
    StW = np.swapaxes(S, -1, -2) @ W
    F = np.empty(batch + (6, 6))
    F[..., :3, :3] = np.sum(StW @ S, axis=-3)
    F[..., :3, 3:] = -np.sum(StW, axis=-3)
    F[..., 3:, :3] = np.swapaxes(F[..., :3, 3:], -1, -2)
    F[..., 3:, 3:] = np.sum(W, axis=-3)
    n_pts = np.sum(use, -1)
    # collinearity of the used points: second singular value of their centred scatter
    cnt = np.maximum(n_pts, 1)[..., None]
    Xu = np.where(use[..., None], X, 0.0)
    mean = np.sum(Xu, -2) / cnt
    D = np.where(use[..., None], X - mean[..., None, :], 0.0)
    ev = np.linalg.eigvalsh(np.swapaxes(D, -1, -2) @ D)
    collinear = ~(ev[..., 1] > 1e-12 * np.maximum(ev[..., 2], 1e-300))
    ok = (n_pts >= 3) & ~collinear & np.all(np.isfinite(F), (-2, -1))
    cov = np.linalg.inv(np.where(ok[..., None, None], F, np.eye(6)))
    cov = np.where(ok[..., None, None], cov, np.nan)
    reason = np.where(n_pts < 3, "fewer than 3 points seen in two views at both epochs",
                      np.where(~ok, "points are collinear", ""))
    cov_rot = cov[..., :3, :3]
    return AttitudeIncrementBound(
        cov=cov, cov_rotation=cov_rot,
        rms_angle_rad=np.sqrt(np.trace(cov_rot, axis1=-2, axis2=-1)), n_points=n_pts,
        ok=scalar_or_array(ok), failure_reason=scalar_or_array(reason.astype(str)),
    )
