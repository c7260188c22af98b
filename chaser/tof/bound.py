"""Cramér–Rao bound of the TOF marker pose (paper 000), from the key points' pixel and range noise.

Measurement model (000 eqs 1, 2, 5, flag P000-1): marker ``i`` at ``p_i = R_SC q_i + r_CS_S`` in
the camera frame S is measured as its pixel centroid and radial range,

``z_i = (u_i, v_i, ρ_i) = (f_x x/z + c_x, f_y y/z + c_y, |p_i|) + ν_i``,  ``ν_i ~ N(0, diag(σ_u², σ_u², σ_ρ,i²))``.

The pose perturbation is ``x = (δθ_S, δr_S)`` with ``R = exp([δθ]×) R̂`` (rotation vector in S, rad)
and ``r = r̂ + δr`` (m), so ``∂p_i/∂x = [−[R q_i]×, I₃]``.  The Fisher information is
``J = Σ_i H_iᵀ R_i⁻¹ H_i`` with ``H_i = ∂z_i/∂p_i · ∂p_i/∂x``, and the bound on any unbiased pose
estimate is ``P ≥ J⁻¹``: ``σ_θ = sqrt(tr P_θθ)`` bounds the RMS rotation angle of the attitude error
and ``σ_r = sqrt(tr P_rr)`` the RMS position error of the plate origin.

:func:`sr4000_marker_noise` predicts ``σ_u`` and ``σ_ρ,i`` of the pipeline's key points from the
SR4000 model of :mod:`vision.tof` (phasor noise ``σ² = κ (A + B) + σ_read²``, range noise
``c/(4π f_mod) σ / A``): the plate-plane range of :func:`chaser.tof.extract_markers` averages
the ``N`` plate pixels of the ring around the dot (``σ_ρ = σ_pixel / √N``, intercept of a plane
fitted on a support centred on the dot), and the dot centre's ``σ_u`` is the Cramér–Rao bound of
the centre from the amplitudes of the pixels around the dot (:func:`chaser.tof.dotfit.dot_centre_fisher`),
which the dot-model fit reaches; for the contrast-weighted centroid (eqs 9–11, flag P000-5) it is
``σ_A sqrt(Σ x²) / Σ w`` over its support.  The pose bound is therefore the bound of a pose from the
key points, each measured as well as its own pixels allow.

Frames: ``S`` camera (OpenCV), ``C`` marker plate; ``p_S = R_SC q_C + r_CS_S`` (000 eq 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from chaser.tof.dotfit import dot_centre_fisher
from vision.tof import MarkerPlate, TofCamera

__all__ = ["TofPoseBound", "tof_pose_bound", "measurement_model", "ml_pose_refinement", "sr4000_marker_noise", "MarkerNoise"]


@dataclass(frozen=True)
class TofPoseBound:
    """The Cramér–Rao bound of one marker-plate pose.

    Attributes
    ----------
    fisher : (6, 6) ndarray
        ``J = Σ Hᵀ R⁻¹ H`` over ``x = (δθ_S [rad], δr_S [m])``.
    covariance : (6, 6) ndarray
        ``J⁻¹`` (NaN when ``J`` is singular: fewer than three non-collinear markers).
    attitude_sigma_rad : float
        ``sqrt(tr P_θθ)``: bound on the RMS rotation angle of the attitude error.
    position_sigma_m : float
        ``sqrt(tr P_rr)``: bound on the RMS position error of the plate origin ``r_CS_S``.
    """

    fisher: np.ndarray
    covariance: np.ndarray
    attitude_sigma_rad: float
    position_sigma_m: float

    @property
    def attitude_sigma_deg(self) -> float:
        """``attitude_sigma_rad`` in degrees."""
        return float(np.degrees(self.attitude_sigma_rad))


def _skew(v: np.ndarray) -> np.ndarray:
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    o = np.zeros_like(x)
    return np.stack([np.stack([o, -z, y], -1), np.stack([z, o, -x], -1), np.stack([-y, x, o], -1)], -2)


def tof_pose_bound(R_SC: ArrayLike, r_CS_S: ArrayLike, q_C: ArrayLike, camera: TofCamera,
                   sigma_px: ArrayLike, sigma_range_m: ArrayLike) -> TofPoseBound:
    """Cramér–Rao bound of the rigid pose from per-marker pixel and range measurements.

    Parameters
    ----------
    R_SC : (3, 3) array_like
        True rotation C → S.
    r_CS_S : (3,) array_like
        True plate origin in S (m).
    q_C : (n, 3) array_like
        Model markers in C (m) that are measured.
    camera : TofCamera
        Intrinsics of the projection (000 eq 2, flag P000-1).
    sigma_px : float or (n,) array_like
        Pixel noise (1σ) of each key point's ``u`` and ``v`` (px).
    sigma_range_m : float or (n,) array_like
        Radial-range noise (1σ) of each key point (m).

    Returns
    -------
    TofPoseBound
    """
    R = np.asarray(R_SC, dtype=float)
    r = np.asarray(r_CS_S, dtype=float)
    q = np.asarray(q_C, dtype=float)
    if R.shape != (3, 3) or r.shape != (3,) or q.ndim != 2 or q.shape[1] != 3:
        raise ValueError(f"R_SC, r_CS_S, q_C: expected (3, 3), (3,), (n, 3), got {R.shape}, {r.shape}, {q.shape}")
    n = len(q)
    s_px = np.broadcast_to(np.asarray(sigma_px, dtype=float), (n,))
    s_rho = np.broadcast_to(np.asarray(sigma_range_m, dtype=float), (n,))
    if np.any(~np.isfinite(s_px) | (s_px <= 0)) or np.any(~np.isfinite(s_rho) | (s_rho <= 0)):
        raise ValueError("sigma_px, sigma_range_m: must be finite and > 0")
    if np.any((q @ R.T + r)[:, 2] <= 0):
        raise ValueError("R_SC, r_CS_S: a marker lies behind the camera")
    _, H = measurement_model(R, r, q, camera)
    w = 1.0 / np.stack([s_px**2, s_px**2, s_rho**2], axis=1)                              # R_i⁻¹ diagonal
    J = np.einsum("nki,nk,nkj->ij", H, w, H)
    try:
        if np.linalg.cond(J) > 1e14:
            raise np.linalg.LinAlgError
        P = np.linalg.inv(J)
    except np.linalg.LinAlgError:
        P = np.full((6, 6), np.nan)
    return TofPoseBound(J, P, float(np.sqrt(np.trace(P[:3, :3]))), float(np.sqrt(np.trace(P[3:, 3:]))))


def measurement_model(R_SC: np.ndarray, r_CS_S: np.ndarray, q_C: np.ndarray,
                      camera: TofCamera) -> tuple[np.ndarray, np.ndarray]:
    """Predicted ``z_i = (u_i, v_i, ρ_i)`` ``(n, 3)`` and the Jacobian ``H_i = ∂z_i/∂x`` ``(n, 3, 6)``.

    ``x = (δθ_S, δr_S)`` with ``R = exp([δθ]×) R_SC``: ``∂p_i/∂x = [−[R q_i]×, I₃]``; 000 eq (2)
    (flag P000-1) for ``u, v`` and the radial range ``ρ = |p|`` of eq (5).
    """
    Rq = q_C @ R_SC.T
    p = Rq + r_CS_S
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    rho = np.linalg.norm(p, axis=1)
    n = len(p)
    dz = np.zeros((n, 3, 3))
    dz[:, 0, 0] = camera.fx_px / z
    dz[:, 0, 2] = -camera.fx_px * x / z**2
    dz[:, 1, 1] = camera.fy_px / z
    dz[:, 1, 2] = -camera.fy_px * y / z**2
    dz[:, 2, :] = p / rho[:, None]
    dp = np.concatenate([-_skew(Rq), np.broadcast_to(np.eye(3), (n, 3, 3))], axis=2)   # (n, 3, 6)
    zhat = np.column_stack([camera.fx_px * x / z + camera.cx_px, camera.fy_px * y / z + camera.cy_px, rho])
    return zhat, dz @ dp


def ml_pose_refinement(R_SC: ArrayLike, r_CS_S: ArrayLike, q_C: ArrayLike, uv_px: ArrayLike, range_m: ArrayLike,
                       camera: TofCamera, sigma_px: ArrayLike, sigma_range_m: ArrayLike, *,
                       iterations: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Maximum-likelihood pose from the key points' pixels and ranges (Gauss–Newton), from a start pose.

    Minimises ``Σ_i (z_i − ẑ_i)ᵀ R_i⁻¹ (z_i − ẑ_i)`` over the measurement model of
    :func:`tof_pose_bound` (``R_i = diag(σ_u², σ_u², σ_ρ²)``), the estimator whose covariance reaches
    ``J⁻¹`` at high signal-to-noise.  The weighted SVD of 000 eqs (27)–(38) weighs each 3-D point
    isotropically by its range noise, so it cannot use the pixel coordinates, which on the SR4000
    model are about 20 times more precise laterally than the range; started from it, a few
    Gauss–Newton steps reach the ML pose.

    Parameters
    ----------
    R_SC, r_CS_S : start pose (the weighted SVD's).
    q_C : (n, 3) matched model markers (m).
    uv_px : (n, 2) key-point centroids (px); range_m : (n,) key-point ranges (m).
    camera : TofCamera
    sigma_px, sigma_range_m : (n,) or scalar standard errors.
    iterations : int

    Returns
    -------
    (R_SC (3, 3), r_CS_S (3,))
    """
    R = np.asarray(R_SC, dtype=float).copy()
    r = np.asarray(r_CS_S, dtype=float).copy()
    q = np.asarray(q_C, dtype=float)
    z = np.column_stack([np.asarray(uv_px, dtype=float), np.asarray(range_m, dtype=float)])
    n = len(q)
    w = 1.0 / np.stack([np.broadcast_to(np.asarray(sigma_px, float), (n,)) ** 2,
                        np.broadcast_to(np.asarray(sigma_px, float), (n,)) ** 2,
                        np.broadcast_to(np.asarray(sigma_range_m, float), (n,)) ** 2], axis=1)
    for _ in range(int(iterations)):
        zhat, H = measurement_model(R, r, q, camera)
        res = z - zhat
        J = np.einsum("nki,nk,nkj->ij", H, w, H)
        g = np.einsum("nki,nk,nk->i", H, w, res)
        dx = np.linalg.solve(J, g)
        th = np.linalg.norm(dx[:3])
        K = _skew(dx[:3] / th) if th > 0 else np.zeros((3, 3))
        R = (np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K) @ R
        r = r + dx[3:]
        if th < 1e-12 and np.linalg.norm(dx[3:]) < 1e-12:
            break
    return R, r


