"""TOF-camera relative pose of a cooperative marker target (paper 000), in its corrected form.

Pipeline (000 §1.2; SEEDS_SPEC §1):

1. :func:`extract_markers` — grey threshold and keep-darkest ``N_max`` (000 §2.1), the
   Laplacian-of-Gaussian with the normalised, zero-mean kernel (flag P000-2) and the dark-marker
   sign (flag P000-3: ``J`` = LoG response, a dark dot gives ``J > 0``, keep ``J ≥ J_t``), the
   hysteresis reading of the double thresholds (flag P000-4), connected components filtered by
   pixel count and eccentricity, contrast-weighted centroids (flag P000-5, eqs 9–11), the mean
   range of each component (eq 12) and the 3-D key point by eq (5) (flag P000-1).
2. Matching observed key points to the model markers from distance consistency (000 §3):

   * :func:`match_markers_mrf` — mean-field deterministic annealing with the null label in the
     corrected form (flags P000-6..9): four-index mismatch ``ρ_klij = d̃_kl − d_ij``, row-wise
     softmax over the labels, iteration to a fixed point at every temperature (damped, because
     undamped synchronous sweeps oscillate), optional Sinkhorn (softassign) normalisation, and a
     *truncated* pair potential ``min(ρ², (τα)²)`` (this project's robustification: with the
     paper's unbounded ``ρ²`` one spurious point outweighs every consistent pair and drives the
     field to the all-null state, see ``docs/tof.md``);
   * :func:`match_markers_mrf_literal` — the paper's printed schedule (one sweep per temperature,
     unbounded ``ρ²``) for comparison;
   * :func:`match_markers_hungarian` — a baseline: a robust distance-profile cost per
     (observation, model) pair and ``scipy.optimize.linear_sum_assignment`` with null columns;
   * :func:`verify_labels` — the pose check recommended by SEEDS_SPEC §1.3.4: drop the match
     with the largest SVD residual while it exceeds ``gate·α`` and re-assign every observation to
     the nearest predicted marker (Hungarian, gated).
3. :func:`weighted_svd_pose` — weighted absolute orientation, 000 eqs (27)–(38) (flag P000-10).
4. :func:`estimate_tof_pose` — the whole chain on one :class:`vision.tof.TofFrame`; the pose is
   reported as ``x, y, z`` (``r_CS_S``) and pitch, yaw, roll.

**Euler sequence** (000 does not state one, SEEDS_SPEC §1.6): pitch, yaw and roll are the 3-2-1
angles of ``R_SC = R_z(yaw) R_y(pitch) R_x(roll)`` (``attitude.euler``, sequence ``"321"``),
i.e. yaw about the camera boresight z_S, pitch about y_S, roll about x_S.

Frames: ``S`` camera (OpenCV), ``C`` marker plate; ``p_S = R_SC q_C + r_CS_S`` (000 eq 1).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage
from scipy.optimize import linear_sum_assignment

from attitude.euler import euler_from_matrix
from vision.tof import MarkerPlate, TofCamera, TofFrame, points_from_pixel_range

__all__ = [
    "ExtractionSettings",
    "ExtractionThresholds",
    "MarkerDetections",
    "log_kernel",
    "extract_markers",
    "MatchSettings",
    "MarkerMatch",
    "match_markers_mrf",
    "match_markers_mrf_literal",
    "match_markers_hungarian",
    "verify_labels",
    "RigidFit",
    "weighted_svd_pose",
    "pitch_yaw_roll_from_matrix",
    "TofPoseResult",
    "estimate_tof_pose",
    "MATCHERS",
    "MatchingTrials",
    "random_matching_trials",
]


# --------------------------------------------------------------------------------------------
# 1. Marker extraction (000 §2)
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ExtractionSettings:
    """Settings of :func:`extract_markers` (000 gives no values; defaults per SEEDS_SPEC §1.6).

    Attributes
    ----------
    grey_threshold_dn : float or None
        ``I_t``; None: ``grey_threshold_frac × W`` with ``W`` the white level (98th percentile of
        the valid amplitudes, the plate).  (SEEDS_SPEC suggests Otsu; with three populations —
        dots, body, plate — Otsu lands between any two of them depending on the pixel counts.)
    grey_threshold_frac : float
        ``I_t / W`` when ``grey_threshold_dn`` is None.
    grey_peak_frac : float
        Strict grey threshold of the hysteresis, ``I_peak = grey_peak_frac × W``.
    n_max_factor : float
        ``N_max = n_max_factor × n_markers × (predicted dot area in pixels)``.
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
        frame's largest response (SEEDS_SPEC's 0.2× and 0.5× the maximum) keep the far and tilted
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
    depth_edge_m : float
        For ``"plane"``: plate pixels whose 3×3 neighbourhood spans more range than this (depth
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
    depth_edge_m: float = 0.02
    plane_support_factor: float = 3.0

    def __post_init__(self) -> None:
        if self.range_estimator not in ("mean", "plane"):
            raise ValueError(f"range_estimator: must be 'mean' or 'plane', got {self.range_estimator!r}")
        for key in ("grey_threshold_frac", "grey_peak_frac", "depth_edge_m", "plane_support_factor", "n_max_factor", "log_threshold_frac", "log_peak_frac",
                    "area_max_frac", "max_eccentricity"):
            v = getattr(self, key)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{key}: must be finite and > 0, got {v!r}")
        if not self.log_scales or any(not np.isfinite(x) or x <= 0 for x in self.log_scales):
            raise ValueError(f"log_scales: must be positive finite factors, got {self.log_scales!r}")
        if self.log_peak_frac < self.log_threshold_frac:
            raise ValueError(f"log_peak_frac: must be >= log_threshold_frac, got {self.log_peak_frac!r}")
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
        Contrast-weighted centroids (u, v) in pixels (eqs 9–11, flag P000-5).
    range_m : (n,) ndarray
        Range of each key point (eq 12, or the plate-plane estimate).
    points_S : (n, 3) ndarray
        Key points in the camera frame S by eq (5) (m).
    range_sigma_m : (n,) ndarray
        Standard error of ``range_m`` from the spread of the pixel ranges used (m).
    pixel_count : (n,) int ndarray
        Pixels in each accepted component.
    eccentricity : (n,) ndarray
    thresholds : ExtractionThresholds
    reason : str
        Empty when the frame could be processed; otherwise why nothing was extracted
        ("all pixels saturated", "no valid range pixels", ...).
    """

    uv_px: np.ndarray
    range_m: np.ndarray
    points_S: np.ndarray
    range_sigma_m: np.ndarray
    pixel_count: np.ndarray
    eccentricity: np.ndarray
    thresholds: ExtractionThresholds = field(default_factory=ExtractionThresholds)
    reason: str = ""

    @property
    def n(self) -> int:
        return len(self.range_m)


def _empty_detections(reason: str, thresholds: ExtractionThresholds | None = None) -> MarkerDetections:
    z = np.zeros(0)
    return MarkerDetections(np.zeros((0, 2)), z, np.zeros((0, 3)), z, np.zeros(0, int), z,
                            thresholds or ExtractionThresholds(), reason)


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
                    settings: ExtractionSettings | None = None) -> MarkerDetections:
    """Extract the dark-marker key points of one TOF frame (000 §2, corrected).

    Steps: valid pixels → grey threshold ``I ≤ I_t`` and keep the darkest ``N_max`` (active set
    Â) → LoG response ``J`` (flags P000-2/3) → components of ``Â ∧ (J ≥ J_t)`` (8-connected),
    accepted when at least one pixel reaches the strict thresholds ``I ≤ I_peak`` and
    ``J ≥ J_peak`` (hysteresis, flag P000-4), the pixel count lies in
    ``[area_min_frac, area_max_frac] × π (r f / ρ)²`` and the eccentricity is below
    ``max_eccentricity`` → contrast-weighted centroid (P000-5) and range (eq 12) → eq (5).

    Parameters
    ----------
    frame : TofFrame
    camera : TofCamera
        Intrinsics for eq (5) (the image must be undistorted).
    plate : MarkerPlate
        Marker radius and count (for the predicted dot size and ``N_max``).
    settings : ExtractionSettings, optional

    Returns
    -------
    MarkerDetections
        With ``reason`` set (and no points) for a frame that is all saturated or has no valid
        pixels; an empty result with reason "no marker candidates" when nothing passes.
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
        cand = np.zeros_like(cand)
        cand.ravel()[keep] = True
    if not cand.any():
        return _empty_detections("no pixels darker than the grey threshold",
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
        return _empty_detections("no marker candidates", thr)

    loose = cand & (J >= j_t)
    n_lab, labels = cv2.connectedComponents(loose.astype(np.uint8), connectivity=8, ltype=cv2.CV_32S)
    if n_lab <= 1:
        return _empty_detections("no marker candidates", thr)
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
    ok = ((min_i <= i_peak) & (max_j >= j_peak) & (count >= s.area_min_frac * area_pred)
          & (count <= s.area_max_frac * area_pred) & (ecc <= s.max_eccentricity))
    accepted = idx[ok]
    if accepted.size == 0:
        return _empty_detections("no marker candidates", thr)

    if s.range_estimator == "plane":
        # mixed pixels sit on depth edges: exclude pixels whose 3x3 range spread exceeds depth_edge_m
        r_hi = np.where(valid, rng_img, np.inf).astype(np.float32)
        r_lo = np.where(valid, rng_img, -np.inf).astype(np.float32)
        k3 = np.ones((3, 3), np.uint8)
        smooth = (cv2.dilate(r_hi, k3) - cv2.erode(r_lo, k3)) <= s.depth_edge_m
    objects = ndimage.find_objects(labels)
    d = int(s.centroid_dilate_px)
    ring_in, ring_out = d + 1, d + 3
    sup_px = s.plane_support_factor * r_dot * f_mean / med_r                     # per component
    pad = int(max(ring_out, np.ceil(sup_px[ok].max()))) + 1
    uv, rho, rho_sig, cnt, ecc_out = [], [], [], [], []
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
        if s.range_estimator == "mean":
            r_pix = r_w[comp & ok_w]
            if r_pix.size < 2:
                continue
            rho_i = float(r_pix.mean())
            sig_i = float(r_pix.std(ddof=1) / np.sqrt(r_pix.size))
        else:
            near = (gu + u0 - uc) ** 2 + (gv + v0 - vc) ** 2 <= sup_px[lab - 1] ** 2
            plate = near & ok_w & (a_w > i_t) & smooth[v0:v1, u0:u1] & ~_dilate(comp, ring_in)
            est = _plane_range(gu[plate] + u0, gv[plate] + v0, r_w[plate], uc, vc, camera)
            if est is None:
                continue
            rho_i, sig_i = est
        uv.append((uc, vc))
        rho.append(rho_i)
        rho_sig.append(sig_i)
        cnt.append(int(count[lab - 1]))
        ecc_out.append(float(ecc[lab - 1]))
    if not uv:
        return _empty_detections("no marker candidates", thr)
    uv_a = np.asarray(uv)
    rho_a = np.asarray(rho)
    pts = points_from_pixel_range(uv_a[:, 0], uv_a[:, 1], rho_a, camera)
    return MarkerDetections(uv_a, rho_a, pts, np.asarray(rho_sig), np.asarray(cnt, int), np.asarray(ecc_out), thr, "")


def _dilate(mask: np.ndarray, px: int) -> np.ndarray:
    if px <= 0:
        return mask.copy()
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * px + 1, 2 * px + 1))
    return cv2.dilate(mask.astype(np.uint8), k).astype(bool)


