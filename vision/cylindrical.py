"""Orthogonal cylindrical-imaging camera with two linear CCDs (paper 004 §2.1, eq 1–4).

Each camera replaces an area sensor by two channels behind a beam splitter: a cylindrical lens
whose power lies in the horizontal plane focuses a point source into a *vertical line* that crosses
the horizontal linear CCD (CCD1) at a position ``u`` that depends on the horizontal angle α; the
orthogonal channel (CCD2) gives ``v`` from the vertical angle β.  In the camera frame ``C``
(OpenCV convention: ``z`` along the boresight, ``x`` right, ``y`` down), 004 eq (1)–(2) read

.. math:: \\tan\\alpha = x_C / z_C, \\qquad \\tan\\beta = y_C / z_C .

This module is the *sensor*: the true mapping from angles to spot centres (with a realistic,
non-separable lens distortion that the user of the camera does not know; the calibration of
``chaser.cylindrical`` has to learn it), the 1-D line signals (pixel-integrated Gaussian spots,
background, shot and read noise, quantisation, saturation) and spot detection on one line signal
(grey-threshold centroid of 004 §3.2 step 4, or a three-point Gaussian fit), with sub-pixel results.

Pixel convention: pixel ``i`` covers ``[i − ½, i + ½)``; coordinates are in pixels with 0 at the
centre of the first pixel.

Distortion model (simulation truth).  With ``a = tan α`` and ``b = tan β`` and ``F = f / pitch``,

.. math::
    u = u_0 + F\\,[a (1 + k_1 a^2 + k_2 a^4 + c\\,b^2) + \\tau\\, b], \\qquad
    v = v_0 + F\\,[b (1 + k'_1 b^2 + k'_2 b^4 + c'\\,a^2) + \\tau'\\, a].

``k`` are the radial terms of each cylindrical lens, ``c`` the bow of the line image of an off-plane
source (a skew ray crosses the cylinder on a longer path), ``τ`` the tilt of the line image
relative to the CCD normal (mounting error).  With the defaults the distortion reaches ≈ 20 px at the
edge of the field and couples the channels, which is why 004 calibrates non-parametrically.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.signal import find_peaks
from scipy.special import erf

__all__ = [
    "CylindricalCamera",
    "LineSpots",
    "angles_from_points",
    "render_line_signals",
    "measure_spot_centres",
    "detect_spots",
    "brightest_spot_centres",
    "SPOT_METHODS",
]

#: Sub-pixel spot-centre estimators: 004's grey-threshold centroid, and a three-point Gaussian fit.
SPOT_METHODS = ("threshold_centroid", "gaussian3")


def _pair(value, name: str) -> tuple[float, float]:
    arr = np.asarray(value, dtype=float)
    if arr.shape != (2,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: expected two finite numbers (CCD1, CCD2), got {value!r}")
    return float(arr[0]), float(arr[1])


@dataclass(frozen=True)
class CylindricalCamera:
    """Hardware of one orthogonal cylindrical-imaging camera (two linear CCDs).

    The values that are pairs are ``(CCD1 = horizontal channel u/α, CCD2 = vertical channel v/β)``.
    None of them is given in 004; the defaults are our choice of a typical linear CCD (5000–8000
    pixels, 7 µm pitch, ±15° field at f = 100 mm).

    Attributes
    ----------
    n_pixels : int
        Pixels per linear CCD.
    pixel_pitch_m : float
        Pixel pitch (m).
    focal_length_m : float
        Focal length of both cylindrical lenses (m).
    principal_px : (2,) float
        Where the optical axis meets each CCD (px).
    k1, k2 : (2,) float
        Radial distortion of each lens (dimensionless, in powers of tan).
    bow : (2,) float
        Coupling of the other angle (``c`` and ``c'`` above).
    line_tilt_rad : (2,) float
        Tilt of the line image relative to the CCD normal (``τ``, ``τ'``).
    spot_sigma_px : float
        Gaussian width (standard deviation) of the line image across the CCD (px).
    peak_dn : float
        Peak of the continuous spot profile above the background (DN).
    background_dn : float
        Dark/background level (DN).
    read_noise_dn : float
        Read noise standard deviation per pixel and scan (DN).
    electrons_per_dn : float
        Conversion gain; shot noise has variance ``signal_dn / electrons_per_dn`` (DN²).
    bits : int
        ADC resolution; signals saturate at ``2**bits − 1``.
    """

    n_pixels: int = 8000
    pixel_pitch_m: float = 7.0e-6
    focal_length_m: float = 0.100
    principal_px: tuple[float, float] = (4003.7, 3996.2)
    k1: tuple[float, float] = (-0.060, 0.045)
    k2: tuple[float, float] = (0.020, -0.010)
    bow: tuple[float, float] = (0.030, -0.025)
    line_tilt_rad: tuple[float, float] = (2.0e-3, -1.5e-3)
    spot_sigma_px: float = 2.5
    peak_dn: float = 3000.0
    background_dn: float = 100.0
    read_noise_dn: float = 4.0
    electrons_per_dn: float = 4.0
    bits: int = 12

    def __post_init__(self) -> None:
        if int(self.n_pixels) != self.n_pixels or self.n_pixels < 64:
            raise ValueError(f"n_pixels: need an integer >= 64, got {self.n_pixels!r}")
        for name in ("pixel_pitch_m", "focal_length_m", "spot_sigma_px", "peak_dn", "electrons_per_dn"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name}: must be a positive finite number, got {v!r}")
        for name in ("background_dn", "read_noise_dn"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"{name}: must be >= 0, got {v!r}")
        if int(self.bits) != self.bits or not 8 <= self.bits <= 16:
            raise ValueError(f"bits: ADC resolution must be an integer in [8, 16], got {self.bits!r}")
        if self.background_dn + self.peak_dn >= 2**self.bits - 1:
            raise ValueError(
                f"peak_dn: background + peak ({self.background_dn + self.peak_dn}) saturates a "
                f"{self.bits}-bit ADC"
            )
        for name in ("principal_px", "k1", "k2", "bow", "line_tilt_rad"):
            object.__setattr__(self, name, _pair(getattr(self, name), name))

    @property
    def focal_px(self) -> float:
        """Focal length in pixels, ``F = f / pitch``."""
        return self.focal_length_m / self.pixel_pitch_m

    @property
    def saturation_dn(self) -> float:
        return float(2**self.bits - 1)

    @property
    def margin_px(self) -> float:
        """Spots closer than this to either end of a CCD are not fully imaged (4 σ)."""
        return 4.0 * self.spot_sigma_px

    def pixels_from_angles(self, alpha_beta_rad: ArrayLike) -> np.ndarray:
        """True spot centres ``(u, v)`` in pixels of sources at angles ``(α, β)`` (distorted).

        Parameters
        ----------
        alpha_beta_rad : (..., 2) array
            Horizontal and vertical angles (rad), 004 eq (1)–(2).

        Returns
        -------
        (..., 2) ndarray
            ``u`` on CCD1 and ``v`` on CCD2 (px); NaN where the source lies outside the CCD (with
            the 4σ margin) or the angles are NaN.
        """
        ab = np.asarray(alpha_beta_rad, dtype=float)
        if ab.ndim == 0 or ab.shape[-1] != 2:
            raise ValueError(f"alpha_beta_rad: expected shape (..., 2), got {ab.shape}")
        with np.errstate(invalid="ignore"):
            a = np.tan(ab[..., 0])
            b = np.tan(ab[..., 1])
            F = self.focal_px
            u = self.principal_px[0] + F * (
                a * (1.0 + self.k1[0] * a**2 + self.k2[0] * a**4 + self.bow[0] * b**2) + self.line_tilt_rad[0] * b
            )
            v = self.principal_px[1] + F * (
                b * (1.0 + self.k1[1] * b**2 + self.k2[1] * b**4 + self.bow[1] * a**2) + self.line_tilt_rad[1] * a
            )
            uv = np.stack([u, v], -1)
            m = self.margin_px
            inside = (uv >= m) & (uv <= self.n_pixels - 1 - m)
        inside = inside[..., 0] & inside[..., 1] & (np.abs(ab[..., 0]) < np.pi / 2) & (np.abs(ab[..., 1]) < np.pi / 2)
        return np.where(inside[..., None], uv, np.nan)

    def half_field_rad(self) -> tuple[float, float]:
        """Approximate half field of view ``(α_max, β_max)`` (rad), from the undistorted model."""
        half = (self.n_pixels - 1) / 2.0 - self.margin_px
        t = half / self.focal_px
        return float(np.arctan(t)), float(np.arctan(t))


def angles_from_points(X_C: ArrayLike) -> np.ndarray:
    """004 eq (1)–(2): ``α = atan2(x, z)``, ``β = atan2(y, z)`` of points in the camera frame.

    Parameters
    ----------
    X_C : (..., 3) array
        Points in camera-frame components (m), ``z`` along the boresight.

    Returns
    -------
    (..., 2) ndarray
        ``(α, β)`` in rad; NaN for points on or behind the lens plane (``z <= 0``).
    """
    X = np.asarray(X_C, dtype=float)
    if X.ndim == 0 or X.shape[-1] != 3:
        raise ValueError(f"X_C: expected shape (..., 3), got {X.shape}")
    ab = np.stack([np.arctan2(X[..., 0], X[..., 2]), np.arctan2(X[..., 1], X[..., 2])], -1)
    return np.where((X[..., 2] > 0)[..., None], ab, np.nan)


def render_line_signals(
    camera: CylindricalCamera,
    uv_px: ArrayLike,
    *,
    rng: np.random.Generator | int | None = None,
    brightness: ArrayLike | None = None,
    n_scans: int = 1,
    roi_start_px: ArrayLike | None = None,
    roi_length_px: int | None = None,
) -> np.ndarray:
    """Line signals of both CCDs for sources whose spot centres are ``uv_px``.

    Each source adds a pixel-integrated Gaussian of width ``camera.spot_sigma_px`` to CCD1 at ``u``
    and to CCD2 at ``v``.  Noise: shot noise (variance ``signal / electrons_per_dn``) and read noise,
    both Gaussian; one scan is quantised to integers and clipped at saturation.  ``n_scans > 1``
    models a static source averaged over that many line scans: the noise variance, including
    the quantisation variance 1/12 DN², is divided by ``n_scans`` and the result is not rounded.

    Parameters
    ----------
    camera : CylindricalCamera
    uv_px : (..., M, 2) array
        Spot centres of ``M`` sources (px); rows with NaN are sources that are off or outside.
    rng : Generator, int or None
    brightness : (..., M) array, optional
        Relative brightness of each source (1 = ``camera.peak_dn``).
    n_scans : int
        Number of line scans averaged.
    roi_start_px, roi_length_px : (..., 2) int array and int, optional
        Read out only pixels ``roi_start + [0, roi_length)`` of each CCD (a region of interest, as
        linear-CCD systems do for a tracked source); default: the whole line.

    Returns
    -------
    (..., 2, L) ndarray
        Signals in DN (``L = n_pixels`` or ``roi_length_px``): index 0 is CCD1 (u), 1 is CCD2 (v).
    """
    rng = np.random.default_rng(rng)
    uv = np.asarray(uv_px, dtype=float)
    if uv.ndim < 2 or uv.shape[-1] != 2:
        raise ValueError(f"uv_px: expected shape (..., M, 2), got {uv.shape}")
    if int(n_scans) != n_scans or n_scans < 1:
        raise ValueError(f"n_scans: must be a positive integer, got {n_scans!r}")
    batch = uv.shape[:-2]
    M = uv.shape[-2]
    if brightness is None:
        bright = np.ones(batch + (M,))
    else:
        bright = np.broadcast_to(np.asarray(brightness, dtype=float), batch + (M,))
        if np.any(bright < 0) or not np.all(np.isfinite(bright)):
            raise ValueError("brightness: must be finite and >= 0")
    flat_uv = uv.reshape(-1, M, 2)
    flat_b = bright.reshape(-1, M)
    B = flat_uv.shape[0]
    if roi_start_px is None:
        L = camera.n_pixels
        start = np.zeros((B, 2), dtype=int)
    else:
        if roi_length_px is None or int(roi_length_px) != roi_length_px or roi_length_px < 8:
            raise ValueError(f"roi_length_px: need an integer >= 8 with roi_start_px, got {roi_length_px!r}")
        L = int(roi_length_px)
        start = np.broadcast_to(np.asarray(roi_start_px), batch + (2,)).reshape(B, 2).astype(int)
    w = camera.spot_sigma_px
    half = int(np.ceil(8 * w)) + 1
    offs = np.arange(-half, half + 1)
    signal = np.full((B, 2, L), camera.background_dn)
    on = np.isfinite(flat_uv).all(-1)
    centre = np.where(on[..., None], flat_uv, 0.0)
    idx = np.floor(centre + 0.5).astype(int)[..., None] + offs  # (B, M, 2, W) absolute pixel index
    s2 = np.sqrt(2.0) * w
    total = camera.peak_dn * w * np.sqrt(2.0 * np.pi)
    prof = 0.5 * (erf((idx + 0.5 - centre[..., None]) / s2) - erf((idx - 0.5 - centre[..., None]) / s2))
    prof = prof * (total * flat_b * on)[..., None, None]
    local = idx - start[:, None, :, None]
    valid = (idx >= 0) & (idx < camera.n_pixels) & (local >= 0) & (local < L)
    bb = np.broadcast_to(np.arange(B)[:, None, None, None], idx.shape)
    cc = np.broadcast_to(np.arange(2)[None, None, :, None], idx.shape)
    np.add.at(signal, (bb[valid], cc[valid], local[valid]), prof[valid])
    var = camera.read_noise_dn**2 + signal / camera.electrons_per_dn
    noise = rng.standard_normal(signal.shape)
    if n_scans == 1:
        noisy = np.rint(signal + noise * np.sqrt(var))
    else:
        noisy = signal + noise * np.sqrt((var + 1.0 / 12.0) / n_scans)
    np.clip(noisy, 0.0, camera.saturation_dn, out=noisy)
    return noisy.reshape(batch + (2, L))


def measure_spot_centres(
    camera: CylindricalCamera,
    uv_px: ArrayLike,
    *,
    rng: np.random.Generator | int | None = None,
    n_scans: int = 1,
    method: str = "threshold_centroid",
    threshold_fraction: float = 0.5,
    roi_length_px: int = 96,
) -> np.ndarray:
    """Measured spot centres of single lit sources: render a region of interest, detect, refine.

    One source is lit per item (calibration samples, control points, sequential lighting); its
    signals are read in a region of interest of ``roi_length_px`` pixels placed at a random offset
    around the spot, and the brightest spot is refined with ``method``
    (:func:`brightest_spot_centres`).

    Parameters
    ----------
    camera : CylindricalCamera
    uv_px : (..., 2) array
        True spot centres (px), e.g. from :meth:`CylindricalCamera.pixels_from_angles`.
    rng, n_scans, method, threshold_fraction, roi_length_px
        See :func:`render_line_signals` and :func:`detect_spots`.

    Returns
    -------
    (..., 2) ndarray
        Measured ``(u, v)`` (px); NaN where the source is outside the field or not detected.
    """
    rng = np.random.default_rng(rng)
    uv = np.asarray(uv_px, dtype=float)
    if uv.ndim == 0 or uv.shape[-1] != 2:
        raise ValueError(f"uv_px: expected shape (..., 2), got {uv.shape}")
    L = int(roi_length_px)
    if L < 32:
        raise ValueError(f"roi_length_px: need >= 32 pixels, got {roi_length_px!r}")
    ok = np.isfinite(uv).all(-1)
    safe = np.where(ok[..., None], uv, camera.n_pixels / 2.0)
    jitter = rng.integers(-L // 4, L // 4 + 1, size=uv.shape)
    start = np.clip(np.floor(safe).astype(int) - L // 2 + jitter, 0, camera.n_pixels - L)
    sig = render_line_signals(camera, np.where(ok[..., None], uv, np.nan)[..., None, :], rng=rng,
                              n_scans=n_scans, roi_start_px=start, roi_length_px=L)
    c = brightest_spot_centres(sig, method=method, threshold_fraction=threshold_fraction)
    out = c + start
    return np.where(ok[..., None], out, np.nan)


@dataclass(frozen=True)
class LineSpots:
    """Spots found on one line signal.

    Attributes
    ----------
    position_px : (K,) ndarray
        Sub-pixel spot centres (px), increasing.
    peak_dn : (K,) ndarray
        Peak height above the background (DN).
    fwhm_px : (K,) ndarray
        Full width at half maximum (px); a value well above the camera's nominal
        ``2.355 spot_sigma_px`` marks spots that have merged.
    background_dn : float
        Background level estimated from the signal (median).
    noise_dn : float
        Noise level estimated from the signal (scaled median absolute deviation).
    """

    position_px: np.ndarray
    peak_dn: np.ndarray
    fwhm_px: np.ndarray
    background_dn: float
    noise_dn: float

    def __len__(self) -> int:
        return int(self.position_px.shape[0])


def _refine(signal: np.ndarray, peak_idx: np.ndarray, bg: np.ndarray, *, method: str,
            threshold_fraction: float, half_window: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sub-pixel centre, height and FWHM of spots at integer peaks (vectorised).

    ``signal`` (B, n), ``peak_idx`` (B, K) int, ``bg`` (B,) → three (B, K) arrays.
    """
    n = signal.shape[-1]
    offs = np.arange(-half_window, half_window + 1)
    idx = np.clip(peak_idx[..., None] + offs, 0, n - 1)  # (B, K, W)
    win = np.take_along_axis(signal[:, None, :], idx, axis=-1) - bg[:, None, None]
    peak = win[..., half_window]
    thr = threshold_fraction * peak
    above = win > thr[..., None]
    # keep only the run of pixels above threshold that contains the peak
    right = np.cumprod(above[..., half_window:], axis=-1).astype(bool)
    left = np.cumprod(above[..., : half_window + 1][..., ::-1], axis=-1).astype(bool)[..., ::-1]
    run = np.concatenate([left[..., :-1], right], axis=-1)
    if method == "threshold_centroid":
        wgt = np.where(run, win - thr[..., None], 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            centre = peak_idx + np.sum(wgt * offs, -1) / np.sum(wgt, -1)
    else:
        with np.errstate(invalid="ignore", divide="ignore"):
            lm = np.log(np.maximum(win[..., half_window - 1], 1e-9))
            l0 = np.log(np.maximum(peak, 1e-9))
            lp = np.log(np.maximum(win[..., half_window + 1], 1e-9))
            den = lm - 2.0 * l0 + lp
            delta = np.where(den < 0, 0.5 * (lm - lp) / den, 0.0)
            centre = peak_idx + np.clip(delta, -0.5, 0.5)
    # FWHM from linear interpolation of the half-maximum crossings at the ends of the run
    half = 0.5 * peak
    above_h = win > half[..., None]
    r_h = np.cumprod(above_h[..., half_window:], axis=-1)
    l_h = np.cumprod(above_h[..., : half_window + 1][..., ::-1], axis=-1)
    nr = np.sum(r_h, -1) - 1  # last index (from centre) still above half
    nl = np.sum(l_h, -1) - 1
    nr_c = np.clip(nr, 0, half_window - 1)
    nl_c = np.clip(nl, 0, half_window - 1)
    in_r = np.take_along_axis(win, (half_window + nr_c)[..., None], -1)[..., 0]
    out_r = np.take_along_axis(win, (half_window + nr_c + 1)[..., None], -1)[..., 0]
    in_l = np.take_along_axis(win, (half_window - nl_c)[..., None], -1)[..., 0]
    out_l = np.take_along_axis(win, (half_window - nl_c - 1)[..., None], -1)[..., 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        fr = nr_c + (in_r - half) / (in_r - out_r)
        fl = nl_c + (in_l - half) / (in_l - out_l)
    fwhm = fr + fl
    return centre, peak, fwhm


def _check_method(method: str, threshold_fraction: float) -> None:
    if method not in SPOT_METHODS:
        raise ValueError(f"method: spot estimator must be one of {SPOT_METHODS}, got {method!r}")
    if not 0.0 < threshold_fraction < 1.0:
        raise ValueError(f"threshold_fraction: must be in (0, 1), got {threshold_fraction!r}")


def _background(signal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    bg = np.median(signal, axis=-1)
    mad = np.median(np.abs(signal - bg[..., None]), axis=-1)
    return bg, np.maximum(1.4826 * mad, 0.5)


def detect_spots(
    signal: ArrayLike,
    *,
    method: str = "threshold_centroid",
    threshold_fraction: float = 0.5,
    min_snr: float = 8.0,
    min_separation_px: float = 3.0,
    half_window_px: int = 12,
) -> LineSpots:
    """Find the spots on one linear-CCD signal, with sub-pixel centres (004 §3.2 step 4).

    Peaks are local maxima more than ``min_snr`` noise levels above the background (median of the
    line; noise from its median absolute deviation) and at least ``min_separation_px`` apart.
    Each peak is refined:

    * ``"threshold_centroid"`` (004): centroid of ``I − T`` over the contiguous pixels above the
      grey threshold ``T = background + threshold_fraction · peak`` (default 50 %, our choice: 004 gives no value);
    * ``"gaussian3"``: vertex of the parabola through the logarithms of the three pixels at the
      peak (exact for a sampled Gaussian).

    Parameters
    ----------
    signal : (n_pixels,) array
        One line signal (DN).
    method, threshold_fraction, min_snr, min_separation_px, half_window_px
        See above; ``half_window_px`` bounds the pixels used around each peak.

    Returns
    -------
    LineSpots
    """
    _check_method(method, threshold_fraction)
    s = np.asarray(signal, dtype=float)
    if s.ndim != 1 or s.shape[0] < 3:
        raise ValueError(f"signal: expected a 1-D line signal, got shape {s.shape}")
    bg, noise = _background(s[None])
    height = bg[0] + min_snr * noise[0]
    peaks, _ = find_peaks(s, height=height, distance=max(1.0, float(min_separation_px)))
    if peaks.size == 0:
        empty = np.zeros(0)
        return LineSpots(empty, empty, empty, float(bg[0]), float(noise[0]))
    centre, peak, fwhm = _refine(s[None], peaks[None], bg, method=method,
                                 threshold_fraction=threshold_fraction, half_window=int(half_window_px))
    return LineSpots(centre[0], peak[0], fwhm[0], float(bg[0]), float(noise[0]))


def brightest_spot_centres(
    signals: ArrayLike,
    *,
    method: str = "threshold_centroid",
    threshold_fraction: float = 0.5,
    min_snr: float = 8.0,
    half_window_px: int = 12,
) -> np.ndarray:
    """Sub-pixel centre of the brightest spot of each line signal (vectorised; one lit source).

    The fast path for calibration and sequential lighting, where one source is lit at a time.

    Parameters
    ----------
    signals : (..., n_pixels) array
        Line signals (DN).

    Returns
    -------
    (...,) ndarray
        Spot centre (px); NaN where no pixel rises ``min_snr`` noise levels above the background.
    """
    _check_method(method, threshold_fraction)
    s = np.asarray(signals, dtype=float)
    if s.ndim < 1 or s.shape[-1] < 3:
        raise ValueError(f"signals: expected shape (..., n_pixels), got {s.shape}")
    batch = s.shape[:-1]
    flat = s.reshape(-1, s.shape[-1])
    bg, noise = _background(flat)
    peak_idx = np.clip(np.argmax(flat, axis=-1), 1, flat.shape[-1] - 2)
    centre, peak, _ = _refine(flat, peak_idx[:, None], bg, method=method,
                              threshold_fraction=threshold_fraction, half_window=int(half_window_px))
    centre = np.where(peak[:, 0] > min_snr * noise, centre[:, 0], np.nan)
    return centre.reshape(batch)
