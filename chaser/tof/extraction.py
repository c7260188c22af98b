"""Dark-marker key points of one TOF frame (paper 000 §2), in its corrected form.

:func:`extract_markers`: grey threshold and keep-darkest ``N_max`` (000 §2.1), the
Laplacian-of-Gaussian with the normalised, zero-mean kernel (flag P000-2, docs/papers.md#p000-2) and
the dark-marker sign (flag P000-3, docs/papers.md#p000-3: ``J`` = LoG response, a dark dot gives
``J > 0``, keep ``J ≥ J_t``), the hysteresis reading of the double thresholds (flag P000-4,
docs/papers.md#p000-4), connected components filtered by pixel count and eccentricity,
contrast-weighted centroids (flag P000-5, docs/papers.md#p000-5, eqs 9–11), the range of each
component (eq 12, or a plate-plane fit) and the 3-D key point by eq (5) (flag P000-1,
docs/papers.md#p000-1).

Frames: ``S`` camera (OpenCV); the key points are returned in S.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy import ndimage

from chaser.tof.dotfit import fit_dot
from vision.tof import MarkerPlate, TofCamera, TofFrame, points_from_pixel_range

__all__ = ["ExtractionSettings", "ExtractionThresholds", "MarkerDetections", "log_kernel", "extract_markers"]


@dataclass(frozen=True)
class ExtractionSettings:
    """Settings of :func:`extract_markers` (000 gives no values; the defaults are this project's).

    Attributes
    ----------
    grey_threshold_dn : float or None
        ``I_t``; None: ``grey_threshold_frac × W`` with ``W`` the white level (98th percentile of
        the valid amplitudes, the plate).  (An Otsu threshold fails here: with three
        populations — dots, body, plate — it lands between any two of them depending on the pixel
        counts.)
    grey_threshold_frac : float
        ``I_t / W`` when ``grey_threshold_dn`` is None.
    grey_peak_frac : float
        Strict grey threshold of the hysteresis, ``I_peak = grey_peak_frac × W``.
    n_max_factor : float
        ``N_max = n_max_factor × n_markers × (predicted dot area in pixels)``.
    hole_depth_frac : float or None
        When more than ``N_max`` pixels pass the grey threshold, the pixels darker than
        ``hole_depth_frac`` times the grey-level closing of the amplitude around them (dark holes in
        a bright surface: the dot cores) are kept besides the darkest ``N_max``.  The budget of
        000 §2.1 is global, and a body face seen at grazing incidence (``cos θ → 0``) is darker than
        the dots: at 1 m with the plate tilted by about 30°, such faces took the whole budget and the
        frame was lost ("no marker candidates").  None: the paper's rule alone.
    log_sigma_px : float or None
        LoG scale σ; None: predicted dot radius in pixels / √2 (scale-normalised blob detector).
    log_scales : tuple of float
        ``J`` is the largest scale-normalised response over the scales ``σ × log_scales``, so a
        dot that looks smaller (farther, or foreshortened by a tilt) responds as strongly as a
        round one (a scale-normalised LoG peaks at ``σ = r/√2`` with a value set by the contrast).
    log_threshold_frac, log_peak_frac : float
        ``J_t`` and ``J_peak`` as fractions of the white level ``W``.  A black dot of radius r on
        the white plate gives a scale-normalised response of about ``0.5 W`` at ``σ = r/√2`` (less
        when it is small or foreshortened); thresholds tied to the contrast rather than to the
        frame's largest response (0.2× and 0.5× the maximum) keep the far and tilted
        dots of an oblique plate.
    log_noise_factor : float
        ``J_peak`` is at least this many robust standard deviations of ``J`` over the valid pixels,
        so a frame without markers does not promote noise to markers.
    area_min_frac, area_max_frac : float
        Accepted component size relative to the predicted face-on dot area ``π (r f / ρ)²`` at the
        component's range (a dot tilted by 64°, eccentricity 0.9, covers 0.44 of it).
    max_eccentricity : float
        Accepted eccentricity ``sqrt(1 − λ_min/λ_max)`` of the component's second moments.
    centroid_dilate_px : int
        The contrast-weighted centroid is taken over the component dilated by this many pixels,
        so the partially dark rim pixels contribute their partial weights.
    range_estimator : {"mean", "plane"}
        ``"mean"``: 000 eq (12), mean range of the component.  ``"plane"``: back-project the
        bright plate ring around the dot, fit a plane, and intersect the centroid ray with it
        (uses high-amplitude, low-noise pixels; the dot lies on the plate).
    plane_support_factor : float
        For ``"plane"``: the plate pixels within this many (predicted) dot radii of the key point
        support the plane.
    centre_estimator : {"fit", "centroid"}
        ``"fit"`` (default): the dot centre is the weighted least-squares fit of the dot's image model
        (:mod:`chaser.tof.dotfit`: a disc of the known radius in the local plate plane, pixel-area
        coverage, the plate's brightness and the contrast free), started from the centroid; the
        centroid is kept where the fit fails.  ``"centroid"``: the contrast-weighted centroid of
        eqs 9–11 (flag P000-5), which is offset from the projected dot centre by perspective and by
        the plate's brightness gradient (0.01–0.05 px at 1 m).
    fit_margin_px : float
        For ``"fit"``: the fit window is the pixels within ``r_px + fit_margin_px`` of the centroid
        (``r_px`` the dot's radius in pixels at the plate-plane range).
    fit_cells : int
        For ``"fit"``: cells per pixel and axis of the model's area integration.
    fit_max_chi2 : float
        For ``"fit"``: a fit whose χ² per degree of freedom exceeds this (the blob is not a dot of
        the model's size) keeps the centroid.
    fallback_sigma_px : float
        For ``"fit"``: standard error (px) given to a centroid kept where the fit failed, so that a
        pose weighting the key points by it does not trust its systematic offset (0.01–0.08 px at 1 m
        on clean dots, more on a dot next to the plate's edge).
    depth_edge_m : float
        For ``"plane"`` and ``"fit"``: plate pixels whose 3×3 neighbourhood spans more range than this (depth
        edges, where the mixed pixels are) are left out of the plane fit.
    """

    grey_threshold_dn: float | None = None
    grey_threshold_frac: float = 0.5
    grey_peak_frac: float = 0.25
    n_max_factor: float = 5.0
    log_sigma_px: float | None = None
    log_scales: tuple[float, ...] = (0.5, 0.7, 1.0)
    log_threshold_frac: float = 0.1
    log_peak_frac: float = 0.2
    log_noise_factor: float = 8.0
    area_min_frac: float = 0.15
    area_max_frac: float = 3.0
    max_eccentricity: float = 0.95
    centroid_dilate_px: int = 2
    range_estimator: str = "plane"
    centre_estimator: str = "fit"
    fit_margin_px: float = 2.5
    fit_cells: int = 4
    fit_max_chi2: float = 10.0
    fallback_sigma_px: float = 0.05
    hole_depth_frac: float | None = 0.25
    depth_edge_m: float = 0.02
    plane_support_factor: float = 3.0

    def __post_init__(self) -> None:
        if self.range_estimator not in ("mean", "plane"):
            raise ValueError(f"range_estimator: must be 'mean' or 'plane', got {self.range_estimator!r}")
        if self.centre_estimator not in ("fit", "centroid"):
            raise ValueError(f"centre_estimator: must be 'fit' or 'centroid', got {self.centre_estimator!r}")
        if not np.isfinite(self.fit_margin_px) or self.fit_margin_px <= 0:
            raise ValueError(f"fit_margin_px: must be finite and > 0, got {self.fit_margin_px!r}")
        if int(self.fit_cells) != self.fit_cells or self.fit_cells < 1:
            raise ValueError(f"fit_cells: must be an integer >= 1, got {self.fit_cells!r}")
        for key in ("grey_threshold_frac", "grey_peak_frac", "depth_edge_m", "plane_support_factor", "n_max_factor",
                    "log_threshold_frac", "log_peak_frac", "area_max_frac", "max_eccentricity", "fit_max_chi2",
                    "fallback_sigma_px"):
            v = getattr(self, key)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{key}: must be finite and > 0, got {v!r}")
        if not self.log_scales or any(not np.isfinite(x) or x <= 0 for x in self.log_scales):
            raise ValueError(f"log_scales: must be positive finite factors, got {self.log_scales!r}")
        if self.log_peak_frac < self.log_threshold_frac:
            raise ValueError(f"log_peak_frac: must be >= log_threshold_frac, got {self.log_peak_frac!r}")
        if self.hole_depth_frac is not None and not 0 < self.hole_depth_frac < 1:
            raise ValueError(f"hole_depth_frac: must lie in (0, 1) or be None, got {self.hole_depth_frac!r}")
        if int(self.centroid_dilate_px) != self.centroid_dilate_px or self.centroid_dilate_px < 0:
            raise ValueError(f"centroid_dilate_px: must be an integer >= 0, got {self.centroid_dilate_px!r}")


@dataclass(frozen=True)
class ExtractionThresholds:
    """The thresholds actually used on one frame (amplitudes in DN, LoG responses in DN)."""

    grey: float = float("nan")
    grey_peak: float = float("nan")
    log: float = float("nan")
    log_peak: float = float("nan")
    n_max: int = 0
    log_sigma_px: float = float("nan")


@dataclass(frozen=True)
class MarkerDetections:
    """Key points extracted from one TOF frame (000 §2), ``n`` of them.

    Attributes
    ----------
    uv_px : (n, 2) ndarray
        Dot centres (u, v) in pixels: the dot-model fit (``centre_estimator="fit"``) or the
        contrast-weighted centroid (eqs 9–11, flag P000-5).
    range_m : (n,) ndarray
        Range of each key point (eq 12, or the plate-plane estimate).
    points_S : (n, 3) ndarray
        Key points in the camera frame S by eq (5) (m).
    range_sigma_m : (n,) ndarray
        Standard error of ``range_m`` from the spread of the pixel ranges used (m).
    pixel_count : (n,) int ndarray
        Pixels in each accepted component.
    eccentricity : (n,) ndarray
    centroid_sigma_px : (n,) ndarray
        Standard error of each centre coordinate (px), ``sqrt(tr Σ_uv / 2)``.
    centre_cov_px2 : (n, 2, 2) ndarray
        Covariance ``Σ_uv`` of each centre (px²): of the dot fit, ``(JᵀWJ)⁻¹`` with the camera's
        amplitude noise; of the centroid, ``σ² I`` with ``σ = σ_A sqrt(Σ w_x x²) / Σ w`` and ``σ_A``
        the robust spread of the amplitudes of the plate ring around the dot (eqs 9–11 propagated).
    centre_fitted : (n,) bool ndarray
        True where the centre is the dot-model fit, False where it is the centroid.
    thresholds : ExtractionThresholds
    failure_reason : str
        Empty when key points were extracted; otherwise why none were ("all pixels saturated",
        "no valid range pixels", "no marker candidates", ...).
    """

    uv_px: np.ndarray
    range_m: np.ndarray
    points_S: np.ndarray
    range_sigma_m: np.ndarray
    pixel_count: np.ndarray
    eccentricity: np.ndarray
    thresholds: ExtractionThresholds = field(default_factory=ExtractionThresholds)
    failure_reason: str = ""
    centroid_sigma_px: np.ndarray = field(default_factory=lambda: np.zeros(0))
    centre_cov_px2: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))
    centre_fitted: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))

    @property
    def ok(self) -> bool:
        """True when key points were extracted (``failure_reason`` is empty)."""
        return not self.failure_reason

    @property
    def n(self) -> int:
        """Number of key points."""
        return len(self.range_m)


def _empty_detections(failure_reason: str, thresholds: ExtractionThresholds | None = None) -> MarkerDetections:
    z = np.zeros(0)
    return MarkerDetections(np.zeros((0, 2)), z, np.zeros((0, 3)), z, np.zeros(0, int), z,
                            thresholds or ExtractionThresholds(), failure_reason)


def log_kernel(sigma_px: float) -> np.ndarray:
    """Laplacian-of-Gaussian kernel, 000 eq (7) corrected (flag P000-2), scale-normalised.

    ``σ² ∇²G = σ² (x² + y² − 2σ²) / (2π σ⁶) · exp(−(x² + y²) / (2σ²))`` on a square of radius
    ``⌈3σ⌉``, minus its mean so that a flat background gives zero response.  The centre weight
    is negative, so a dark dot on a bright plate gives a *positive* response (flag P000-3).
    """
    if not np.isfinite(sigma_px) or sigma_px <= 0:
        raise ValueError(f"sigma_px: must be finite and > 0, got {sigma_px!r}")
    rad = int(np.ceil(3.0 * sigma_px))
    x = np.arange(-rad, rad + 1, dtype=float)
    r2 = x[None, :] ** 2 + x[:, None] ** 2
    s2 = sigma_px**2
    k = (r2 - 2 * s2) / (2 * np.pi * s2**3) * np.exp(-r2 / (2 * s2))
    k -= k.mean()
    return s2 * k


def extract_markers(frame: TofFrame, camera: TofCamera, plate: MarkerPlate, *,
                    settings: ExtractionSettings | None = None,
                    plate_plane_S: tuple[np.ndarray, float] | None = None) -> MarkerDetections:
    """Extract the dark-marker key points of one TOF frame (000 §2, corrected).

    Steps: valid pixels → grey threshold ``I ≤ I_t`` and keep the darkest ``N_max`` (active set
    Â) → LoG response ``J`` (flags P000-2/3) → components of ``Â ∧ (J ≥ J_t)`` (8-connected),
    accepted when at least one pixel reaches the strict thresholds ``I ≤ I_peak`` and
    ``J ≥ J_peak`` (hysteresis, flag P000-4), the pixel count lies in
    ``[area_min_frac, area_max_frac] × π (r f / ρ)²`` and the eccentricity is below
    ``max_eccentricity``, and the component does not touch the image border → contrast-weighted centroid (P000-5) and range (eq 12) → eq (5).

    Parameters
    ----------
    frame : TofFrame
    camera : TofCamera
        Intrinsics for eq (5) (the image must be undistorted).
    plate : MarkerPlate
        Marker radius and count (for the predicted dot size and ``N_max``).
    settings : ExtractionSettings, optional
    plate_plane_S : (n_S (3,), h_m), optional
        The plate plane ``n_S · p_S = h`` (unit normal in S, offset in m) that the dot fit
        (``centre_estimator="fit"``) takes for the dots' shape, e.g. from a pose of the whole plate;
        None: the plane fitted to the range pixels around each dot.  The key points' ranges come
        from the local planes either way.

    Returns
    -------
    MarkerDetections
        ``ok`` False with ``failure_reason`` set (and no points) for a frame that is all saturated
        or has no valid pixels, and with "no marker candidates" when nothing passes.
    """
    s = settings or ExtractionSettings()
    amp = np.asarray(frame.amplitude_dn, dtype=float)
    rng_img = np.asarray(frame.range_m, dtype=float)
    valid = np.asarray(frame.valid, dtype=bool)
    if amp.shape != (camera.height_px, camera.width_px):
        raise ValueError(f"frame: amplitude shape {amp.shape} does not match the camera "
                         f"({camera.height_px}, {camera.width_px})")
    if np.all(frame.saturated):
        return _empty_detections("all pixels saturated")
    if not valid.any():
        return _empty_detections("no valid range pixels")

    f_mean = 0.5 * (camera.fx_px + camera.fy_px)
    r_dot = plate.marker_radius_m
    median_range = float(np.median(rng_img[valid]))
    dot_px = r_dot * f_mean / median_range
    dot_area = np.pi * dot_px**2
    sigma = s.log_sigma_px if s.log_sigma_px is not None else max(dot_px / np.sqrt(2.0), 0.7)

    vals = amp[valid]
    white = float(np.percentile(vals, 98))
    i_t = s.grey_threshold_dn if s.grey_threshold_dn is not None else s.grey_threshold_frac * white
    i_peak = min(s.grey_peak_frac * white, i_t)
    cand = valid & (amp <= i_t)
    n_max = int(np.ceil(s.n_max_factor * plate.n_markers * dot_area))
    if cand.sum() > n_max:
        idx = np.flatnonzero(cand)
        keep = idx[np.argpartition(amp.ravel()[idx], n_max - 1)[:n_max]]
        holes = cand & _dark_holes(amp, valid, dot_px, s.hole_depth_frac) if s.hole_depth_frac is not None else None
        cand = np.zeros_like(cand)
        cand.ravel()[keep] = True
        if holes is not None:
            cand |= holes
    if not cand.any():
        return _empty_detections(_why_none(frame, camera, dot_px) or "no pixels darker than the grey threshold",
                                 ExtractionThresholds(grey=i_t, n_max=n_max, log_sigma_px=sigma))

    img = amp.astype(np.float32)
    J = np.max([cv2.filter2D(img, cv2.CV_32F, log_kernel(sc * sigma).astype(np.float32),
                             borderType=cv2.BORDER_REPLICATE) for sc in s.log_scales], axis=0).astype(float)
    j_max = float(J[cand].max())
    j_valid = J[valid]
    j_noise = 1.4826 * float(np.median(np.abs(j_valid - np.median(j_valid))))
    j_t = s.log_threshold_frac * white
    j_peak = max(s.log_peak_frac * white, s.log_noise_factor * j_noise)
    i_bg = white
    thr = ExtractionThresholds(grey=i_t, grey_peak=i_peak, log=j_t, log_peak=j_peak, n_max=n_max,
                               log_sigma_px=sigma)
    if j_max <= 0:
        return _empty_detections(_why_none(frame, camera, dot_px) or "no marker candidates", thr)

    loose = cand & (J >= j_t)
    n_lab, labels = cv2.connectedComponents(loose.astype(np.uint8), connectivity=8, ltype=cv2.CV_32S)
    if n_lab <= 1:
        return _empty_detections(_why_none(frame, camera, dot_px) or "no marker candidates", thr)
    idx = np.arange(1, n_lab)
    # per-component statistics over the labelled pixels only (bincount / reduceat)
    pv, pu = np.nonzero(labels)
    pl = labels[pv, pu]
    order = np.argsort(pl, kind="stable")
    pv, pu, pl = pv[order], pu[order], pl[order]
    starts = np.searchsorted(pl, idx)
    count = np.bincount(pl, minlength=n_lab)[1:].astype(float)
    min_i = np.minimum.reduceat(amp[pv, pu], starts)
    max_j = np.maximum.reduceat(J[pv, pu], starts)
    r_ok = valid[pv, pu]
    n_r = np.bincount(pl, weights=r_ok, minlength=n_lab)[1:]
    sum_r = np.bincount(pl, weights=np.where(r_ok, rng_img[pv, pu], 0.0), minlength=n_lab)[1:]
    med_r = np.where(n_r > 0, sum_r / np.maximum(n_r, 1), median_range)          # mean range
    fu, fv = pu.astype(float), pv.astype(float)
    mu = np.bincount(pl, weights=fu, minlength=n_lab)[1:] / count
    mv = np.bincount(pl, weights=fv, minlength=n_lab)[1:] / count
    cuu = np.bincount(pl, weights=fu * fu, minlength=n_lab)[1:] / count - mu**2
    cvv = np.bincount(pl, weights=fv * fv, minlength=n_lab)[1:] / count - mv**2
    cuv = np.bincount(pl, weights=fu * fv, minlength=n_lab)[1:] / count - mu * mv
    tr, det = cuu + cvv, cuu * cvv - cuv**2
    disc = np.sqrt(np.maximum(tr**2 / 4 - det, 0.0))
    lam_max, lam_min = tr / 2 + disc, np.maximum(tr / 2 - disc, 0.0)
    ecc = np.sqrt(1.0 - lam_min / np.maximum(lam_max, 1e-12))
    area_pred = np.pi * (r_dot * f_mean / med_r) ** 2
    # a dot cut by the image border has neither its centroid nor its whole edge: not a key point
    inside = ((np.minimum.reduceat(pu, starts) > 0) & (np.maximum.reduceat(pu, starts) < amp.shape[1] - 1)
              & (np.minimum.reduceat(pv, starts) > 0) & (np.maximum.reduceat(pv, starts) < amp.shape[0] - 1))
    ok = ((min_i <= i_peak) & (max_j >= j_peak) & (count >= s.area_min_frac * area_pred)
          & (count <= s.area_max_frac * area_pred) & (ecc <= s.max_eccentricity) & inside)
    accepted = idx[ok]
    if accepted.size == 0:
        return _empty_detections(_why_none(frame, camera, dot_px) or "no marker candidates", thr)

    if s.range_estimator == "plane" or s.centre_estimator == "fit":
        # mixed pixels sit on depth edges: exclude pixels whose 3x3 range spread exceeds depth_edge_m
        r_hi = np.where(valid, rng_img, np.inf).astype(np.float32)
        r_lo = np.where(valid, rng_img, -np.inf).astype(np.float32)
        k3 = np.ones((3, 3), np.uint8)
        smooth = (cv2.dilate(r_hi, k3) - cv2.erode(r_lo, k3)) <= s.depth_edge_m
        # pixels without a range enclosed by returns: dot cores below the confidence threshold
        holes = ndimage.binary_fill_holes(valid | frame.saturated) & ~valid & ~np.asarray(frame.saturated, bool)
    objects = ndimage.find_objects(labels)
    d = int(s.centroid_dilate_px)
    ring_in, ring_out = d + 1, d + 3
    sup_px = s.plane_support_factor * r_dot * f_mean / med_r                     # per component
    fit_px = r_dot * f_mean / med_r + s.fit_margin_px
    pad = int(max(ring_out, np.ceil(sup_px[ok].max()), np.ceil(fit_px[ok].max()))) + 1
    uv, uv_cov, fitted, rho, rho_sig, cnt, ecc_out = [], [], [], [], [], [], []
    for lab in accepted:
        sl = objects[lab - 1]
        v0, v1 = max(sl[0].start - pad, 0), min(sl[0].stop + pad, amp.shape[0])
        u0, u1 = max(sl[1].start - pad, 0), min(sl[1].stop + pad, amp.shape[1])
        comp = (labels[v0:v1, u0:u1] == lab)
        a_w, r_w, ok_w = amp[v0:v1, u0:u1], rng_img[v0:v1, u0:u1], valid[v0:v1, u0:u1]
        support = _dilate(comp, d)
        ring = _dilate(comp, ring_out) & ~_dilate(comp, ring_in) & ok_w
        i_local = float(np.median(a_w[ring])) if ring.any() else i_bg
        w = np.clip(i_local - a_w, 0.0, None) * support
        if w.sum() <= 0:
            continue
        gv, gu = np.indices(comp.shape, dtype=float)
        uc = float((w * (gu + u0)).sum() / w.sum())
        vc = float((w * (gv + v0)).sum() / w.sum())
        pair = ring[:, 1:] & ring[:, :-1]                  # amplitude noise from neighbour differences
        diff = (a_w[:, 1:] - a_w[:, :-1])[pair]
        sig_a = 1.4826 * float(np.median(np.abs(diff - np.median(diff)))) / np.sqrt(2.0) if diff.size >= 8 else i_local
        x2 = float(((gu + u0 - uc) ** 2 * support).sum() + ((gv + v0 - vc) ** 2 * support).sum()) / 2.0
        sig_uv = max(sig_a, 1.0) * np.sqrt(x2) / float(w.sum())
        cov_uv, is_fit = sig_uv**2 * np.eye(2), False
        plane = None
        if s.range_estimator == "plane" or s.centre_estimator == "fit":
            near = (gu + u0 - uc) ** 2 + (gv + v0 - vc) ** 2 <= sup_px[lab - 1] ** 2
            on_plate = near & ok_w & (a_w > i_t) & smooth[v0:v1, u0:u1] & ~_dilate(comp, ring_in)
            plane = _plate_plane(gu[on_plate] + u0, gv[on_plate] + v0, r_w[on_plate], uc, vc, camera)
        if s.centre_estimator == "fit" and plane is not None:
            shape = plane if plate_plane_S is None else (np.asarray(plate_plane_S[0], float), float(plate_plane_S[1]), 0.0)
            n_S, h_m, _ = shape
            r_px = r_dot * f_mean / _plane_ray_range(shape, uc, vc, camera)
            pu, pv = (gu + u0).ravel(), (gv + v0).ravel()
            rr = np.hypot(pu - uc, pv - vc).reshape(comp.shape)
            # off the plate: a return farther from the plane than 4 of its own range sigmas + 2 mm (the body
            # behind the plate, 55 mm), or no return that is not enclosed by returns (beyond the plate's
            # edge); their neighbours are mixed pixels
            tol = 4.0 * camera.range_sigma_m(np.maximum(a_w, 1.0)) + 0.002
            off = np.where(ok_w, np.abs(r_w - _plane_ray_range(plane, gu + u0, gv + v0, camera)) > tol,
                           ~holes[v0:v1, u0:u1])
            win = (rr <= r_px + s.fit_margin_px) & ~np.asarray(frame.saturated)[v0:v1, u0:u1] & ~_dilate(off, 1)
            if win.sum() >= 12:
                fit = fit_dot(a_w[win], (gu + u0)[win], (gv + v0)[win], camera, n_S, h_m, r_dot, (uc, vc), i_local,
                              sub=int(s.fit_cells), max_shift_px=max(1.0, 0.5 * r_px))
                if fit.ok and fit.chi2_per_dof < s.fit_max_chi2:
                    (uc, vc), cov_uv, is_fit = fit.uv_px, fit.cov_uv_px2, True
        if s.centre_estimator == "fit" and not is_fit:
            cov_uv = max(sig_uv, s.fallback_sigma_px) ** 2 * np.eye(2)
        if s.range_estimator == "mean":
            r_pix = r_w[comp & ok_w]
            if r_pix.size < 2:
                continue
            rho_i = float(r_pix.mean())
            sig_i = float(r_pix.std(ddof=1) / np.sqrt(r_pix.size))
        else:
            if plane is None:
                continue
            rho_i, sig_i = _plane_ray_range(plane, uc, vc, camera), plane[2]
        uv.append((float(uc), float(vc)))
        uv_cov.append(cov_uv)
        fitted.append(is_fit)
        rho.append(float(rho_i))
        rho_sig.append(float(sig_i))
        cnt.append(int(count[lab - 1]))
        ecc_out.append(float(ecc[lab - 1]))
    if not uv:
        return _empty_detections(_why_none(frame, camera, dot_px) or "no marker candidates", thr)
    uv_a = np.asarray(uv)
    rho_a = np.asarray(rho)
    cov_a = np.asarray(uv_cov)
    pts = points_from_pixel_range(uv_a[:, 0], uv_a[:, 1], rho_a, camera)
    return MarkerDetections(uv_a, rho_a, pts, np.asarray(rho_sig), np.asarray(cnt, int), np.asarray(ecc_out), thr, "",
                            np.sqrt(np.trace(cov_a, axis1=1, axis2=2) / 2.0), cov_a, np.asarray(fitted, bool))


def _why_none(frame: TofFrame, camera: TofCamera, dot_px: float) -> str:
    """Why a frame gave no usable key points: saturation, or dark dots without range, else ""."""
    valid, sat = np.asarray(frame.valid, bool), np.asarray(frame.saturated, bool)
    if sat.sum() > 0.05 * (valid | sat).sum():
        return f"plate saturated ({int(sat.sum())} px above the full well)"
    holes = ndimage.binary_fill_holes(valid | sat) & ~valid & ~sat      # no-range pixels enclosed by returns
    if holes.sum() >= 0.5 * np.pi * dot_px**2:
        return (f"markers below the confidence threshold ({int(holes.sum())} px inside the plate under "
                f"{camera.amplitude_min_dn:g} DN)")
    return ""


def _dark_holes(amp: np.ndarray, valid: np.ndarray, dot_px: float, depth_frac: float) -> np.ndarray:
    """Pixels darker than ``depth_frac`` times the grey-level closing of the amplitude around them.

    The closing (dilation then erosion, elliptic disk of radius ``⌈2 r_dot⌉ + 1`` px) fills every
    dark region narrower than the disk with the brightness of its surroundings: a dot on the plate
    becomes plate-bright, so its core is a deep *hole*.  A dark surface that borders no-return
    pixels or extends beyond the disk (a body face seen at grazing incidence, the background) is
    not filled and gives no hole.  Pixels without a range count as dark (amplitude 0).
    """
    a = np.where(valid, amp, 0.0).astype(np.float32)
    rad = int(np.ceil(2.0 * dot_px)) + 1
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * rad + 1, 2 * rad + 1))
    closed = cv2.morphologyEx(a, cv2.MORPH_CLOSE, k, borderType=cv2.BORDER_CONSTANT, borderValue=0.0)
    return valid & (a <= depth_frac * closed)


def _dilate(mask: np.ndarray, px: int) -> np.ndarray:
    if px <= 0:
        return mask.copy()
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * px + 1, 2 * px + 1))
    return cv2.dilate(mask.astype(np.uint8), k).astype(bool)


def _plane_ray_range(plane: tuple[np.ndarray, float, float], u, v, camera: TofCamera):
    """Radial range (m) along the ray of pixel ``(u, v)`` to the plane ``n_S · p = h`` of :func:`_plate_plane`."""
    n_S, h_m, _ = plane
    e = points_from_pixel_range(u, v, 1.0, camera)
    return h_m / (e @ n_S)


def _plate_plane(u: np.ndarray, v: np.ndarray, r: np.ndarray, uc: float, vc: float,
                 camera: TofCamera) -> tuple[np.ndarray, float, float] | None:
    """Plane ``n_S · p_S = h`` through the plate pixels around ``(uc, vc)``: ``(n_S, h_m, σ_ρ)``.

    ``σ_ρ`` is the standard error (m) of the range along the ray of ``(uc, vc)`` to the plane.
    In axes ``(a, b, e)`` with ``e`` the unit ray of the key point, the back-projected plate pixels
    are fitted by ``z = c0 + c1 x + c2 y`` (least squares, refitted once without the pixels beyond
    3 robust σ); the ray meets the plane at range ``c0``, whose standard error
    ``σ sqrt((XᵀX)⁻¹₀₀)`` includes the extrapolation when the support is one-sided.
    """
    if r.size < 8:
        return None
    p = points_from_pixel_range(u, v, r, camera)
    e = points_from_pixel_range(uc, vc, 1.0, camera)
    a = np.array([-e[2], 0.0, e[0]]) / np.hypot(e[0], e[2])        # e × y, normalised
    b = np.array([e[1] * a[2] - e[2] * a[1], e[2] * a[0] - e[0] * a[2], e[0] * a[1] - e[1] * a[0]])
    X = np.column_stack([np.ones(len(p)), p @ a, p @ b])
    z = p @ e
    keep = np.ones(len(p), dtype=bool)
    for it in range(3):
        Xk, zk = X[keep], z[keep]
        if len(zk) < 8:
            return None
        G = Xk.T @ Xk
        if np.linalg.cond(G) > 1e12:
            return None
        coef = np.linalg.solve(G, Xk.T @ zk)
        res = z - X @ coef
        if it == 2:
            break
        mad = 1.4826 * float(np.median(np.abs(res[keep])))
        keep = np.abs(res) <= 3.0 * max(mad, 1e-6)
    rk = res[keep]
    dof = int(keep.sum()) - 3
    if dof < 5:
        return None
    var0 = float(np.linalg.inv(G)[0, 0]) * float(rk @ rk) / dof
    n = e - coef[1] * a - coef[2] * b
    norm = float(np.linalg.norm(n))
    return n / norm, float(coef[0]) / norm, float(np.sqrt(var0))