@dataclass(frozen=True)
class MarkerNoise:
    """Predicted noise of the key points of one frame (per model marker).

    Attributes
    ----------
    sigma_px : (n,) ndarray
        Centroid noise per image axis (px).
    sigma_range_m : (n,) ndarray
        Plate-plane range noise (m).
    dot_radius_px : (n,) ndarray
        Face-on dot radius ``r f / ρ`` (px).
    foreshortening : (n,) ndarray
        ``cos`` of the viewing angle of the plate at the marker (the dot's minor/major axis ratio).
    """

    sigma_px: np.ndarray
    sigma_range_m: np.ndarray
    dot_radius_px: np.ndarray
    foreshortening: np.ndarray


def sr4000_marker_noise(camera: TofCamera, plate: MarkerPlate, R_SC: ArrayLike, r_CS_S: ArrayLike, *,
                        ambient_dn: float = 0.0, plane_support_factor: float = 3.0,
                        centroid_dilate_px: int = 2, centre_estimator: str = "fit",
                        fit_margin_px: float = 2.5, fit_cells: int = 4) -> MarkerNoise:
    """Pixel and range noise of the pipeline's key points, from the TOF camera's noise model.

    For marker ``i`` at range ``ρ`` seen at angle ``θ`` to the plate normal (``c = cos θ``): plate and
    dot amplitudes ``A_p``, ``A_d`` (:meth:`vision.tof.TofCamera.signal_amplitude_dn`), phasor noise
    ``σ_A`` and per-pixel range noise ``σ_pix`` of the plate (:meth:`~vision.tof.TofCamera.range_sigma_m`).
    The dot is an ellipse of semi-axes ``r_px = r f / ρ`` and ``c r_px``.

    * range (plate plane, :func:`chaser.tof.extract_markers` with ``range_estimator="plane"``): the
      ``N = π (k r_px)² − π (r_px + d + 1)(c r_px + d + 1)`` plate pixels within ``k = plane_support_factor``
      dot radii, outside the dot dilated by ``d + 1`` px; ``σ_ρ = σ_pix / √N`` (the intercept of a
      plane fitted on a support centred on the key point);
    * centre, ``centre_estimator="fit"`` (default): the Cramér–Rao bound of the dot centre from the
      amplitudes of the pixels within ``r_px + fit_margin_px`` of it
      (:func:`chaser.tof.dotfit.dot_centre_fisher`: the dot's image model at the true pose, the
      plate's brightness and the contrast as nuisance parameters), ``σ_u = sqrt(tr Σ_uv / 2)``;
    * centre, ``"centroid"`` (eqs 9–11 with flag P000-5): weights ``w = A_p − A`` over the dot dilated
      by ``d``, ``Σ w = (A_p − A_d) π c r_px²``, ``σ_u = σ_A sqrt(Σ x²) / Σ w`` with
      ``Σ x² = π a³ b / 4`` over the support ellipse ``a = r_px + d``, ``b = c r_px + d``.

    Parameters
    ----------
    camera : TofCamera
    plate : MarkerPlate
    R_SC : (3, 3) array_like
    r_CS_S : (3,) array_like
        True pose (m).
    ambient_dn : float
        Ambient light (DN).
    plane_support_factor, centroid_dilate_px, centre_estimator, fit_margin_px, fit_cells
        As in :class:`chaser.tof.ExtractionSettings`.

    Returns
    -------
    MarkerNoise
    """
    if centre_estimator not in ("fit", "centroid"):
        raise ValueError(f"centre_estimator: must be 'fit' or 'centroid', got {centre_estimator!r}")
    R = np.asarray(R_SC, dtype=float)
    r_CS = np.asarray(r_CS_S, dtype=float)
    p = plate.markers_C @ R.T + r_CS
    rho = np.linalg.norm(p, axis=1)
    e = p / rho[:, None]
    c = np.clip(np.abs(e @ R[:, 2]), 1e-3, 1.0)
    f = 0.5 * (camera.fx_px + camera.fy_px)
    r_px = plate.marker_radius_m * f / rho
    a_p = camera.signal_amplitude_dn(plate.plate_reflectivity, rho, c)
    a_d = camera.signal_amplitude_dn(plate.marker_reflectivity, rho, c)
    d = int(centroid_dilate_px)
    n_ring = np.maximum(np.pi * (plane_support_factor * r_px) ** 2 - np.pi * (r_px + d + 1) * (c * r_px + d + 1), 8.0)
    sigma_rho = camera.range_sigma_m(a_p, ambient_dn) / np.sqrt(n_ring)
    if centre_estimator == "centroid":
        ax, bx = r_px + d, c * r_px + d
        sum_x2 = np.pi * ax**3 * bx / 4.0
        sum_w = (a_p - a_d) * np.pi * c * r_px**2
        sigma_px = camera.phasor_sigma_dn(a_p, ambient_dn) * np.sqrt(sum_x2) / sum_w
        return MarkerNoise(sigma_px, sigma_rho, r_px, c)
    uv = np.column_stack([camera.fx_px * p[:, 0] / p[:, 2] + camera.cx_px, camera.fy_px * p[:, 1] / p[:, 2] + camera.cy_px])
    n_S, h_m = R[:, 2], float(R[:, 2] @ r_CS)
    sigma_px = np.empty(len(p))
    for i in range(len(p)):
        rad = r_px[i] + fit_margin_px
        gv, gu = np.mgrid[int(np.floor(uv[i, 1] - rad)):int(np.ceil(uv[i, 1] + rad)) + 1,
                          int(np.floor(uv[i, 0] - rad)):int(np.ceil(uv[i, 0] + rad)) + 1]
        win = np.hypot(gu - uv[i, 0], gv - uv[i, 1]) <= rad
        params = np.array([uv[i, 0], uv[i, 1], a_p[i], 0.0, 0.0, 1.0 - plate.marker_reflectivity / plate.plate_reflectivity])
        P = dot_centre_fisher(gu[win].astype(float), gv[win].astype(float), camera, n_S, h_m, plate.marker_radius_m,
                              params, sub=fit_cells, ambient_dn=ambient_dn)
        sigma_px[i] = np.sqrt(np.trace(P) / 2.0)
    return MarkerNoise(sigma_px, sigma_rho, r_px, c)
