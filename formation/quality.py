"""Observation quality of an observer set: the Cramér–Rao bound of the attitude increment.

:func:`crlb_score` builds a ``score_fn`` for :func:`formation.selection.select_observers` that
ranks every candidate k-subset at every epoch by the smallest achievable RMS error of the
inter-frame attitude increment, ``sqrt(tr F⁻¹_θθ)`` of
:func:`reconstruction.accuracy.attitude_increment_crlb` (Fisher information of the rigid motion
with the unknown surface points eliminated; the ML registration of ``reconstruction`` attains it).
Each observer is a pinhole camera at its position looking at the target's centre; a surface point
counts for a camera when it is in front of it, inside its image and (when normals are given) on
the side facing it.

What the bound says about geometry, compared with the point-at-the-centre proxy
:func:`formation.selection.point_dop`: both prefer shorter ranges and wider baselines, one factor
at a time.  But the attitude increment is far less sensitive to the baseline than a triangulated
point: at 60 m, three views at 2° and at 30° differ by ~3 % in the bound (point DOP: 14×), while
the bound grows in proportion to the range (the pixel footprint).  So the two disagree on the
range–baseline trade-off (a close narrow set beats a far wide one for the bound), and with
self-occlusion the bound also rewards views that share more visible surface.

Cost: the bound's few 3×3 products per (epoch, subset, point, view), computed in chunks of at
most ``max_batch_views`` point-views (about 3·10⁵ point-views per second on one core).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from attitude.quaternion import matrix_from_quat, quat_from_rotvec
from formation.geometry import look_at
from reconstruction.accuracy import attitude_increment_crlb

if TYPE_CHECKING:
    from vision.camera import PinholeCamera

__all__ = ["DEFAULT_INCREMENT_ROTVEC_H", "camera_poses_at_target", "crlb_score"]

#: 003's attitude step between frames, [0.5°, 0.5°, 0.5°] (0.866°), as a rotation vector in H, rad.
DEFAULT_INCREMENT_ROTVEC_H = tuple(float(v) for v in np.deg2rad([0.5, 0.5, 0.5]))


def camera_poses_at_target(r_ST_H: ArrayLike) -> np.ndarray:
    """Look-at poses ``T_CW (..., 4, 4)`` of cameras at ``r_ST_H (..., 3)`` aimed at the target's centre.

    Image up is towards +z_H, or +x_H where the line of sight is within 8° of z_H.  (The bound does
    not depend on the roll about the boresight except through which points fall inside the image
    corners.)  Positions at the target's centre get the identity rotation; the caller marks them.
    """
    r = np.asarray(r_ST_H, dtype=float)
    d = np.linalg.norm(r, axis=-1, keepdims=True)
    safe = np.where(d > 0, r, np.array([0.0, 0.0, -1.0]))
    dz = np.abs(safe[..., 2:3]) / np.linalg.norm(safe, axis=-1, keepdims=True)
    up = np.where(dz > 0.99, np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))
    return look_at(safe, np.zeros(3), up)


def _check_camera(camera) -> tuple[np.ndarray, tuple[int, int] | None]:
    try:
        K = np.asarray(camera.K, dtype=float)
    except AttributeError:
        raise ValueError(f"camera: expected an object with K and image_size (vision.camera.PinholeCamera), "
                         f"got {type(camera).__name__}") from None
    if K.shape != (3, 3):
        raise ValueError(f"camera: K must be 3x3, got shape {K.shape}")
    size = getattr(camera, "image_size", None)
    return K, (None if size is None else (int(size[0]), int(size[1])))


def crlb_score(
    camera: PinholeCamera,
    points_H: ArrayLike,
    *,
    pixel_sigma_px: float,
    increment_rotvec_H: ArrayLike = DEFAULT_INCREMENT_ROTVEC_H,
    normals_H: ArrayLike | None = None,
    use_image_bounds: bool = True,
    max_batch_views: int = 400_000,
) -> Callable[[np.ndarray], np.ndarray]:
    """Score function: predicted attitude-increment accuracy of every observer subset (lower is better).

    Parameters
    ----------
    camera : vision.camera.PinholeCamera
        Camera of every observer (anything with ``K (3, 3)`` in px and ``image_size (w, h)``).
    points_H : (M, 3) or (T, M, 3) array_like
        Target surface points relative to the target's centre in H, m; per epoch when the target
        turns (``R_HT(t) X_T``), else the same at every epoch.
    pixel_sigma_px : float
        Pixel noise σ per image coordinate, px, > 0.
    increment_rotvec_H : (3,) or (T, 3) array_like
        Expected rotation of the target between two frames, as a rotation vector in H, rad
        (default: 003's step [0.5°, 0.5°, 0.5°], 0.866°).  The bound linearised at zero motion
        ignores how poorly narrow baselines fix the points' depths (the rotation then moves
        points along unknown depths); a realistic increment puts that coupling back.
    normals_H : array_like, same shape as ``points_H``, optional
        Outward surface normals in H: a point is seen only by cameras on its front side
        (self-occlusion of a convex body; occlusion by other parts is not modelled).
    use_image_bounds : bool
        Count a point only inside the camera's image (``camera.image_size``).
    max_batch_views : int
        Largest number of (subset, point, view) triples computed at once (memory bound).

    Returns
    -------
    callable
        ``score(r (T, S, k, 3)) -> (T, S)``: ``sqrt(tr cov_θθ)`` of
        :func:`reconstruction.accuracy.attitude_increment_crlb`, rad, for the cameras at the
        subset positions (H, m, relative to the target's centre) looking at the centre; ``inf``
        where the bound does not exist (fewer than 3 points seen in two views at both epochs,
        collinear points, a camera at the target's centre).
    """
    K, size = _check_camera(camera)
    X = np.asarray(points_H, dtype=float)
    if X.ndim not in (2, 3) or X.shape[-1] != 3 or X.shape[-2] < 3:
        raise ValueError(f"points_H: expected shape (M, 3) or (T, M, 3) with M >= 3, got {X.shape}")
    if not np.all(np.isfinite(X)):
        raise ValueError("points_H: contains non-finite values")
    if not np.isfinite(pixel_sigma_px) or pixel_sigma_px <= 0:
        raise ValueError(f"pixel_sigma_px: must be positive, got {pixel_sigma_px!r}")
    rv = np.asarray(increment_rotvec_H, dtype=float)
    if rv.ndim not in (1, 2) or rv.shape[-1] != 3 or not np.all(np.isfinite(rv)):
        raise ValueError(f"increment_rotvec_H: expected finite (3,) or (T, 3), got shape {rv.shape}")
    R_delta = matrix_from_quat(quat_from_rotvec(rv))
    Nrm = None
    if normals_H is not None:
        Nrm = np.asarray(normals_H, dtype=float)
        if Nrm.shape != X.shape:
            raise ValueError(f"normals_H: expected the shape of points_H {X.shape}, got {Nrm.shape}")
    if max_batch_views < 1:
        raise ValueError(f"max_batch_views: must be >= 1, got {max_batch_views!r}")
    if use_image_bounds and size is None:
        raise ValueError("camera: has no image_size; pass use_image_bounds=False")
    image_size = size if use_image_bounds else None

    def score(r_ST_H: np.ndarray) -> np.ndarray:
        r = np.asarray(r_ST_H, dtype=float)
        if r.ndim != 4 or r.shape[-1] != 3:
            raise ValueError(f"r_ST_H: expected shape (T, S, k, 3), got {r.shape}")
        T, S, k, _ = r.shape
        for name, a in (("points_H", X), ("increment_rotvec_H", rv)):
            if a.ndim == (3 if name == "points_H" else 2) and a.shape[0] != T:
                raise ValueError(f"{name}: {a.shape[0]} epochs, the positions have {T}")
        M = X.shape[-2]
        Xt = np.broadcast_to(X if X.ndim == 3 else X[None], (T, M, 3))
        Nt = None if Nrm is None else np.broadcast_to(Nrm if Nrm.ndim == 3 else Nrm[None], (T, M, 3))
        Rt = np.broadcast_to(R_delta if R_delta.ndim == 3 else R_delta[None], (T, 3, 3))
        Kk = np.broadcast_to(K, (k, 3, 3))
        at_centre = np.any(np.linalg.norm(r, axis=-1) == 0, axis=-1)  # (T, S)
        out = np.full(T * S, np.inf)
        flat_r = r.reshape(T * S, k, 3)
        t_of = np.repeat(np.arange(T), S)
        step = max(1, max_batch_views // (k * M))
        for lo in range(0, T * S, step):
            sl = slice(lo, min(lo + step, T * S))
            rb, tb = flat_r[sl], t_of[sl]
            Xb = Xt[tb]  # (B, M, 3)
            T_CW = camera_poses_at_target(rb)  # (B, k, 4, 4)
            vis = vis_next = None
            if Nt is not None:  # each epoch's own view sets: the points and normals turn by R_delta
                vis = _facing_in_view(rb, Xb, Nt[tb], K, T_CW, image_size)
                R_b = Rt[tb][:, None]
                vis_next = _facing_in_view(rb, (R_b @ Xb[..., None])[..., 0], (R_b @ Nt[tb][..., None])[..., 0],
                                           K, T_CW, image_size)
            b = attitude_increment_crlb(Xb, Kk, T_CW, pixel_sigma_px=pixel_sigma_px, visible=vis,
                                        visible_next=vis_next, R_delta=Rt[tb], image_size=image_size)
            out[sl] = np.where(np.asarray(b.ok), np.asarray(b.rms_angle_rad), np.inf)
        return np.where(at_centre, np.inf, out.reshape(T, S))

    return score


def _facing_in_view(r: np.ndarray, X: np.ndarray, N: np.ndarray, K: np.ndarray, T_CW: np.ndarray,
                    image_size) -> np.ndarray:
    """(B, M, k): points ``X (B, M, 3)`` with normals ``N`` facing cameras at ``r (B, k, 3)`` and in view."""
    facing = np.einsum("bkd,bmd->bmk", r, N) > np.sum(X * N, -1)[..., None]
    return facing & _in_view(X, K, T_CW, image_size)


def _in_view(X: np.ndarray, K: np.ndarray, T_CW: np.ndarray, image_size) -> np.ndarray:
    """(B, M, k): points ``X (B, M, 3)`` in front of cameras ``T_CW (B, k, 4, 4)`` (and inside the image)."""
    X_C = np.einsum("bkij,bmj->bmki", T_CW[..., :3, :3], X) + T_CW[:, None, :, :3, 3]
    z = X_C[..., 2]
    ok = z > 0
    if image_size is not None:
        with np.errstate(divide="ignore", invalid="ignore"):
            u = (K[0, 0] * X_C[..., 0] + K[0, 1] * X_C[..., 1]) / z + K[0, 2]
            v = K[1, 1] * X_C[..., 1] / z + K[1, 2]
        w, h = image_size
        ok &= (u >= 0) & (u < w) & (v >= 0) & (v < h)
    return ok
