"""Intrinsic and extrinsic calibration of an orthogonal cylindrical-imaging camera (paper 004 §2.3).

1. **Intrinsic calibration** (004 eq 12–14, flags P004-5/P004-6, docs/papers.md#p004-5): a
   non-parametric mapping ``(u, v) → (α, β)`` fitted by radial basis functions
   (``scipy.interpolate.RBFInterpolator``, multiquadric kernel, linear polynomial tail, coordinates
   scaled to [0, 1]) to samples from a turntable-and-rail rig (:func:`simulate_turntable_calibration`),
   and its inverse ``(α, β) → (u, v)`` fitted on the swapped samples (flag P004-10b,
   docs/papers.md#p004-10) for prediction.
2. **Extrinsic calibration** (004 eq 15–20, flags P004-7..9, docs/papers.md#p004-7): the linear solve of
   the 2n equations (16)–(17) (SVD null vector, ≥ 6 points), projection onto SO(3), then
   Levenberg–Marquardt (``scipy.optimize.least_squares``) on the angular residuals with a
   rotation-vector parameterisation; the paper's penalty form (20) is an option.

Frames: ``W`` is the world (laser-tracker) frame; ``C`` a camera frame (``z`` boresight, ``x`` right,
``y`` down); 004 eq (15) maps world to camera, ``x_C = R_CW X_W + t_CW`` (flag P004-7).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import RBFInterpolator
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

from attitude.matrix import orthonormalize, rot_y
from attitude.quaternion import matrix_from_quat, quat_from_rotvec
from chaser.cylindrical._arrays import as_pairs, as_points
from vision.cylindrical import CylindricalCamera, angles_from_points, measure_spot_centres

__all__ = [
    "TurntableSamples",
    "tracker_sigma_m",
    "simulate_turntable_calibration",
    "IntrinsicCalibration",
    "fit_intrinsic_rbf",
    "ExtrinsicCalibration",
    "calibrate_extrinsics",
]


# =============================================================================== intrinsic calibration
@dataclass(frozen=True, eq=False)
class TurntableSamples:
    """Intrinsic calibration samples of one camera from the turntable-and-rail rig (004 §2.3).

    Attributes
    ----------
    uv_px : (N, 2) ndarray
        Measured spot centres on CCD1 and CCD2 (px).
    alpha_beta_rad : (N, 2) ndarray
        Reference angles ``(α_i, β_i)`` (rad) computed from the tracker-measured light point and the
        turntable reading; they carry the tracker and turntable errors.
    alpha_beta_true_rad : (N, 2) ndarray
        The true angles (simulation truth, for diagnostics only).
    """

    uv_px: np.ndarray
    alpha_beta_rad: np.ndarray
    alpha_beta_true_rad: np.ndarray


def tracker_sigma_m(distance_m: ArrayLike, *, mpe_const_m: float = 15e-6, mpe_per_m: float = 6e-6) -> np.ndarray:
    """Per-axis standard deviation of a laser-tracker coordinate from its MPE ``±(15 µm + 6 µm/m)``.

    The Leica AT901 specification of 004 §4.1 in the corrected reading of flag P004-11.  The MPE
    ``U_xyz`` bounds the error of the 3-D coordinate and its typical value is half of it (the
    manufacturer's convention), so the 3-D RMS error is ``U_xyz / 2`` and each axis gets
    ``U_xyz / (2 √3)``: 5.3 µm at 2 m, 11 µm at 3.7 m.
    """
    return (mpe_const_m + mpe_per_m * np.asarray(distance_m, dtype=float)) / (2.0 * np.sqrt(3.0))


def simulate_turntable_calibration(
    camera: CylindricalCamera,
    *,
    rng: np.random.Generator | int | None = None,
    rail_distance_m: float = 3.0,
    alpha_max_deg: float = 14.0,
    alpha_step_deg: float = 1.0,
    beta_max_deg: float = 14.0,
    rail_step_m: float = 0.06,
    tracker_distance_m: float = 2.0,
    turntable_sigma_rad: float = 1.0e-6,
    axis_offset_m: ArrayLike = (0.0, 0.0, 0.0),
    n_scans: int = 20,
    method: str = "threshold_centroid",
) -> TurntableSamples:
    """Simulate the non-parametric calibration rig of 004 §2.3 (Fig. 4–5) for one camera.

    The camera sits on a one-axis turntable whose axis is the camera ``y`` axis through the optical
    centre; a light point is moved along a vertical rail at ``rail_distance_m`` in steps of
    ``rail_step_m`` (its position measured once per stop by the laser tracker, error
    :func:`tracker_sigma_m` at ``tracker_distance_m``); at each stop the turntable turns in steps of
    ``alpha_step_deg`` (encoder error ``turntable_sigma_rad``; 0.6″ full-range accuracy in 004) and
    the spot centres are measured, averaged over ``n_scans`` line scans.  The reference angles are
    ``α_i = atan(x_C/z_C)``, ``β_i = atan(y_C/z_C)`` of the tracker-measured point rotated by the
    turntable reading.  ``axis_offset_m`` (camera frame) is where the turntable axis really passes
    when the optical centre is not adjusted exactly onto it (004 step 1); the reference angles
    assume it passes through the optical centre, so an offset is a systematic calibration error.

    Returns
    -------
    TurntableSamples
        Samples whose spots fall on both CCDs.
    """
    rng = np.random.default_rng(rng)
    for name, v in (("rail_distance_m", rail_distance_m), ("alpha_step_deg", alpha_step_deg),
                    ("rail_step_m", rail_step_m), ("alpha_max_deg", alpha_max_deg), ("beta_max_deg", beta_max_deg)):
        if not np.isfinite(v) or v <= 0:
            raise ValueError(f"{name}: must be positive, got {v!r}")
    if turntable_sigma_rad < 0 or tracker_distance_m < 0:
        raise ValueError("turntable_sigma_rad, tracker_distance_m: must be >= 0")
    theta = np.deg2rad(np.arange(-alpha_max_deg, alpha_max_deg + 1e-9, alpha_step_deg))
    h_max = rail_distance_m * np.tan(np.deg2rad(beta_max_deg))
    heights = np.arange(-h_max, h_max + 1e-12, rail_step_m)
    # light point in the camera frame at turntable angle 0: (0, h, D); tracker measures it with error
    P_true = np.stack([np.zeros_like(heights), heights, np.full_like(heights, rail_distance_m)], -1)
    P_meas = P_true + rng.standard_normal(P_true.shape) * tracker_sigma_m(tracker_distance_m)
    off = np.asarray(axis_offset_m, dtype=float)
    if off.shape != (3,) or not np.all(np.isfinite(off)):
        raise ValueError(f"axis_offset_m: expected 3 finite numbers, got {axis_offset_m!r}")
    th_true = theta[None, :] + rng.standard_normal((heights.size, theta.size)) * turntable_sigma_rad
    # turning the camera by θ about its y axis (through ``off``) shows the point at R_y(θ)(P − off) + off
    X_true = np.einsum("hkij,hj->hki", rot_y(th_true), P_true - off) + off
    X_ref = np.einsum("kij,hj->hki", rot_y(np.broadcast_to(theta, th_true.shape[1:])), P_meas)
    ab_true = angles_from_points(X_true).reshape(-1, 2)
    ab_ref = angles_from_points(X_ref).reshape(-1, 2)
    uv_true = camera.pixels_from_angles(ab_true)
    uv = measure_spot_centres(camera, uv_true, rng=rng, n_scans=n_scans, method=method)
    ok = np.isfinite(uv).all(-1)
    return TurntableSamples(uv[ok], ab_ref[ok], ab_true[ok])


@dataclass(frozen=True, eq=False)
class IntrinsicCalibration:
    """Non-parametric intrinsic calibration of one camera (004 eq 12–14) and its inverse.

    ``angles_from_pixels`` is 004 eq (12)–(13): ``α(u, v) = Σ c₁ᵢ ψᵢ(u, v) + c₂ᵀ [1, u, v]`` with the
    multiquadric ``ψᵢ = sqrt((u − uᵢ)² + (v − vᵢ)² + χ²)`` (corrected eq 14, flag P004-5) and the linear
    tail (flag P004-6), in coordinates scaled to [0, 1].  ``pixels_from_angles`` is the inverse map
    fitted on the swapped samples (flag P004-10b).

    Attributes
    ----------
    forward, inverse : scipy.interpolate.RBFInterpolator
        ``(u, v)`` scaled → ``(α, β)`` rad, and ``(α, β)`` scaled → ``(u, v)`` px.
    uv_lo_px, uv_span_px, ab_lo_rad, ab_span_rad : (2,) ndarray
        Affine scaling of the inputs to [0, 1].
    shape_chi : float
        Multiquadric shape parameter χ in scaled units (scipy's ``epsilon = 1/χ``).
    smoothing : float
        scipy's ``smoothing`` (0 = interpolation).
    n_samples : int
    holdout_rms_rad : float
        RMS error of the forward map on samples held out during the choice of χ and smoothing
        (against the reference angles, so it includes their errors).
    """

    forward: RBFInterpolator
    inverse: RBFInterpolator
    uv_lo_px: np.ndarray
    uv_span_px: np.ndarray
    ab_lo_rad: np.ndarray
    ab_span_rad: np.ndarray
    shape_chi: float
    smoothing: float
    n_samples: int
    holdout_rms_rad: float

    def angles_from_pixels(self, uv_px: ArrayLike) -> np.ndarray:
        """``(u, v)`` px ``(..., 2)`` → ``(α, β)`` rad ``(..., 2)`` (004 eq 12–13); NaN stays NaN."""
        uv = as_pairs(uv_px, "uv_px")
        return self._eval(self.forward, (uv - self.uv_lo_px) / self.uv_span_px)

    def pixels_from_angles(self, alpha_beta_rad: ArrayLike) -> np.ndarray:
        """Inverse map ``(α, β)`` rad → ``(u, v)`` px (flag P004-10b); NaN stays NaN."""
        ab = as_pairs(alpha_beta_rad, "alpha_beta_rad")
        return self._eval(self.inverse, (ab - self.ab_lo_rad) / self.ab_span_rad)

    @staticmethod
    def _eval(interp: RBFInterpolator, x: np.ndarray) -> np.ndarray:
        flat = x.reshape(-1, 2)
        out = np.full(flat.shape, np.nan)
        ok = np.isfinite(flat).all(-1)
        if np.any(ok):
            out[ok] = interp(flat[ok])
        return out.reshape(x.shape)


def _scale(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lo = x.min(0)
    span = x.max(0) - lo
    return lo, np.where(span > 0, span, 1.0)


def fit_intrinsic_rbf(
    uv_px: ArrayLike,
    alpha_beta_rad: ArrayLike,
    *,
    shape_chi: float | None = None,
    smoothing: float | None = None,
    chi_factors: Sequence[float] = (1.0, 3.0, 10.0),
    smoothing_candidates: Sequence[float] = (0.0, 1e-7, 1e-5),
    holdout_fraction: float = 0.15,
    neighbors: int | None = None,
    min_samples: int = 20,
    rng: np.random.Generator | int | None = None,
) -> IntrinsicCalibration:
    """Fit the RBF intrinsic calibration (004 eq 12–14) and its inverse from calibration samples.

    Parameters
    ----------
    uv_px : (N, 2) array
        Spot centres (px).
    alpha_beta_rad : (N, 2) array
        Reference angles (rad).
    shape_chi, smoothing : float, optional
        Multiquadric χ (scaled units) and scipy smoothing.  When not given they are chosen on a
        grid (``chi_factors`` × the mean nearest-neighbour spacing of the scaled samples, and
        ``smoothing_candidates``) by the error on a random hold-out of ``holdout_fraction`` of the
        samples (004 does not say how χ is chosen; the hold-out stands in for cross-validation), then the maps are refitted on all samples.
    neighbors : int, optional
        Use only this many nearest samples per evaluation (scipy's local RBF, for large N).
    min_samples : int
        Fewer samples raise ``ValueError``.

    Returns
    -------
    IntrinsicCalibration
    """
    uv = as_pairs(uv_px, "uv_px")
    ab = as_pairs(alpha_beta_rad, "alpha_beta_rad")
    if uv.ndim != 2 or ab.shape != uv.shape:
        raise ValueError(f"uv_px, alpha_beta_rad: expected matching (N, 2) arrays, got {uv.shape} and {ab.shape}")
    if min_samples < 4:
        raise ValueError(f"min_samples: must be >= 4, got {min_samples!r}")
    if uv.shape[0] < min_samples:
        raise ValueError(
            f"uv_px: intrinsic calibration needs at least {min_samples} samples, got {uv.shape[0]}"
        )
    if not (np.all(np.isfinite(uv)) and np.all(np.isfinite(ab))):
        raise ValueError("uv_px, alpha_beta_rad: contain non-finite values")
    for name, arr in (("uv_px", uv), ("alpha_beta_rad", ab)):
        sv = np.linalg.svd(arr - arr.mean(0), compute_uv=False)
        if sv[1] <= 1e-9 * max(sv[0], 1e-300):
            raise ValueError(f"{name}: calibration samples are collinear; they must span both axes")
    rng = np.random.default_rng(rng)
    uv_lo, uv_span = _scale(uv)
    ab_lo, ab_span = _scale(ab)
    x_uv = (uv - uv_lo) / uv_span
    x_ab = (ab - ab_lo) / ab_span
    spacing = float(np.mean(cKDTree(x_uv).query(x_uv, k=2)[0][:, 1]))
    if spacing <= 0:
        raise ValueError("uv_px: duplicate calibration samples only")

    def make(x, y, chi, sm):
        return RBFInterpolator(x, y, kernel="multiquadric", epsilon=1.0 / chi, degree=1,
                               smoothing=sm, neighbors=neighbors)

    holdout_rms = float("nan")
    if shape_chi is None or smoothing is None:
        chis = [shape_chi] if shape_chi is not None else [f * spacing for f in chi_factors]
        sms = [smoothing] if smoothing is not None else list(smoothing_candidates)
        n = uv.shape[0]
        n_out = max(1, int(round(holdout_fraction * n)))
        perm = rng.permutation(n)
        test, train = perm[:n_out], perm[n_out:]
        best = (np.inf, chis[0], sms[0])
        for chi in chis:
            for sm in sms:
                f = make(x_uv[train], ab[train], chi, sm)
                err = float(np.sqrt(np.mean((f(x_uv[test]) - ab[test]) ** 2)))
                if err < best[0]:
                    best = (err, chi, sm)
        holdout_rms, shape_chi, smoothing = best
    if shape_chi <= 0 or smoothing < 0:
        raise ValueError(f"shape_chi, smoothing: need chi > 0 and smoothing >= 0, got {shape_chi!r}, {smoothing!r}")
    forward = make(x_uv, ab, shape_chi, smoothing)
    # inverse: same relative shape, in the scaled angle coordinates
    spacing_ab = float(np.mean(cKDTree(x_ab).query(x_ab, k=2)[0][:, 1]))
    inverse = make(x_ab, uv, shape_chi * spacing_ab / spacing, smoothing)
    return IntrinsicCalibration(forward, inverse, uv_lo, uv_span, ab_lo, ab_span, float(shape_chi),
                                float(smoothing), int(uv.shape[0]), holdout_rms)


# =============================================================================== extrinsic calibration
@dataclass(frozen=True, eq=False)
class ExtrinsicCalibration:
    """Camera pose from control points (004 eq 15–20): ``x_C = R_CW X_W + t_CW``.

    Attributes
    ----------
    R_CW : (3, 3) ndarray
    t_CW : (3,) ndarray
        Metres.
    R_CW_linear, t_CW_linear : ndarray
        The linear solution (flag P004-8) projected onto SO(3), before refinement.
    rms_residual_rad, max_residual_rad : float
        Angular residuals ``α_i − atan2(x_C, z_C)``, ``β_i − atan2(y_C, z_C)`` after refinement.
    n_points : int
    method : str
        ``"rotvec"`` or ``"penalty"``.
    orthogonality_error : float
        ``max |R Rᵀ − I|`` of the refined matrix before the final projection (0 for ``"rotvec"``).
    """

    R_CW: np.ndarray
    t_CW: np.ndarray
    R_CW_linear: np.ndarray
    t_CW_linear: np.ndarray
    rms_residual_rad: float
    max_residual_rad: float
    n_points: int
    method: str
    orthogonality_error: float


def _angle_residuals(R: np.ndarray, t: np.ndarray, X: np.ndarray, ab: np.ndarray) -> np.ndarray:
    Xc = X @ R.T + t
    pred = np.stack([np.arctan2(Xc[:, 0], Xc[:, 2]), np.arctan2(Xc[:, 1], Xc[:, 2])], -1)
    return (ab - pred).ravel()


def calibrate_extrinsics(
    X_W: ArrayLike,
    alpha_beta_rad: ArrayLike,
    *,
    method: str = "rotvec",
    penalty_weight: float = 1.0e4,
    min_points: int = 6,
) -> ExtrinsicCalibration:
    """Extrinsic calibration of one camera from control points (004 eq 15–20, flags P004-8/P004-9).

    1. Linear: stack (16) and (17) for every point (two equations each, not their sum as in
       eq 18), in Hartley-normalised world coordinates; the SVD null vector gives ``[R t]`` up to
       scale; rescale so that the rows of ``R`` have unit norm, pick the sign that puts the points in
       front of the camera (``z_C > 0``), project ``R`` onto SO(3).
    2. Refine with Levenberg–Marquardt (``scipy.optimize.least_squares``, ``method="lm"``):
       ``"rotvec"`` (default) parameterises ``R = exp([δ×]) R_linear`` and minimises the angular
       residuals, so no penalty is needed; ``"penalty"`` is 004 eq (20) with the 12 entries free,
       residuals (16)–(17) divided by the mean depth (≈ radians) and ``sqrt(M) f_j`` of eq (19),
       ``M = penalty_weight`` (004 leaves M unstated, flag P004-9, docs/papers.md#p004-9), projected onto SO(3) at the end.

    Parameters
    ----------
    X_W : (n, 3) array
        Control points measured by the laser tracker, world frame (m).
    alpha_beta_rad : (n, 2) array
        Their angles measured by the camera (rad).

    Raises
    ------
    ValueError
        Fewer than ``min_points`` (≥ 6) points, or points in a degenerate (e.g. coplanar) layout.
    """
    X = as_points(X_W, "X_W")
    ab = as_pairs(alpha_beta_rad, "alpha_beta_rad")
    if method not in ("rotvec", "penalty"):
        raise ValueError(f"method: must be 'rotvec' or 'penalty', got {method!r}")
    if min_points < 6:
        raise ValueError(f"min_points: the linear solve needs at least 6 points, got {min_points!r}")
    if X.ndim != 2 or ab.ndim != 2 or X.shape[0] != ab.shape[0]:
        raise ValueError(f"X_W, alpha_beta_rad: expected (n, 3) and (n, 2), got {X.shape} and {ab.shape}")
    n = X.shape[0]
    if n < min_points:
        raise ValueError(f"X_W: extrinsic calibration needs at least {min_points} control points, got {n}")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(ab))):
        raise ValueError("X_W, alpha_beta_rad: contain non-finite values")
    m = X.mean(0)
    s = float(np.sqrt(np.mean(np.sum((X - m) ** 2, -1))))
    if s == 0:
        raise ValueError("X_W: all control points coincide")
    Xn = (X - m) / s
    ta, tb = np.tan(ab[:, 0]), np.tan(ab[:, 1])
    Xh = np.concatenate([Xn, np.ones((n, 1))], -1)
    Z = np.zeros((n, 4))
    # unknowns p = [row1 (4), row2 (4), row3 (4)] of P' = [s R | R m + t] (up to scale)
    A = np.concatenate([
        np.concatenate([Xh, Z, -ta[:, None] * Xh], -1),
        np.concatenate([Z, Xh, -tb[:, None] * Xh], -1),
    ], 0)
    _, sv, Vt = np.linalg.svd(A)
    if sv[-2] < 1e-6 * sv[0]:
        raise ValueError(
            f"X_W: control points are degenerate for the linear solve (e.g. coplanar); "
            f"singular values {sv[-2]:.3g}, {sv[-1]:.3g} relative to {sv[0]:.3g}"
        )
    P = Vt[-1].reshape(3, 4)
    k = float(np.mean(np.linalg.norm(P[:, :3], axis=1)))
    P = P / k
    depth = Xh @ P[2]
    if np.median(depth) < 0:
        P = -P
    # x_C = R X + t = (s R) Xn + (R m + t), so P ∝ [s R | R m + t]; after dividing by the mean row norm
    # of its left block, P ≈ [R | (R m + t) / s]
    R_lin = orthonormalize(P[:, :3])
    t_lin = P[:, 3] * s - R_lin @ m
    if method == "rotvec":
        def fun(p):
            R = matrix_from_quat(quat_from_rotvec(p[:3])) @ R_lin
            return _angle_residuals(R, p[3:], X, ab)

        sol = least_squares(fun, np.concatenate([np.zeros(3), t_lin]), method="lm", x_scale="jac")
        R = matrix_from_quat(quat_from_rotvec(sol.x[:3])) @ R_lin
        t = sol.x[3:]
        ortho = 0.0
    else:
        zbar = float(np.mean(X @ R_lin[2] + t_lin[2]))
        sq = np.sqrt(penalty_weight)

        def fun(p):
            R = p[:9].reshape(3, 3)
            t = p[9:]
            Xc = X @ R.T + t
            F16 = (Xc[:, 0] - ta * Xc[:, 2]) / zbar
            F17 = (Xc[:, 1] - tb * Xc[:, 2]) / zbar
            G = R @ R.T
            f = np.array([G[0, 0] - 1, G[1, 1] - 1, G[2, 2] - 1, G[0, 1], G[0, 2], G[1, 2]])
            return np.concatenate([F16, F17, sq * f])

        sol = least_squares(fun, np.concatenate([R_lin.ravel(), t_lin]), method="lm", x_scale="jac")
        Rp = sol.x[:9].reshape(3, 3)
        ortho = float(np.max(np.abs(Rp @ Rp.T - np.eye(3))))
        R = orthonormalize(Rp)
        t = sol.x[9:]
    res = _angle_residuals(R, t, X, ab)
    return ExtrinsicCalibration(R, t, R_lin, t_lin, float(np.sqrt(np.mean(res**2))),
                                float(np.max(np.abs(res))), n, method, ortho)
