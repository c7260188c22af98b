"""3-D points from the planes of several calibrated cylindrical-imaging cameras (paper 004 eq 1–4).

Each angle ``α`` or ``β`` a camera measures defines a plane through its centre; a point is the
least-squares intersection of the 2n planes of n cameras.  Channels whose spots overlap are dropped
(004 §3.2 step 8); fewer than three independent planes is a reported failure (``ok`` False and a
``failure_reason``).

Frames: ``W`` is the world (laser-tracker) frame; ``C`` a camera frame (``z`` boresight, ``x`` right,
``y`` down); ``x_C = R_CW X_W + t_CW`` (004 eq 15, flag P004-7, docs/papers.md#p004-7).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from chaser.cylindrical._arrays import as_pairs, as_points
from chaser.cylindrical.calibration import IntrinsicCalibration
from vision.cylindrical import angles_from_points

__all__ = ["CalibratedCamera", "PlaneIntersection", "intersect_planes", "measure_points"]


@dataclass(frozen=True, eq=False)
class CalibratedCamera:
    """A calibrated camera of the system: intrinsic RBF maps and extrinsic pose ``x_C = R_CW X_W + t_CW``."""

    intrinsic: IntrinsicCalibration
    R_CW: np.ndarray
    t_CW: np.ndarray

    def angles_from_world(self, X_W: ArrayLike) -> np.ndarray:
        """004 eq (15) then (1)–(2): predicted ``(α, β)`` (rad) of world points ``(..., 3)``."""
        X = as_points(X_W, "X_W")
        return angles_from_points(X @ self.R_CW.T + self.t_CW)

    def pixels_from_world(self, X_W: ArrayLike) -> np.ndarray:
        """Back-projection of 004 §3.2: world point → angles → inverse RBF → predicted ``(u, v)`` px."""
        return self.intrinsic.pixels_from_angles(self.angles_from_world(X_W))

    def angles_from_pixels(self, uv_px: ArrayLike) -> np.ndarray:
        """Spot centres ``(u, v)`` px ``(..., 2)`` → ``(α, β)`` rad by the RBF calibration (004 eq 12–13)."""
        return self.intrinsic.angles_from_pixels(uv_px)


@dataclass(frozen=True, eq=False)
class PlaneIntersection:
    """3-D points from the planes of several cameras (004 eq 1–4).

    Attributes
    ----------
    X_W : (..., 3) ndarray
        Points (m); NaN where ``ok`` is False.
    ok : (...,) bool ndarray
    n_planes : (...,) int ndarray
        Planes (channels) used.
    independence : (...,) ndarray
        Smallest over largest singular value of the stacked unit plane normals (0 when < 3 planes).
    residual_rms_m : (...,) ndarray
        RMS distance of the point to its planes (m).
    covariance_m2 : (..., 3, 3) ndarray or None
        ``(Σ n̂ n̂ᵀ / (σ ρ)²)⁻¹`` with ``σ = angle_sigma_rad`` and ρ the camera-to-point range; only
        when ``angle_sigma_rad`` was given.
    failure_reason : (...,) ndarray of str
        "" where ok; otherwise why.
    """

    X_W: np.ndarray
    ok: np.ndarray
    n_planes: np.ndarray
    independence: np.ndarray
    residual_rms_m: np.ndarray
    covariance_m2: np.ndarray | None
    failure_reason: np.ndarray


def _sym_entries(nx: np.ndarray, ny: np.ndarray, nz: np.ndarray, w2: np.ndarray) -> tuple[np.ndarray, ...]:
    """Entries ``(xx, yy, zz, xy, xz, yz)`` of ``Σ_k w²_k n̂_k n̂_kᵀ`` from component arrays ``(K, ...)``."""
    wx, wy, wz = w2 * nx, w2 * ny, w2 * nz
    return ((wx * nx).sum(0), (wy * ny).sum(0), (wz * nz).sum(0), (wx * ny).sum(0), (wx * nz).sum(0),
            (wy * nz).sum(0))


def _sym_inverse(a: np.ndarray, b: np.ndarray, c: np.ndarray, e: np.ndarray, f: np.ndarray,
                 g: np.ndarray) -> tuple[tuple[np.ndarray, ...], np.ndarray]:
    """Adjugate and determinant of the symmetric matrices ``[[a, e, f], [e, b, g], [f, g, c]]``."""
    A00, A01, A02 = b * c - g * g, f * g - e * c, e * g - b * f
    A11, A12, A22 = a * c - f * f, e * f - a * g, a * b - e * e
    det = a * A00 + e * A01 + f * A02
    return (A00, A11, A22, A01, A02, A12), det


def _sym_eigvals(a: np.ndarray, b: np.ndarray, c: np.ndarray, e: np.ndarray, f: np.ndarray,
                 g: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ascending eigenvalues of the same symmetric matrices (closed trigonometric form)."""
    q = (a + b + c) / 3.0
    p1 = e * e + f * f + g * g
    p = np.sqrt(((a - q) ** 2 + (b - q) ** 2 + (c - q) ** 2 + 2.0 * p1) / 6.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        A, B, Cc, E, F, G = (a - q) / p, (b - q) / p, (c - q) / p, e / p, f / p, g / p
        r = np.clip((A * (B * Cc - G * G) - E * (E * Cc - G * F) + F * (E * G - B * F)) / 2.0, -1.0, 1.0)
    phi = np.where(p > 0, np.arccos(np.where(np.isfinite(r), r, 1.0)) / 3.0, 0.0)
    e1 = q + 2.0 * p * np.cos(phi)
    e3 = q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    return e3, 3.0 * q - e1 - e3, e1


def intersect_planes(
    R_CW: ArrayLike,
    t_CW: ArrayLike,
    alpha_beta_rad: ArrayLike,
    *,
    angle_sigma_rad: float | None = None,
    min_independence: float = 1e-6,
    strict: bool = False,
) -> PlaneIntersection:
    """Least-squares intersection of the planes of n cameras (004 eq 1–4).

    Each finite angle of camera ``c`` gives one plane through its centre,
    ``(r_c1 − tan α r_c3)·X = tan α t_c3 − t_c1`` and ``(r_c2 − tan β r_c3)·X = tan β t_c3 − t_c2``,
    normalised so that the residual is the distance to the plane; rows are weighted by the inverse
    range to the camera (a second pass), so the residuals are angles.  NaN angles are dropped
    channels (overlapped spots, 004 §3.2 step 8).  A point needs at least three planes whose normals
    span 3-D (``independence`` ≥ ``min_independence``, a numerical-rank test); otherwise it is a
    failure (NaN point and a reason), or a ``ValueError`` when ``strict``.  Three planes can be
    independent yet weak: for two cameras side by side, dropping an α channel leaves the two β planes,
    which both nearly contain the baseline, so the depth is poorly fixed (``independence`` ~ 1e-3);
    ``covariance_m2`` shows it.

    Parameters
    ----------
    R_CW : (C, 3, 3) array
    t_CW : (C, 3) array
        Extrinsics of the C cameras (m).
    alpha_beta_rad : (..., C, 2) array
        Angles per camera (rad); NaN for a channel that is not used.
    angle_sigma_rad : float, optional
        Angle noise per channel, for the covariance.
    """
    R = np.asarray(R_CW, dtype=float)
    t = np.asarray(t_CW, dtype=float)
    ab = np.asarray(alpha_beta_rad, dtype=float)
    if R.ndim != 3 or R.shape[1:] != (3, 3) or t.shape != (R.shape[0], 3):
        raise ValueError(f"R_CW, t_CW: expected (C, 3, 3) and (C, 3), got {R.shape} and {t.shape}")
    C = R.shape[0]
    if ab.ndim < 2 or ab.shape[-2:] != (C, 2):
        raise ValueError(f"alpha_beta_rad: expected shape (..., {C}, 2), got {ab.shape}")
    if angle_sigma_rad is not None and not angle_sigma_rad > 0:
        raise ValueError(f"angle_sigma_rad: must be positive, got {angle_sigma_rad!r}")
    batch = ab.shape[:-2]
    # plane-major layout (2C, ...): planes ordered (camera, channel); sums over planes are then fast
    tan = np.ascontiguousarray(np.moveaxis(np.tan(ab).reshape(batch + (2 * C,)), -1, 0))
    use = np.isfinite(tan)
    tan0 = np.where(use, tan, 0.0)
    # plane k of camera c, channel j: normal r_cj − tan r_c3, right-hand side tan t_c3 − t_cj
    Rj = R[:, :2, :].reshape(2 * C, 3)
    R3 = np.repeat(R[:, 2, :], 2, axis=0)
    tj = t[:, :2].reshape(2 * C)
    t3 = np.repeat(t[:, 2], 2)
    ex = (slice(None),) + (None,) * len(batch)
    nx, ny, nz = (Rj[:, i][ex] - tan0 * R3[:, i][ex] for i in range(3))
    norm = np.sqrt(nx * nx + ny * ny + nz * nz)
    nx, ny, nz = nx / norm, ny / norm, nz / norm
    d = (tan0 * t3[ex] - tj[ex]) / norm
    w = use.astype(float)
    n_planes = use.sum(0)
    # independence: singular values of the stacked used unit normals = sqrt(eigenvalues of Σ n̂ n̂ᵀ)
    lam_min, _, lam_max = _sym_eigvals(*_sym_entries(nx, ny, nz, w))
    with np.errstate(invalid="ignore", divide="ignore"):
        indep = np.where(lam_max > 0, np.sqrt(np.maximum(lam_min, 0.0) / lam_max), 0.0)
    ok = (n_planes >= 3) & (indep >= min_independence)
    centres = -np.einsum("cji,cj->ci", R, t)  # camera centres in W
    cam_of_plane = np.repeat(np.arange(C), 2)

    def solve(w2):
        ent = _sym_entries(nx, ny, nz, w2)
        adj, det = _sym_inverse(*ent)
        det = np.where(ok, det, 1.0)
        wd = w2 * d
        bx, by, bz = (wd * nx).sum(0), (wd * ny).sum(0), (wd * nz).sum(0)
        A00, A11, A22, A01, A02, A12 = adj
        with np.errstate(invalid="ignore", divide="ignore"):
            X = np.stack([A00 * bx + A01 * by + A02 * bz, A01 * bx + A11 * by + A12 * bz,
                          A02 * bx + A12 * by + A22 * bz], -1) / det[..., None]
        return X, adj, det

    X, _, _ = solve(w)
    rng_c = np.linalg.norm(np.where(ok[..., None], X, 0.0)[None] - centres[(slice(None),) + ex[1:] + (slice(None),)],
                           axis=-1)  # (C, ...)
    w2 = w / np.maximum(rng_c[cam_of_plane], 1e-9) ** 2
    X, adj, det = solve(w2)
    resid = (nx * X[..., 0] + ny * X[..., 1] + nz * X[..., 2] - d) * w
    rms = np.sqrt(np.sum(resid**2, axis=0) / np.maximum(n_planes, 1))
    cov = None
    if angle_sigma_rad is not None:
        A00, A11, A22, A01, A02, A12 = adj
        cov = np.stack([np.stack([A00, A01, A02], -1), np.stack([A01, A11, A12], -1),
                        np.stack([A02, A12, A22], -1)], -2) / det[..., None, None] * angle_sigma_rad**2
        cov = np.where(ok[..., None, None], cov, np.nan)
    reason = np.where(n_planes < 3, "fewer than 3 planes",
                      np.where(indep < min_independence, "planes not independent", ""))
    reason = np.asarray(reason, dtype=object)
    X = np.where(ok[..., None], X, np.nan)
    rms = np.where(ok, rms, np.nan)
    if strict and not np.all(ok):
        bad = np.flatnonzero(~np.asarray(ok).ravel())[0]
        raise ValueError(
            f"alpha_beta_rad: point {bad} has {int(np.asarray(n_planes).ravel()[bad])} usable plane(s) "
            f"(independence {float(np.asarray(indep).ravel()[bad]):.3g}); a 3-D point needs at least "
            f"3 independent planes"
        )
    return PlaneIntersection(X, ok, n_planes, indep, rms, cov, reason)


def measure_points(cameras: Sequence[CalibratedCamera], uv_px: ArrayLike, *,
                   angle_sigma_rad: float | None = None, strict: bool = False) -> PlaneIntersection:
    """3-D points from spot centres ``uv_px`` ``(..., C, 2)`` of C calibrated cameras (NaN = not used).

    Each camera's ``(u, v)`` is mapped to ``(α, β)`` by its RBF calibration, then
    :func:`intersect_planes`.  A NaN in ``u`` or ``v`` drops the whole camera for that point (the
    RBF needs both); use :func:`intersect_planes` directly to drop a single channel.
    """
    uv = as_pairs(uv_px, "uv_px")
    C = len(cameras)
    if uv.ndim < 2 or uv.shape[-2] != C:
        raise ValueError(f"uv_px: expected shape (..., {C}, 2), got {uv.shape}")
    ab = np.stack([cam.angles_from_pixels(uv[..., c, :]) for c, cam in enumerate(cameras)], -2)
    R = np.stack([cam.R_CW for cam in cameras])
    t = np.stack([cam.t_CW for cam in cameras])
    return intersect_planes(R, t, ab, angle_sigma_rad=angle_sigma_rad, strict=strict)
