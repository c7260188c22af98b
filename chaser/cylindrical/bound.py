"""Cramér–Rao bounds of the cylindrical-imaging system (paper 004) from its own measurement model.

Each linear CCD measures one angle per LED: camera ``c`` gives ``α_c = atan2(x_C, z_C)`` and
``β_c = atan2(y_C, z_C)`` of ``x_C = R_CW X_W + t_CW`` (004 eq 1–2 and 15), each with independent
Gaussian noise of standard deviation ``σ`` (rad).  The Fisher information of the 3-D point is
``J = Hᵀ R⁻¹ H`` with ``H = ∂(α_1, β_1, …, α_C, β_C)/∂X_W`` and ``R = diag(σ²)``; its inverse is the
bound on the covariance of any unbiased point estimate (:func:`point_crlb`).

The attitude of 004 eq 5–11 is a function of the three LEDs only (the LED layout is not used: the
body frame is ``−x_S ∥ ab``, ``y_S ∥ bc′``).  With the layout unknown, the three points (9
coordinates) and (position, attitude, shape) (9 parameters) are in one-to-one correspondence, so the
Cramér–Rao bound of the attitude is the point bound propagated through the attitude solution:
``Σ_θ = G diag(Σ_a, Σ_b, Σ_c) Gᵀ`` with ``G = ∂δθ/∂(a, b, c)`` (:func:`attitude_crlb`).  ``δθ`` is the
rotation vector of the error in the reference frame, ``R̂_OS = exp([δθ×]) R_OS``; its norm is the
rotation angle of ``R̂_OS R_OSᵀ``, free of any Euler-angle singularity.  The bound of the 3-1-2
yaw/roll/pitch (corrected eq 9–11) follows by the Jacobian of the Euler angles with respect to
``δθ``, which grows as ``1/cos(roll)`` for yaw and pitch near the gimbal lock (roll → ±90°).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from attitude.quaternion import (
    matrix_from_quat,
    quat_from_matrix,
    quat_from_rotvec,
    rotvec_from_quat,
)
from chaser.cylindrical._arrays import as_points
from chaser.cylindrical.attitude import attitude_from_three_points, yaw_roll_pitch_from_matrix

__all__ = ["angle_jacobian", "point_fisher_information", "PointBound", "point_crlb", "AttitudeBound",
           "attitude_jacobian", "attitude_crlb", "rotation_error_vector"]


def angle_jacobian(R_CW: ArrayLike, t_CW: ArrayLike, X_W: ArrayLike) -> np.ndarray:
    """``∂(α, β)/∂X_W`` of every camera (004 eq 1–2 after eq 15): ``(..., C, 2, 3)`` rad/m.

    ``α = atan2(x, z)`` gives ``∂α/∂x_C = (z, 0, −x)/(x² + z²)``; ``β = atan2(y, z)`` gives
    ``∂β/∂x_C = (0, z, −y)/(y² + z²)``; both are multiplied by ``R_CW`` (``∂x_C/∂X_W``).
    """
    R = np.asarray(R_CW, dtype=float)
    t = np.asarray(t_CW, dtype=float)
    X = as_points(X_W, "X_W")
    if R.ndim != 3 or R.shape[1:] != (3, 3) or t.shape != (R.shape[0], 3):
        raise ValueError(f"R_CW, t_CW: expected shapes (C, 3, 3) and (C, 3), got {R.shape} and {t.shape}")
    xc = np.einsum("cij,...j->...ci", R, X) + t  # (..., C, 3)
    x, y, z = xc[..., 0], xc[..., 1], xc[..., 2]
    zero = np.zeros_like(x)
    d_alpha = np.stack([z, zero, -x], -1) / (x * x + z * z)[..., None]
    d_beta = np.stack([zero, z, -y], -1) / (y * y + z * z)[..., None]
    d_C = np.stack([d_alpha, d_beta], -2)  # (..., C, 2, 3) w.r.t. x_C
    return np.einsum("...ckj,cji->...cki", d_C, R)


def point_fisher_information(R_CW: ArrayLike, t_CW: ArrayLike, X_W: ArrayLike, angle_sigma_rad: ArrayLike, *,
                             used: ArrayLike | None = None) -> np.ndarray:
    """Fisher information ``J = Hᵀ R⁻¹ H`` (m⁻²) of world points ``(..., 3)`` from the measured angles.

    Parameters
    ----------
    R_CW, t_CW : (C, 3, 3), (C, 3) arrays
        Camera poses, ``x_C = R_CW X_W + t_CW`` (004 eq 15).
    X_W : (..., 3) array
        True points (m).
    angle_sigma_rad : float or (C, 2) array
        Standard deviation of each channel's angle (α, β) per camera.
    used : (..., C, 2) bool array, optional
        Channels that measure the point (False: dropped or outside the field); default all.

    Returns
    -------
    (..., 3, 3) ndarray
    """
    H = angle_jacobian(R_CW, t_CW, X_W)
    sig = np.broadcast_to(np.asarray(angle_sigma_rad, dtype=float), H.shape[-3:-1])
    if not np.all(sig > 0):
        raise ValueError("angle_sigma_rad: must be positive")
    w = 1.0 / sig**2
    if used is not None:
        w = w * np.asarray(used, dtype=float)
    return np.einsum("...cki,...ck,...ckj->...ij", H, np.broadcast_to(w, H.shape[:-1]), H)


@dataclass(frozen=True, eq=False)
class PointBound:
    """Cramér–Rao bound of 3-D points (004 eq 1–4 with angle noise).

    Attributes
    ----------
    covariance_m2 : (..., 3, 3) ndarray
        ``J⁻¹``; NaN where ``ok`` is False.
    rms_m : (...,) ndarray
        ``sqrt(trace)``: the bound on the RMS 3-D error.
    ok : (...,) bool ndarray
        False where the information is singular (fewer than three independent planes).
    """

    covariance_m2: np.ndarray
    rms_m: np.ndarray
    ok: np.ndarray


def point_crlb(R_CW: ArrayLike, t_CW: ArrayLike, X_W: ArrayLike, angle_sigma_rad: ArrayLike, *,
               used: ArrayLike | None = None, min_condition: float = 1e-12) -> PointBound:
    """Cramér–Rao bound of points measured by the cameras: ``J⁻¹`` of :func:`point_fisher_information`."""
    J = point_fisher_information(R_CW, t_CW, X_W, angle_sigma_rad, used=used)
    ev = np.linalg.eigvalsh(J)
    ok = ev[..., 0] > min_condition * np.maximum(ev[..., -1], 1e-300)
    safe = np.where(ok[..., None, None], J, np.eye(3))
    cov = np.where(ok[..., None, None], np.linalg.inv(safe), np.nan)
    return PointBound(cov, np.sqrt(np.trace(cov, axis1=-2, axis2=-1)), ok)


def rotation_error_vector(R_est: ArrayLike, R_true: ArrayLike) -> np.ndarray:
    """Rotation vector ``δθ`` (rad) of ``R_est R_trueᵀ`` (reference frame): ``R_est = exp([δθ×]) R_true``.

    Its norm is the rotation-angle error, which no Euler sequence amplifies.
    """
    E = np.asarray(R_est, dtype=float) @ np.swapaxes(np.asarray(R_true, dtype=float), -1, -2)
    return rotvec_from_quat(quat_from_matrix(E))


def attitude_jacobian(a: ArrayLike, b: ArrayLike, c: ArrayLike, *, step_m: float = 1e-6) -> np.ndarray:
    """``G = ∂δθ/∂(a, b, c)`` ``(..., 3, 9)`` (rad/m) of the 004 attitude solution (eq 5–11).

    Central differences through :func:`chaser.cylindrical.attitude_from_three_points` itself, so the
    propagation follows the solution that is used (virtual point, Cayley least squares, switching).
    """
    P = np.stack([as_points(v, n) for v, n in ((a, "a"), (b, "b"), (c, "c"))], -2)  # (..., 3, 3)
    batch = P.shape[:-2]
    R0 = attitude_from_three_points(P[..., 0, :], P[..., 1, :], P[..., 2, :]).R_OS
    steps = np.eye(9).reshape(9, 3, 3) * step_m  # (9, led, xyz)
    Pp = P[..., None, :, :] + steps  # (..., 9, 3, 3)
    Pm = P[..., None, :, :] - steps
    Rp = attitude_from_three_points(Pp[..., 0, :], Pp[..., 1, :], Pp[..., 2, :]).R_OS
    Rm = attitude_from_three_points(Pm[..., 0, :], Pm[..., 1, :], Pm[..., 2, :]).R_OS
    R0b = np.broadcast_to(R0[..., None, :, :], batch + (9, 3, 3))
    d = (rotation_error_vector(Rp, R0b) - rotation_error_vector(Rm, R0b)) / (2 * step_m)  # (..., 9, 3)
    return np.swapaxes(d, -1, -2)


def _euler_jacobian(R_OS: np.ndarray, step_rad: float = 1e-7) -> np.ndarray:
    """``∂(yaw, roll, pitch)/∂δθ`` ``(..., 3, 3)`` of the corrected eq 9–11 at ``R_OS`` (central differences)."""
    cols = []
    for k in range(3):
        v = np.zeros(3)
        v[k] = step_rad
        Rp = matrix_from_quat(quat_from_rotvec(v)) @ R_OS
        Rm = matrix_from_quat(quat_from_rotvec(-v)) @ R_OS
        d = yaw_roll_pitch_from_matrix(Rp) - yaw_roll_pitch_from_matrix(Rm)
        cols.append((d + np.pi) % (2 * np.pi) - np.pi)
    return np.stack(cols, -1) / (2 * step_rad)


@dataclass(frozen=True, eq=False)
class AttitudeBound:
    """Cramér–Rao bound of the three-LED attitude (004 eq 5–11).

    Attributes
    ----------
    covariance_rad2 : (..., 3, 3) ndarray
        Covariance of the rotation-vector error ``δθ`` (reference frame ``O``).
    rotation_rms_rad : (...,) ndarray
        ``sqrt(trace)``: the bound on the RMS rotation-angle error.
    euler_covariance_rad2 : (..., 3, 3) ndarray
        Covariance of (yaw, roll, pitch), 3-1-2 of the corrected eq 9–11.
    euler_sigma_rad : (..., 3) ndarray
        Its standard deviations; yaw and pitch grow as ``1/cos(roll)`` near the gimbal lock.
    """

    covariance_rad2: np.ndarray
    rotation_rms_rad: np.ndarray
    euler_covariance_rad2: np.ndarray
    euler_sigma_rad: np.ndarray


def attitude_crlb(a: ArrayLike, b: ArrayLike, c: ArrayLike, cov_a: ArrayLike, cov_b: ArrayLike,
                  cov_c: ArrayLike) -> AttitudeBound:
    """Cramér–Rao bound of the attitude from three LEDs whose fixes have covariances ``cov_*`` (m²).

    ``Σ_θ = G diag(Σ_a, Σ_b, Σ_c) Gᵀ`` with ``G`` of :func:`attitude_jacobian` (independent LED fixes);
    with ``cov_*`` the point bounds of :func:`point_crlb` this is the bound of any unbiased attitude
    estimate that, like 004's, does not know the LED layout.
    """
    a, b, c = (as_points(v, n) for v, n in ((a, "a"), (b, "b"), (c, "c")))
    G = attitude_jacobian(a, b, c)
    batch = G.shape[:-2]
    S = np.zeros(batch + (9, 9))
    for k, cov in enumerate((cov_a, cov_b, cov_c)):
        S[..., 3 * k:3 * k + 3, 3 * k:3 * k + 3] = np.broadcast_to(np.asarray(cov, dtype=float), batch + (3, 3))
    cov_theta = G @ S @ np.swapaxes(G, -1, -2)
    R0 = attitude_from_three_points(a, b, c).R_OS
    E = _euler_jacobian(R0)
    cov_e = E @ cov_theta @ np.swapaxes(E, -1, -2)
    return AttitudeBound(cov_theta, np.sqrt(np.trace(cov_theta, axis1=-2, axis2=-1)), cov_e,
                         np.sqrt(np.diagonal(cov_e, axis1=-2, axis2=-1)))