def _plane_range(u: np.ndarray, v: np.ndarray, r: np.ndarray, uc: float, vc: float,
                 camera: TofCamera) -> tuple[float, float] | None:
    """Range along the ray of ``(uc, vc)`` to the plane through the plate pixels around it, and its σ.

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
    return float(coef[0]), float(np.sqrt(var0))


# --------------------------------------------------------------------------------------------
# 2. Matching (000 §3)
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class MatchSettings:
    """Settings of the MRF deterministic-annealing matcher (SEEDS_SPEC §1.3.4 defaults).

    Attributes
    ----------
    alpha_m : float
        α, the distance-consistency threshold (3–5 × the 3-D point noise).
    truncation : float or None
        τ of the truncated pair potential ``min(ρ², (τα)²)``; None is the paper's ``ρ²``.
    beta0, beta_max : float
        Start and end inverse temperature, in units of ``1/α²``.
    rate : float
        Annealing rate ``c`` of eq (23), ``β ← c β``.
    damping : float
        Fraction of the new field taken per sweep, ``A ← (1−λ) A + λ softmax(·)`` (1 = undamped).
    tol : float
        Fixed point reached at a temperature when ``max |ΔA| < tol``.
    max_sweeps : int
        Sweeps per temperature at most (1 = the paper's single sweep).
    sinkhorn : bool
        Alternate row/column normalisation with a slack row and column (softassign).
    sinkhorn_iterations : int
    """

    alpha_m: float = 0.010
    truncation: float | None = 2.0
    beta0: float = 1e-3
    beta_max: float = 1e2
    rate: float = 1.2
    damping: float = 0.5
    tol: float = 1e-3
    max_sweeps: int = 50
    sinkhorn: bool = False
    sinkhorn_iterations: int = 20

    def __post_init__(self) -> None:
        for key in ("alpha_m", "beta0", "beta_max", "tol"):
            v = getattr(self, key)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{key}: must be finite and > 0, got {v!r}")
        if self.truncation is not None and (not np.isfinite(self.truncation) or self.truncation <= 1):
            raise ValueError(f"truncation: must be None or > 1, got {self.truncation!r}")
        if not self.rate > 1:
            raise ValueError(f"rate: must be > 1, got {self.rate!r}")
        if not 0 < self.damping <= 1:
            raise ValueError(f"damping: must lie in (0, 1], got {self.damping!r}")
        if int(self.max_sweeps) != self.max_sweeps or self.max_sweeps < 1:
            raise ValueError(f"max_sweeps: must be an integer >= 1, got {self.max_sweeps!r}")


#: The paper's schedule: one undamped sweep per temperature, unbounded ρ² potential.
LITERAL_SETTINGS = MatchSettings(truncation=None, beta0=1e-4, rate=1.1, damping=1.0, max_sweeps=1)


@dataclass(frozen=True)
class MarkerMatch:
    """Labels of the observed key points.

    Attributes
    ----------
    labels : (..., n) int ndarray
        Model index of every observation, −1 for the null label (no model counterpart).
    assignment : (..., n, q+1) ndarray
        The matrix ``A`` of eq (22) (column 0 = null); for the Hungarian baseline, the 0/1 assignment.
    n_temperatures, n_sweeps : int
        Temperatures visited and total fixed-point sweeps (0 for the Hungarian baseline).
    method : str
    """

    labels: np.ndarray
    assignment: np.ndarray
    n_temperatures: int
    n_sweeps: int
    method: str


def _check_points(model_C: ArrayLike, points_S: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    m = np.asarray(model_C, dtype=float)
    if m.ndim != 2 or m.shape[1] != 3 or len(m) < 3 or not np.all(np.isfinite(m)):
        raise ValueError(f"model_C: expected a finite (q >= 3, 3) array, got shape {m.shape}")
    p = np.asarray(points_S, dtype=float)
    if p.ndim < 2 or p.shape[-1] != 3 or not np.all(np.isfinite(p)):
        raise ValueError(f"points_S: expected a finite (..., n, 3) array, got shape {p.shape}")
    return m, p


def _pair_energy(model_C: np.ndarray, points_S: np.ndarray, alpha: float, truncation: float | None) -> np.ndarray:
    """``W[..., k, i, l, j] = V(ρ_klij) − α²`` reshaped to ``(..., n q, n q)`` (flag P000-6)."""
    q = len(model_C)
    n = points_S.shape[-2]
    dm = np.linalg.norm(model_C[:, None] - model_C[None], axis=-1)                       # (q, q)
    do = np.linalg.norm(points_S[..., :, None, :] - points_S[..., None, :, :], axis=-1)  # (..., n, n)
    rho2 = (do[..., :, :, None, None] - dm) ** 2                                           # (..., k, l, i, j)
    if truncation is not None:
        rho2 = np.minimum(rho2, (truncation * alpha) ** 2)
    w = rho2 - alpha**2
    w = np.swapaxes(w, -3, -2)                                                              # (..., k, i, l, j)
    return w.reshape(points_S.shape[:-2] + (n * q, n * q))


def _anneal(model_C: np.ndarray, points_S: np.ndarray, st: MatchSettings) -> tuple[np.ndarray, int, int]:
    """Mean-field annealing of eqs (19), (23)–(26) corrected; returns ``(A, n_temperatures, n_sweeps)``."""
    q = len(model_C)
    batch = points_S.shape[:-2]
    n = points_S.shape[-2]
    alpha = st.alpha_m
    W = _pair_energy(model_C, points_S, alpha, st.truncation)
    A = np.full(batch + (n, q + 1), 1.0 / (q + 1))
    beta = st.beta0 / alpha**2
    beta_end = st.beta_max / alpha**2
    n_t = n_s = 0
    while beta < beta_end:
        n_t += 1
        for _ in range(int(st.max_sweeps)):
            n_s += 1
            # E[k, i] = Σ_l Σ_j W[k,i,l,j] A[l,j]  (the null label's energy is 0: eq 19/24)
            e = (W @ A[..., 1:].reshape(batch + (n * q, 1))).reshape(batch + (n, q))
            logits = np.concatenate([np.zeros(batch + (n, 1)), -beta * e], axis=-1)
            logits -= logits.max(axis=-1, keepdims=True)
            F = np.exp(logits)
            new = _sinkhorn(F, st.sinkhorn_iterations) if st.sinkhorn else F / F.sum(-1, keepdims=True)
            new = (1.0 - st.damping) * A + st.damping * new
            delta = float(np.abs(new - A).max()) if new.size else 0.0
            A = new
            if delta < st.tol:
                break
        if A.size and float((1.0 - A.max(axis=-1)).max()) < 1e-3:
            break
        beta *= st.rate
    return A, n_t, n_s


def _sinkhorn(F: np.ndarray, iterations: int) -> np.ndarray:
    """Softassign: alternate row (observations, over labels 0..q) and column (model 1..q)
    normalisation with a slack row for unmatched model markers; returns row-stochastic A."""
    n = F.shape[-2]
    M = np.concatenate([F, np.ones(F.shape[:-2] + (1, F.shape[-1]))], axis=-2)
    M[..., n, 0] = 0.0
    for _ in range(iterations):
        M[..., :n, :] /= M[..., :n, :].sum(-1, keepdims=True)
        M[..., :, 1:] /= M[..., :, 1:].sum(-2, keepdims=True)
    A = M[..., :n, :]
    return A / A.sum(-1, keepdims=True)


def _decode(A: np.ndarray) -> np.ndarray:
    """Labels from ``A`` (flag P000-8: the label of row k is its arg max over 0..q), null when
    the winning probability is below ½, and one observation per model marker (the most probable)."""
    lab = A.argmax(axis=-1) - 1
    best = A.max(axis=-1)
    lab = np.where(best < 0.5, -1, lab)
    flat_lab = lab.reshape(-1, lab.shape[-1])
    flat_best = best.reshape(-1, lab.shape[-1])
    for row, pb in zip(flat_lab, flat_best, strict=True):
        for i in np.unique(row[row >= 0]):
            who = np.flatnonzero(row == i)
            if who.size > 1:
                row[who[who != who[np.argmax(pb[who])]]] = -1
    return flat_lab.reshape(lab.shape)


def match_markers_mrf(model_C: ArrayLike, points_S: ArrayLike, *, settings: MatchSettings | None = None) -> MarkerMatch:
    """MRF mean-field deterministic-annealing matcher with the null label, corrected (000 §3).

    Energies (flag P000-6): ``E_ki = Σ_l Σ_{j≥1} A_lj (V(ρ_klij) − α²)`` for labels ``i ≥ 1`` and
    ``E_k0 = 0``, with ``ρ_klij = d̃_kl − d_ij`` (eqs 13–14) and ``V = min(ρ², (τα)²)`` (τ =
    ``settings.truncation``; ``None`` gives the paper's ``ρ²``); the ``l = k`` terms are kept.
    Update (flag P000-7): row-wise softmax ``A_ki ∝ exp(−β E_ki)`` over ``i = 0..q`` (optionally
    Sinkhorn), iterated to a fixed point at every β (flag P000-9), then ``β ← c β`` (eq 23) from
    ``β0/α²`` to ``β_max/α²``.  Decoding: flag P000-8.

    Parameters
    ----------
    model_C : (q, 3) array_like
        Model marker positions in frame C (m).
    points_S : (..., n, 3) array_like
        Observed key points in frame S (m); leading axes are independent problems (vectorised).
    settings : MatchSettings, optional

    Returns
    -------
    MarkerMatch
    """
    m, p = _check_points(model_C, points_S)
    st = settings or MatchSettings()
    A, n_t, n_s = _anneal(m, p, st)
    return MarkerMatch(_decode(A), A, n_t, n_s, "mrf" + ("-sinkhorn" if st.sinkhorn else ""))


def match_markers_mrf_literal(model_C: ArrayLike, points_S: ArrayLike, *, alpha_m: float = 0.010) -> MarkerMatch:
    """The paper's matcher as printed, made executable (for comparison).

    Kept from the paper: the unbounded potential ``ρ²``, a single synchronous sweep per temperature
    (eq 24 uses ``A^(m−1)``), the schedule of eqs (23), (26).  Changed only where the printed text
    cannot be executed: the four-index ``ρ_klij`` (the printed ``ρ_kij`` has no ``l``, P000-6) and
    the row normaliser of eq (25) (the printed ``Σ_k F_kk`` is a diagonal that does not exist for
    ``n ≠ q``, P000-7).
    """
    import dataclasses

    st = dataclasses.replace(LITERAL_SETTINGS, alpha_m=alpha_m)
    m, p = _check_points(model_C, points_S)
    A, n_t, n_s = _anneal(m, p, st)
    return MarkerMatch(_decode(A), A, n_t, n_s, "mrf-literal")


def match_markers_hungarian(model_C: ArrayLike, points_S: ArrayLike, *, alpha_m: float = 0.010,
                            truncation: float = 2.0) -> MarkerMatch:
    """Baseline: linear assignment on distance-matrix consistency.

    Cost of observation k taking model label i: ``C_ki = Σ_{l≠k} min(min_{j≠i} |d̃_kl − d_ij|, τα)``
    (how badly k's distances to the other observations fit i's distances to the other markers,
    each term capped); ``n`` null columns cost ``½ (n − 1) τ α`` each.  Solved by
    ``scipy.optimize.linear_sum_assignment`` per problem.
    """
    m, p = _check_points(model_C, points_S)
    q = len(m)
    n = p.shape[-2]
    cap = truncation * alpha_m
    dm = np.linalg.norm(m[:, None] - m[None], axis=-1)
    dm_off = np.where(np.eye(q, dtype=bool), np.inf, dm)                                    # exclude j = i
    do = np.linalg.norm(p[..., :, None, :] - p[..., None, :, :], axis=-1)                   # (..., n, n)
    gap = np.abs(do[..., :, :, None, None] - dm_off).min(axis=-1)                           # (..., k, l, i)
    gap = np.minimum(gap, cap)
    off = ~np.eye(n, dtype=bool)
    cost = (gap * off[..., :, :, None]).sum(axis=-2)                                        # (..., k, i)
    null_cost = 0.5 * max(n - 1, 1) * cap
    flat = cost.reshape(-1, n, q)
    labels = np.full(flat.shape[:2], -1, dtype=int)
    A = np.zeros(flat.shape[:2] + (q + 1,))
    for b, c in enumerate(flat):
        full = np.concatenate([c, np.full((n, n), null_cost)], axis=1)
        rows, cols = linear_sum_assignment(full)
        lab = np.where(cols < q, cols, -1)
        labels[b, rows] = lab
        A[b, rows, lab + 1] = 1.0
    return MarkerMatch(labels.reshape(p.shape[:-1]), A.reshape(p.shape[:-1] + (q + 1,)), 0, 0, "hungarian")


# --------------------------------------------------------------------------------------------
# 3. Pose (000 §4)
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class RigidFit:
    """Weighted absolute orientation ``p ≈ R q + r`` (000 eqs 27–38).

    Attributes
    ----------
    R_SC : (..., 3, 3) ndarray
    r_CS_S : (..., 3) ndarray
    singular_values : (..., 3) ndarray
        Of the weighted cross-covariance ``B`` (eq 33); ``σ₂ ≈ 0`` means collinear points.
    rms_residual_m : (...,) ndarray
        Weighted RMS of ``|p_i − R q_i − r|``.
    """

    R_SC: np.ndarray
    r_CS_S: np.ndarray
    singular_values: np.ndarray
    rms_residual_m: np.ndarray


def weighted_svd_pose(q_C: ArrayLike, p_S: ArrayLike, weights: ArrayLike | None = None) -> RigidFit:
    """Weighted SVD pose, 000 eqs (27)–(38) with flag P000-10 (Kabsch / Umeyama).

    ``q̄ = Σ w q / Σ w``, ``p̄ = Σ w p / Σ w`` (eq 30); ``B = Σ w (p − p̄)(q − q̄)ᵀ = U D Vᵀ``
    (eqs 33–34, centred); ``R = U diag(1, 1, det U det V) Vᵀ`` (eq 37); ``r = p̄ − R q̄`` (eq 38).

    Parameters
    ----------
    q_C : (..., m, 3) array_like
        Model points in C (m), m ≥ 3 (weights of 0 remove a point).
    p_S : (..., m, 3) array_like
        Matched measured points in S (m).
    weights : (..., m) array_like, optional
        Non-negative weights ``w_i`` (eq 28); default 1.
    """
    q = np.asarray(q_C, dtype=float)
    p = np.asarray(p_S, dtype=float)
    if q.shape[-1:] != (3,) or p.shape[-1:] != (3,) or q.shape[-2] < 3:
        raise ValueError(f"q_C, p_S: expected (..., m >= 3, 3) arrays, got {q.shape} and {p.shape}")
    q, p = np.broadcast_arrays(q, p)
    w = np.ones(p.shape[:-1]) if weights is None else np.broadcast_to(np.asarray(weights, dtype=float), p.shape[:-1])
    if np.any(w < 0) or not np.all(np.isfinite(w)):
        raise ValueError("weights: must be finite and >= 0")
    ws = w.sum(axis=-1, keepdims=True)
    if np.any(ws <= 0):
        raise ValueError("weights: every problem needs a positive total weight")
    qb = (w[..., None] * q).sum(-2) / ws
    pb = (w[..., None] * p).sum(-2) / ws
    B = np.einsum("...m,...mi,...mj->...ij", w, p - pb[..., None, :], q - qb[..., None, :])
    U, D, Vt = np.linalg.svd(B)
    s = np.sign(np.linalg.det(U) * np.linalg.det(Vt))
    s = np.where(s == 0, 1.0, s)
    Dm = np.zeros(B.shape)
    Dm[..., 0, 0] = 1.0
    Dm[..., 1, 1] = 1.0
    Dm[..., 2, 2] = s
    R = U @ Dm @ Vt
    r = pb - np.einsum("...ij,...j->...i", R, qb)
    res = p - (np.einsum("...ij,...mj->...mi", R, q) + r[..., None, :])
    rms = np.sqrt((w * (res**2).sum(-1)).sum(-1) / ws[..., 0])
    return RigidFit(R, r, D, rms)


def verify_labels(model_C: ArrayLike, points_S: ArrayLike, labels: ArrayLike, *, gate_m: float) -> np.ndarray:
    """Pose check of a labelling (SEEDS_SPEC §1.3.4): consensus, re-solve, re-assign.

    Among the labelled observations, every triple of matches gives a pose
    (:func:`weighted_svd_pose`, all triples in one batch); the pose that brings the most labelled
    observations within ``gate_m`` of their markers wins (ties: smallest summed residual), and is
    refitted on those inliers.  Every observation is then assigned to the predicted markers by
    linear assignment on the 3-D distance, keeping pairs closer than ``gate_m``: this drops
    spurious points that took a label, repairs swapped labels and recovers markers the matcher
    left null.  Fewer than three consistent matches: all null.

    Parameters
    ----------
    model_C : (q, 3) array_like
    points_S : (..., n, 3) array_like
    labels : (..., n) int array_like
    gate_m : float

    Returns
    -------
    (..., n) int ndarray of verified labels (−1 = null).
    """
    from itertools import combinations

    m, p = _check_points(model_C, points_S)
    lab_in = np.asarray(labels, dtype=int)
    if lab_in.shape != p.shape[:-1]:
        raise ValueError(f"labels: expected shape {p.shape[:-1]}, got {lab_in.shape}")
    if not np.isfinite(gate_m) or gate_m <= 0:
        raise ValueError(f"gate_m: must be finite and > 0, got {gate_m!r}")
    n = p.shape[-2]
    flat_p = p.reshape(-1, n, 3)
    flat_l = lab_in.reshape(-1, n)
    out = np.full_like(flat_l, -1)
    for b in range(len(flat_p)):
        idx = np.flatnonzero(flat_l[b] >= 0)
        if idx.size < 3:
            continue
        obs, mod = flat_p[b, idx], m[flat_l[b, idx]]
        tri = np.array(list(combinations(range(idx.size), 3)))
        fits = weighted_svd_pose(mod[tri], obs[tri])
        pred = np.einsum("tij,mj->tmi", fits.R_SC, mod) + fits.r_CS_S[:, None, :]
        res = np.linalg.norm(pred - obs, axis=-1)                                   # (triples, m)
        inl = res <= gate_m
        proper = fits.singular_values[:, 1] > 1e-6 * fits.singular_values[:, 0]
        score = np.where(proper, inl.sum(-1) - np.where(inl, res, 0).sum(-1) / (gate_m * idx.size + 1e-300), -1)
        best = int(np.argmax(score))
        keep = inl[best]
        if keep.sum() < 3 or not proper[best]:
            continue
        fit = weighted_svd_pose(mod[keep], obs[keep])
        pred = m @ fit.R_SC.T + fit.r_CS_S
        dist = np.linalg.norm(flat_p[b, :, None, :] - pred[None], axis=-1)
        rows, cols = linear_sum_assignment(np.where(dist <= gate_m, dist, 1e6 * gate_m))
        ok = dist[rows, cols] <= gate_m
        if ok.sum() >= 3:
            out[b, rows[ok]] = cols[ok]
    return out.reshape(lab_in.shape)


def pitch_yaw_roll_from_matrix(R_SC: ArrayLike) -> np.ndarray:
    """Pitch, yaw, roll (rad) of ``R_SC`` for the 3-2-1 sequence ``R = R_z(yaw) R_y(pitch) R_x(roll)``.

    Returns ``(..., 3)`` in the paper's column order (pitch, yaw, roll).
    """
    ang, _ = euler_from_matrix(R_SC, "321")
    return np.stack([ang[..., 1], ang[..., 0], ang[..., 2]], axis=-1)


# --------------------------------------------------------------------------------------------
# 4. The pipeline
# --------------------------------------------------------------------------------------------

#: Matcher names accepted by :func:`estimate_tof_pose`.
MATCHERS = ("mrf", "mrf-sinkhorn", "mrf-literal", "hungarian")


@dataclass(frozen=True)
class TofPoseResult:
    """Pose of the marker plate from one TOF frame.

    Attributes
    ----------
    found : bool
        False when the target was not found; ``reason`` says why and the pose fields are NaN.
    reason : str
        Empty when found; otherwise e.g. "all pixels saturated", "too few markers detected (2 < 3)".
    R_SC : (3, 3) ndarray
        Rotation C → S (000's ``T``).
    r_CS_S : (3,) ndarray
        Position of the plate origin in S (m): the reported x, y, z.
    pitch_yaw_roll_rad : (3,) ndarray
        3-2-1 Euler angles of ``R_SC`` in the order pitch, yaw, roll (see module docstring).
    labels : (n,) int ndarray
        Model index of every detection (−1: not a model marker).
    n_matched : int
    rms_residual_m : float
        Weighted RMS 3-D residual of the matched markers after the fit.
    detections : MarkerDetections
    """

    found: bool
    reason: str
    R_SC: np.ndarray
    r_CS_S: np.ndarray
    pitch_yaw_roll_rad: np.ndarray
    labels: np.ndarray
    n_matched: int
    rms_residual_m: float
    detections: MarkerDetections

    @property
    def pitch_yaw_roll_deg(self) -> np.ndarray:
        return np.degrees(self.pitch_yaw_roll_rad)


def _not_found(reason: str, det: MarkerDetections, labels: np.ndarray | None = None) -> TofPoseResult:
    nan3 = np.full(3, np.nan)
    lab = labels if labels is not None else np.full(det.n, -1, dtype=int)
    return TofPoseResult(False, reason, np.full((3, 3), np.nan), nan3, nan3.copy(), lab,
                         int((lab >= 0).sum()), float("nan"), det)


def estimate_tof_pose(frame: TofFrame, camera: TofCamera, plate: MarkerPlate, *, matcher: str = "mrf",
                      match_settings: MatchSettings | None = None,
                      extraction: ExtractionSettings | None = None, verify: bool = True,
                      gate_factor: float = 2.0, weighting: str = "inverse_variance") -> TofPoseResult:
    """Relative pose of the marker plate from one TOF frame (000 §2–§4, corrected).

    Parameters
    ----------
    frame : TofFrame
    camera : TofCamera
    plate : MarkerPlate
        The model: marker positions ``q_i`` in C and the marker radius.
    matcher : {"mrf", "mrf-sinkhorn", "mrf-literal", "hungarian"}
    match_settings : MatchSettings, optional
        For the MRF matchers (α also sets the Hungarian cap and the verification gate).
    extraction : ExtractionSettings, optional
    verify : bool
        Run :func:`verify_labels` with gate ``gate_factor × α`` after matching.
    gate_factor : float
    weighting : {"inverse_variance", "uniform"}
        SVD weights ``w_i`` (eq 28): ``1 / σ_i²`` from the range standard error of each key point
        (floored at 0.1 mm), or 1.

    Returns
    -------
    TofPoseResult
        ``found=False`` with a reason (never an exception) for frames without a usable target.
    """
    if matcher not in MATCHERS:
        raise ValueError(f"matcher: must be one of {MATCHERS}, got {matcher!r}")
    if weighting not in ("inverse_variance", "uniform"):
        raise ValueError(f"weighting: must be 'inverse_variance' or 'uniform', got {weighting!r}")
    st = match_settings or MatchSettings()
    det = extract_markers(frame, camera, plate, settings=extraction)
    if det.reason:
        return _not_found(det.reason, det)
    if det.n < 3:
        return _not_found(f"too few markers detected ({det.n} < 3)", det)
    model = plate.markers_C
    if matcher == "mrf":
        match = match_markers_mrf(model, det.points_S, settings=st)
    elif matcher == "mrf-sinkhorn":
        import dataclasses

        match = match_markers_mrf(model, det.points_S, settings=dataclasses.replace(st, sinkhorn=True))
    elif matcher == "mrf-literal":
        match = match_markers_mrf_literal(model, det.points_S, alpha_m=st.alpha_m)
    else:
        match = match_markers_hungarian(model, det.points_S, alpha_m=st.alpha_m,
                                        truncation=st.truncation or 2.0)
    labels = match.labels
    if verify:
        labels = verify_labels(model, det.points_S, labels, gate_m=gate_factor * st.alpha_m)
    sel = np.flatnonzero(labels >= 0)
    if sel.size < 3:
        return _not_found(f"too few markers matched ({sel.size} < 3)", det, labels)
    if weighting == "uniform":
        w = np.ones(sel.size)
    else:
        w = 1.0 / np.maximum(det.range_sigma_m[sel], 1e-4) ** 2
    fit = weighted_svd_pose(model[labels[sel]], det.points_S[sel], w)
    if fit.singular_values[1] <= 1e-6 * fit.singular_values[0]:
        return _not_found("matched markers are collinear", det, labels)
    return TofPoseResult(True, "", fit.R_SC, fit.r_CS_S, pitch_yaw_roll_from_matrix(fit.R_SC), labels,
                         int(sel.size), float(fit.rms_residual_m), det)


# --------------------------------------------------------------------------------------------
# 5. Random matching problems (Monte Carlo of SEEDS_SPEC Appendix A.5)
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class MatchingTrials:
    """A batch of synthetic matching problems with their true labels.

    Attributes
    ----------
    points_S : (T, n, 3) ndarray
        Observed points (m), in random order.
    truth : (T, n) int ndarray
        Model index of every observed point, −1 for a spurious point.
    """

    points_S: np.ndarray
    truth: np.ndarray


def random_matching_trials(plate: MarkerPlate, n_trials: int, *, n_missing: int = 0, n_spurious: int = 0,
                           spurious: str = "volume", noise_m: float = 0.002, range_m: float = 0.7,
                           spurious_sigma_m: float = 0.150,
                           rng: np.random.Generator | int | None = None) -> MatchingTrials:
    """Random observations of the plate's markers: the experiment of SEEDS_SPEC Appendix A.5.

    Each trial draws a uniformly random rotation (distances do not depend on it), places the plate
    origin at ``[0, 0, range_m]``, adds isotropic Gaussian noise ``noise_m`` to every point, removes
    ``n_missing`` random markers and adds ``n_spurious`` spurious points, then shuffles.

    Parameters
    ----------
    spurious : {"volume", "plate"}
        ``"volume"``: spurious point at the centroid of the observed points plus isotropic Gaussian
        ``spurious_sigma_m`` (A.5).  ``"plate"``: a dark blob on the plate, uniform over the plate
        at least two marker diameters from every marker (a blob closer than that would merge with
        the marker in the image), moved with the plate and noised like the markers.
    """
    if int(n_trials) != n_trials or n_trials < 1:
        raise ValueError(f"n_trials: must be an integer >= 1, got {n_trials!r}")
    q = plate.n_markers
    if not 0 <= n_missing <= q - 3:
        raise ValueError(f"n_missing: must lie in [0, {q - 3}], got {n_missing!r}")
    if n_spurious < 0:
        raise ValueError(f"n_spurious: must be >= 0, got {n_spurious!r}")
    if spurious not in ("volume", "plate"):
        raise ValueError(f"spurious: must be 'volume' or 'plate', got {spurious!r}")
    if not np.isfinite(noise_m) or noise_m < 0:
        raise ValueError(f"noise_m: must be finite and >= 0, got {noise_m!r}")
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(rng)
    T = int(n_trials)
    R = Rotation.random(T, random_state=rng).as_matrix()
    model = plate.markers_C
    r = np.array([0.0, 0.0, range_m])
    obs_idx = np.argsort(rng.random((T, q)), axis=1)[:, : q - n_missing]            # kept markers
    pts = np.einsum("tij,tmj->tmi", R, model[obs_idx]) + r
    truth = obs_idx.copy()
    if n_spurious:
        if spurious == "volume":
            extra = pts.mean(axis=1, keepdims=True) + spurious_sigma_m * rng.standard_normal((T, n_spurious, 3))
        else:
            xy = _random_plate_points(plate, T * n_spurious, rng).reshape(T, n_spurious, 2)
            extra = np.einsum("tij,tmj->tmi", R, np.concatenate([xy, np.zeros((T, n_spurious, 1))], -1)) + r
        pts = np.concatenate([pts, extra], axis=1)
        truth = np.concatenate([truth, np.full((T, n_spurious), -1)], axis=1)
    pts = pts + noise_m * rng.standard_normal(pts.shape)
    perm = np.argsort(rng.random(truth.shape), axis=1)
    return MatchingTrials(np.take_along_axis(pts, perm[..., None], axis=1), np.take_along_axis(truth, perm, axis=1))


def _random_plate_points(plate: MarkerPlate, count: int, rng: np.random.Generator) -> np.ndarray:
    half = np.array([plate.width_m, plate.height_m]) / 2 - plate.marker_radius_m
    markers = np.asarray(plate.markers_xy_m)
    out = np.empty((0, 2))
    while len(out) < count:
        xy = rng.uniform(-half, half, size=(2 * count + 16, 2))
        far = np.linalg.norm(xy[:, None] - markers[None], axis=-1).min(axis=1) >= 4 * plate.marker_radius_m
        out = np.concatenate([out, xy[far]])
    return out[:count]
