"""Sub-pixel centre of one dark dot by a fit of its image model (known radius, plate plane, pixel area).

The contrast-weighted centroid of 000 eqs (9)–(11) (flag P000-5, docs/papers.md#p000-5) is the
centre of the dot's *image*, which is not the image of the dot's centre: a disc seen obliquely
projects to an ellipse whose centre is offset from the projected disc centre (perspective), and the
contrast weights over a dilated support also pick up the plate's brightness gradient.  At 1 m these
offsets are 0.01–0.05 px, 5–25 times the centroid's noise (docs/tof.md, "The Cramér–Rao bound").

This module fits the dot's image instead.  The dot is a disc of known radius ``r`` (m) lying in the
plate plane ``n_S · p_S = h`` (fitted to the range image around it); its centre is parameterised by
the pixel ``(u_c, v_c)`` whose ray meets the plane at the centre, so the fitted ``(u_c, v_c)`` *is*
the projection of the dot's centre (000 eq 2, flag P000-1) and carries no perspective offset.  Each
pixel integrates its area (a box pixel): it is split into ``sub × sub`` cells, and a cell's covered
fraction is the exact coverage of a straight edge crossing its footprint on the plate (the
distribution of a box's projection on the edge normal: the sum of two uniform widths).  Reflectance
multiplies illumination, so the model amplitude of a pixel is

``A(u, v) = B(u, v) · (1 − k · coverage(u, v))``

with the plate's local brightness ``B = (b₀ + b_u Δu + b_v Δv) · g / g₀``, where ``g = cos θ / ρ²`` is the
fall-off of the camera's co-located illumination on the Lambertian plate plane (``g₀`` at the
reference pixel) and the linear term takes what that model leaves, and the contrast
``k = 1 − ρ_dot / ρ_plate``.  The six parameters ``(u_c, v_c, b₀, b_u, b_v, k)`` are fitted
by weighted least squares (``scipy.optimize.least_squares``, residuals divided by the per-pixel
amplitude noise ``σ_A`` of the camera model), which is the maximum-likelihood estimate under the
Gaussian phasor noise of :mod:`vision.tof`; :func:`dot_centre_fisher` gives the Cramér–Rao bound
of the centre from the same model.

Frames: ``S`` camera (OpenCV); pixel centres at integer ``(u, v)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from vision.tof import TofCamera, box_edge_coverage

__all__ = ["DotFit", "dot_model_amplitude", "dot_model_jacobian", "fit_dot", "dot_centre_fisher"]


def _cells(u_px: np.ndarray, v_px: np.ndarray, sub: int) -> tuple[np.ndarray, np.ndarray]:
    off = (np.arange(sub) + 0.5) / sub - 0.5
    du, dv = np.meshgrid(off, off, indexing="xy")
    return u_px[:, None] + du.ravel()[None, :], v_px[:, None] + dv.ravel()[None, :]


def _coverage(uc: float, vc: float, U: np.ndarray, V: np.ndarray, camera: TofCamera, n: np.ndarray, h: float,
              radius_m: float, sub: int) -> np.ndarray:
    """Covered fraction ``(m, sub²)`` of every cell by the disc centred on the plane point seen at ``(uc, vc)``."""
    fx, fy = camera.fx_px, camera.fy_px
    dx, dy = (U - camera.cx_px) / fx, (V - camera.cy_px) / fy              # rays (dx, dy, 1) in S
    nd = n[0] * dx + n[1] * dy + n[2]
    t = h / nd                                                             # z of the cell centre on the plate (m)
    ex, ey = (uc - camera.cx_px) / fx, (vc - camera.cy_px) / fy
    tc = h / (n[0] * ex + n[1] * ey + n[2])
    Dx, Dy, Dz = dx * t - ex * tc, dy * t - ey * tc, t - tc
    dist = np.maximum(np.sqrt(Dx**2 + Dy**2 + Dz**2), 1e-12)
    mx, my, mz = Dx / dist, Dy / dist, Dz / dist                           # in-plane radial direction
    # footprint of a cell (1/sub px) on the plane, along m: m·∂p/∂u = t/f_x (m_x − (m·d) n_x / (n·d))
    md = mx * dx + my * dy + mz
    wu = np.abs(t / fx * (mx - md * n[0] / nd)) / sub
    wv = np.abs(t / fy * (my - md * n[1] / nd)) / sub
    return box_edge_coverage(radius_m - dist, wu, wv)


def _illumination(U: np.ndarray, V: np.ndarray, camera: TofCamera, n: np.ndarray, h: float) -> np.ndarray:
    """``cos θ / ρ²`` of the plate seen along the rays of ``(U, V)``: the fall-off of a co-located source on a
    Lambertian plane (the amplitude model of :meth:`vision.tof.TofCamera.signal_amplitude_dn`)."""
    dx, dy = (U - camera.cx_px) / camera.fx_px, (V - camera.cy_px) / camera.fy_px
    nd = n[0] * dx + n[1] * dy + n[2]
    norm2 = dx**2 + dy**2 + 1.0
    return np.abs(nd) * nd**2 / (h**2 * norm2**1.5)                     # |n·d|/|d| / (h/(n·d))² / |d|²


def dot_model_amplitude(params: np.ndarray, u_px: np.ndarray, v_px: np.ndarray, camera: TofCamera,
                        plane_n_S: np.ndarray, plane_h_m: float, radius_m: float, ref_uv_px: tuple[float, float],
                        sub: int = 4) -> np.ndarray:
    """Model amplitude (DN) of the pixels ``(u_px, v_px)`` for ``params = (u_c, v_c, b₀, b_u, b_v, k)``.

    Parameters
    ----------
    params : (6,) array_like
        Dot centre's pixel (px), plate brightness at ``ref_uv_px`` (DN) and its gradient (DN/px),
        contrast ``k`` (1).
    u_px, v_px : (m,) ndarray
        Pixel centres.
    camera : TofCamera
        Intrinsics (000 eq 2, flag P000-1).
    plane_n_S : (3,) ndarray
        Unit normal of the plate plane in S; ``plane_h_m`` its offset, ``n_S · p_S = h`` (m).
    radius_m : float
        Dot radius (m).
    ref_uv_px : (2,)
        Reference pixel of the brightness gradient.
    sub : int
        Cells per pixel and axis.

    Returns
    -------
    (m,) ndarray
    """
    return dot_model_jacobian(params, u_px, v_px, camera, plane_n_S, plane_h_m, radius_m, ref_uv_px, sub=sub,
                              value_only=True)


def dot_model_jacobian(params: np.ndarray, u_px: np.ndarray, v_px: np.ndarray, camera: TofCamera,
                       plane_n_S: np.ndarray, plane_h_m: float, radius_m: float, ref_uv_px: tuple[float, float],
                       sub: int = 4, step_px: float = 1e-4, value_only: bool = False) -> np.ndarray:
    """``∂A/∂params`` ``(m, 6)`` of :func:`dot_model_amplitude`: central differences (step ``step_px``)
    for the centre, exact for the photometric parameters (the model is linear in ``b₀, b_u, b_v`` and ``k``)."""
    uc, vc, b0, bu, bv, k = (float(p) for p in params)
    n = np.asarray(plane_n_S, dtype=float)
    off = (np.arange(sub) + 0.5) / sub - 0.5
    du, dv = np.meshgrid(off, off, indexing="xy")
    U = np.asarray(u_px, float)[:, None] + du.ravel()[None, :]
    V = np.asarray(v_px, float)[:, None] + dv.ravel()[None, :]
    geo = (U, V, camera, n, float(plane_h_m), float(radius_m), int(sub))
    cover = _coverage(uc, vc, *geo)
    gu, gv = U - ref_uv_px[0], V - ref_uv_px[1]
    shade = _illumination(U, V, camera, n, float(plane_h_m)) / _illumination(
        np.asarray(ref_uv_px[0], float), np.asarray(ref_uv_px[1], float), camera, n, float(plane_h_m))
    B = (b0 + bu * gu + bv * gv) * shade
    if value_only:
        return (B * (1.0 - k * cover)).mean(axis=1)
    dc_du = (_coverage(uc + step_px, vc, *geo) - _coverage(uc - step_px, vc, *geo)) / (2 * step_px)
    dc_dv = (_coverage(uc, vc + step_px, *geo) - _coverage(uc, vc - step_px, *geo)) / (2 * step_px)
    one = (1.0 - k * cover) * shade
    return np.column_stack([(-k * B * dc_du).mean(1), (-k * B * dc_dv).mean(1), one.mean(1), (gu * one).mean(1),
                            (gv * one).mean(1), (-B * cover).mean(1)])


@dataclass(frozen=True)
class DotFit:
    """The fitted dot: centre ``uv_px`` (px), its covariance ``cov_uv_px2`` (px²) and the fit's state.

    ``ok`` is False when the fit did not converge or moved the centre by more than the dot's radius
    from the start (the caller then keeps the centroid).
    """

    uv_px: np.ndarray
    cov_uv_px2: np.ndarray
    params: np.ndarray
    chi2_per_dof: float
    ok: bool


def fit_dot(amplitude_dn: np.ndarray, u_px: np.ndarray, v_px: np.ndarray, camera: TofCamera,
            plane_n_S: np.ndarray, plane_h_m: float, radius_m: float, start_uv_px: tuple[float, float],
            background_dn: float, *, sub: int = 4, ambient_dn: float = 0.0, max_shift_px: float = 2.0) -> DotFit:
    """Weighted least-squares fit of :func:`dot_model_amplitude` to the measured amplitudes of one dot.

    Parameters
    ----------
    amplitude_dn : (m,) ndarray
        Measured amplitudes of the window's pixels ``(u_px, v_px)``.
    camera, plane_n_S, plane_h_m, radius_m, sub
        As in :func:`dot_model_amplitude`.
    start_uv_px : (2,)
        Start of the centre (the contrast-weighted centroid); also the brightness reference pixel.
    background_dn : float
        Start of the plate brightness ``b₀``.
    ambient_dn : float
        Ambient light in the noise model of the weights (:meth:`vision.tof.TofCamera.phasor_sigma_dn`).
    max_shift_px : float
        A fit that moves the centre farther than this from the start is not ``ok``.

    Returns
    -------
    DotFit
        The centre's covariance is ``(JᵀWJ)⁻¹`` of the weighted fit, restricted to ``(u_c, v_c)``.
    """
    a = np.asarray(amplitude_dn, dtype=float)
    w = 1.0 / camera.phasor_sigma_dn(a, ambient_dn)
    ref = (float(start_uv_px[0]), float(start_uv_px[1]))
    args = (u_px, v_px, camera, plane_n_S, plane_h_m, radius_m, ref)
    x0 = np.array([ref[0], ref[1], background_dn, 0.0, 0.0, 0.9])

    def res(p):
        return (dot_model_amplitude(p, *args, sub=sub) - a) * w

    def jac(p):
        return dot_model_jacobian(p, *args, sub=sub) * w[:, None]

    nan2 = np.full(2, np.nan)
    try:
        sol = least_squares(res, x0, jac=jac, method="lm", x_scale=np.array([0.1, 0.1, max(background_dn, 1.0) * 0.01,
                                                                             1.0, 1.0, 0.01]))
    except (ValueError, np.linalg.LinAlgError):
        return DotFit(nan2, np.full((2, 2), np.nan), np.full(6, np.nan), float("nan"), False)
    p = sol.x
    dof = max(len(a) - 6, 1)
    chi2 = float(sol.fun @ sol.fun) / dof
    cov = _centre_covariance(np.asarray(sol.jac))
    ok = bool(sol.success and np.all(np.isfinite(p)) and np.hypot(p[0] - ref[0], p[1] - ref[1]) <= max_shift_px
              and 0.0 < p[5] <= 1.5 and np.all(np.isfinite(cov)) and np.all(np.linalg.eigvalsh(cov) > 0))
    return DotFit(p[:2].copy(), cov, p, chi2, ok)


def _centre_covariance(H: np.ndarray) -> np.ndarray:
    """Centre block ``(2, 2)`` of ``(HᵀH)⁻¹`` (columns equilibrated first); NaN when ``H`` is rank-deficient."""
    scale = np.linalg.norm(H, axis=0)
    if np.any(~np.isfinite(scale)) or np.any(scale <= 0):
        return np.full((2, 2), np.nan)
    Hs = H / scale
    G = Hs.T @ Hs
    if np.linalg.cond(G) > 1e12:
        return np.full((2, 2), np.nan)
    return (np.linalg.inv(G) / np.outer(scale, scale))[:2, :2]


def dot_centre_fisher(u_px: np.ndarray, v_px: np.ndarray, camera: TofCamera, plane_n_S: np.ndarray,
                      plane_h_m: float, radius_m: float, params: np.ndarray, *, sub: int = 4,
                      ambient_dn: float = 0.0) -> np.ndarray:
    """Cramér–Rao bound ``(2, 2)`` (px²) of the dot centre from the pixels ``(u_px, v_px)``.

    ``J = Σ ∂Aᵀ/∂θ σ_A⁻² ∂A/∂θ`` over the six parameters of :func:`dot_model_amplitude` at the
    true ``params``, with ``σ_A`` the camera's phasor noise at the model amplitude; the centre's
    block of ``J⁻¹`` (the photometric parameters are nuisance parameters).
    """
    ref = (float(params[0]), float(params[1]))
    args = (u_px, v_px, camera, plane_n_S, plane_h_m, radius_m, ref)
    A = dot_model_amplitude(params, *args, sub=sub)
    H = dot_model_jacobian(params, *args, sub=sub) / camera.phasor_sigma_dn(A, ambient_dn)[:, None]
    return _centre_covariance(H)
