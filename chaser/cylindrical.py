"""Pose measurement by orthogonal cylindrical imaging (linear CCDs), paper 004.

The system of GUAN et al. (2016): two or more cameras, each measuring the horizontal and vertical
angles ``(α, β)`` of point sources (LEDs) with two linear CCDs (:mod:`vision.cylindrical`).

Pipeline (SEEDS_SPEC §4.2), with the corrected forms of flags P004-1..10:

1. **Intrinsic calibration** (004 eq 12–14, flags P004-5/P004-6): a non-parametric mapping
   ``(u, v) → (α, β)`` fitted by radial basis functions (``scipy.interpolate.RBFInterpolator``,
   multiquadric kernel, linear polynomial tail, coordinates scaled to [0, 1]) to samples from a
   turntable-and-rail rig (:func:`simulate_turntable_calibration`), and its inverse
   ``(α, β) → (u, v)`` fitted on the swapped samples (flag P004-10b) for prediction.
2. **Extrinsic calibration** (004 eq 15–20, flags P004-7..9): the linear solve of the 2n equations
   (16)–(17) (SVD null vector, ≥ 6 points), projection onto SO(3), then Levenberg–Marquardt
   (``scipy.optimize.least_squares``) on the angular residuals with a rotation-vector
   parameterisation; the paper's penalty form (20) is an option.
3. **3-D points** (004 eq 1–4): least-squares intersection of the 2n planes of n cameras; channels
   whose spots overlap are dropped (004 §3.2 step 8); fewer than three independent planes is a
   reported failure.
4. **Multi-target recognition** (004 §3.2, flag P004-10): a constant-velocity Kalman filter per
   target (``filterpy``), prediction back-projected through the extrinsics and the inverse RBF,
   nearest-neighbour association on each CCD, initial identities by lighting the targets in turn.
5. **Attitude from three targets** (004 eq 5–11): the virtual point ``c′`` (corrected eq 5, flag
   P004-1), the Cayley least squares for the Rodrigues parameters (flag P004-4) with the parameter-set
   switching of paper 001 near 180° (``attitude.gibbs``), yaw/roll/pitch by the corrected eq 9–11
   (flags P004-2/P004-3, 3-1-2 sequence).

Frames: ``W`` is the world (laser-tracker) frame; ``C`` a camera frame (``z`` boresight, ``x`` right,
``y`` down); 004 eq (15) maps world to camera, ``x_C = R_CW X_W + t_CW`` (flag P004-7).  For the
attitude, ``O`` is the reference (world) frame and ``S`` the target body frame of 004 eq (6)
(``−x_S ∥ ab``, ``y_S ∥ bc′``); 004's ``R_ob`` is ``R_OS`` (``n^t = R_ob n^s``, eq 7).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import predict as kf_predict
from filterpy.kalman import update as kf_update
from numpy.typing import ArrayLike
from scipy.interpolate import RBFInterpolator
from scipy.optimize import least_squares
from scipy.spatial import cKDTree
from scipy.stats import qmc

from attitude.euler import euler_from_matrix
from attitude.gibbs import (
    GIBBS_SET_MATRICES,
    gibbs_switch,
    quat_from_gibbs_set,
    shuster_matrix_from_gibbs_set,
)
from attitude.matrix import orthonormalize, rot_y
from attitude.quaternion import (
    matrix_from_quat,
    quat_conjugate,
    quat_from_rotvec,
    quat_multiply,
    skew,
)
from vision.cylindrical import (
    CylindricalCamera,
    LineSpots,
    angles_from_points,
    detect_spots,
    measure_spot_centres,
    render_line_signals,
)

__all__ = [
    "TurntableSamples",
    "simulate_turntable_calibration",
    "IntrinsicCalibration",
    "fit_intrinsic_rbf",
    "ExtrinsicCalibration",
    "calibrate_extrinsics",
    "CalibratedCamera",
    "PlaneIntersection",
    "intersect_planes",
    "measure_points",
    "CylindricalRig",
    "paper_rig",
    "tracker_sigma_m",
    "control_points_in_cube",
    "SystemCalibration",
    "calibrate_system",
    "rig_detections",
    "TrackerSettings",
    "TrackState",
    "FrameTrack",
    "initialise_tracks",
    "track_predict",
    "track_frame",
    "virtual_point",
    "sigma_from_vector_pairs",
    "yaw_roll_pitch_from_sigma",
    "yaw_roll_pitch_from_matrix",
    "ThreePointAttitude",
    "attitude_from_three_points",
    "N_S_BODY",
]

#: Body-frame unit vectors of 004 eq (6): ``n_1^s = [0, 1, 0]`` (along bc′) and ``n_2^s = [−1, 0, 0]`` (along ab).
N_S_BODY = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


def _as_points(X: ArrayLike, name: str) -> np.ndarray:
    arr = np.asarray(X, dtype=float)
    if arr.ndim == 0 or arr.shape[-1] != 3:
        raise ValueError(f"{name}: expected shape (..., 3), got {arr.shape}")
    return arr


def _as_pairs(x: ArrayLike, name: str) -> np.ndarray:
    arr = np.asarray(x, dtype=float)
    if arr.ndim == 0 or arr.shape[-1] != 2:
        raise ValueError(f"{name}: expected shape (..., 2), got {arr.shape}")
    return arr


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
        uv = _as_pairs(uv_px, "uv_px")
        return self._eval(self.forward, (uv - self.uv_lo_px) / self.uv_span_px)

    def pixels_from_angles(self, alpha_beta_rad: ArrayLike) -> np.ndarray:
        """Inverse map ``(α, β)`` rad → ``(u, v)`` px (flag P004-10b); NaN stays NaN."""
        ab = _as_pairs(alpha_beta_rad, "alpha_beta_rad")
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
        samples (SEEDS_SPEC §4.6 suggests cross-validation), then the maps are refitted on all samples.
    neighbors : int, optional
        Use only this many nearest samples per evaluation (scipy's local RBF, for large N).
    min_samples : int
        Fewer samples raise ``ValueError``.

    Returns
    -------
    IntrinsicCalibration
    """
    uv = _as_pairs(uv_px, "uv_px")
    ab = _as_pairs(alpha_beta_rad, "alpha_beta_rad")
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
       ``M = penalty_weight`` (1e4 per SEEDS_SPEC), projected onto SO(3) at the end.

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
    X = _as_points(X_W, "X_W")
    ab = _as_pairs(alpha_beta_rad, "alpha_beta_rad")
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


# =============================================================================== calibrated camera, planes
@dataclass(frozen=True, eq=False)
class CalibratedCamera:
    """A calibrated camera of the system: intrinsic RBF maps and extrinsic pose ``x_C = R_CW X_W + t_CW``."""

    intrinsic: IntrinsicCalibration
    R_CW: np.ndarray
    t_CW: np.ndarray

    def angles_from_world(self, X_W: ArrayLike) -> np.ndarray:
        """004 eq (15) then (1)–(2): predicted ``(α, β)`` (rad) of world points ``(..., 3)``."""
        X = _as_points(X_W, "X_W")
        return angles_from_points(X @ self.R_CW.T + self.t_CW)

    def pixels_from_world(self, X_W: ArrayLike) -> np.ndarray:
        """Back-projection of 004 §3.2: world point → angles → inverse RBF → predicted ``(u, v)`` px."""
        return self.intrinsic.pixels_from_angles(self.angles_from_world(X_W))

    def angles_from_pixels(self, uv_px: ArrayLike) -> np.ndarray:
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


def _sym_entries(nx, ny, nz, w2):
    """Entries ``(xx, yy, zz, xy, xz, yz)`` of ``Σ_k w²_k n̂_k n̂_kᵀ`` from component arrays ``(K, ...)``."""
    wx, wy, wz = w2 * nx, w2 * ny, w2 * nz
    return ((wx * nx).sum(0), (wy * ny).sum(0), (wz * nz).sum(0), (wx * ny).sum(0), (wx * nz).sum(0),
            (wy * nz).sum(0))


def _sym_inverse(a, b, c, e, f, g):
    """Adjugate and determinant of the symmetric matrices ``[[a, e, f], [e, b, g], [f, g, c]]``."""
    A00, A01, A02 = b * c - g * g, f * g - e * c, e * g - b * f
    A11, A12, A22 = a * c - f * f, e * f - a * g, a * b - e * e
    det = a * A00 + e * A01 + f * A02
    return (A00, A11, A22, A01, A02, A12), det


def _sym_eigvals(a, b, c, e, f, g):
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
    """Least-squares intersection of the planes of n cameras (004 eq 1–4, SEEDS_SPEC §4.3.1).

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
    uv = _as_pairs(uv_px, "uv_px")
    C = len(cameras)
    if uv.ndim < 2 or uv.shape[-2] != C:
        raise ValueError(f"uv_px: expected shape (..., {C}, 2), got {uv.shape}")
    ab = np.stack([cam.angles_from_pixels(uv[..., c, :]) for c, cam in enumerate(cameras)], -2)
    R = np.stack([cam.R_CW for cam in cameras])
    t = np.stack([cam.t_CW for cam in cameras])
    return intersect_planes(R, t, ab, angle_sigma_rad=angle_sigma_rad, strict=strict)


# =============================================================================== simulated rig
@dataclass(frozen=True, eq=False)
class CylindricalRig:
    """Simulation truth of a measuring rig: the camera hardware and their true poses.

    Attributes
    ----------
    cameras : tuple of CylindricalCamera
    R_CW : (C, 3, 3) ndarray
    t_CW : (C, 3) ndarray
        True extrinsics, ``x_C = R_CW X_W + t_CW`` (m).
    """

    cameras: tuple[CylindricalCamera, ...]
    R_CW: np.ndarray
    t_CW: np.ndarray

    @property
    def n_cameras(self) -> int:
        return len(self.cameras)

    @property
    def centres_W(self) -> np.ndarray:
        return -np.einsum("cji,cj->ci", self.R_CW, self.t_CW)

    def true_angles(self, X_W: ArrayLike) -> np.ndarray:
        """True ``(α, β)`` of world points ``(..., 3)`` in every camera: ``(..., C, 2)``."""
        X = _as_points(X_W, "X_W")
        Xc = np.einsum("cij,...j->...ci", self.R_CW, X) + self.t_CW
        return angles_from_points(Xc)

    def true_pixels(self, X_W: ArrayLike) -> np.ndarray:
        """True spot centres ``(..., C, 2)`` (NaN outside a camera's field)."""
        ab = self.true_angles(X_W)
        return np.stack([cam.pixels_from_angles(ab[..., c, :]) for c, cam in enumerate(self.cameras)], -2)


def paper_rig(
    *,
    baseline_m: float = 2.0,
    convergence_deg: float = 30.0,
    camera: CylindricalCamera | None = None,
    camera_spread: float = 1.0,
) -> CylindricalRig:
    """The two-camera rig of 004 §4: baseline 2 m, optical axes converging at 30°.

    World frame (laser-tracker frame): ``x`` along the baseline, ``y`` forward (depth), ``z`` up.
    Camera 1 is at the origin and camera 2 at ``(baseline, 0, 0)``; each is turned inwards by half the
    convergence angle, so the axes meet at ``(baseline/2, baseline/2 / tan(conv/2), 0)`` (3.73 m
    for the paper's values).  The second camera's lens differs from the first (principal points and
    distortion changed by ``camera_spread`` × a few per cent), as two real units would.
    """
    if not baseline_m > 0:
        raise ValueError(f"baseline_m: must be positive, got {baseline_m!r}")
    if not 0 < convergence_deg < 120:
        raise ValueError(f"convergence_deg: must be in (0, 120), got {convergence_deg!r}")
    cam1 = camera if camera is not None else CylindricalCamera()
    sp = camera_spread
    cam2 = replace(
        cam1,
        principal_px=(cam1.principal_px[0] - 6.3 * sp, cam1.principal_px[1] + 4.1 * sp),
        k1=(cam1.k1[0] * (1 + 0.08 * sp), cam1.k1[1] * (1 - 0.06 * sp)),
        k2=(cam1.k2[0] * (1 - 0.1 * sp), cam1.k2[1] * (1 + 0.1 * sp)),
        bow=(cam1.bow[0] * (1 + 0.1 * sp), cam1.bow[1] * (1 - 0.1 * sp)),
        line_tilt_rad=(cam1.line_tilt_rad[0] - 0.7e-3 * sp, cam1.line_tilt_rad[1] + 0.5e-3 * sp),
    )
    h = np.deg2rad(convergence_deg) / 2.0
    Rs, ts = [], []
    for centre, yaw in (((0.0, 0.0, 0.0), h), ((baseline_m, 0.0, 0.0), -h)):
        z_c = np.array([np.sin(yaw), np.cos(yaw), 0.0])   # boresight, turned towards the middle
        x_c = np.array([np.cos(yaw), -np.sin(yaw), 0.0])  # right
        y_c = np.cross(z_c, x_c)                          # down
        R_CW = np.stack([x_c, y_c, z_c])
        Rs.append(R_CW)
        ts.append(-R_CW @ np.asarray(centre))
    return CylindricalRig((cam1, cam2), np.stack(Rs), np.stack(ts))


def control_points_in_cube(n: int, *, centre_W: ArrayLike, edge_m: float = 1.0,
                           rng: np.random.Generator | int | None = None) -> np.ndarray:
    """``n`` control points spread uniformly over a cube (Latin hypercube sample, ``scipy.stats.qmc``).

    Returns ``(n, 3)`` world points (m).
    """
    if int(n) != n or n < 1:
        raise ValueError(f"n: must be a positive integer, got {n!r}")
    if not edge_m > 0:
        raise ValueError(f"edge_m: must be positive, got {edge_m!r}")
    c = np.asarray(centre_W, dtype=float)
    if c.shape != (3,):
        raise ValueError(f"centre_W: expected shape (3,), got {c.shape}")
    sample = qmc.LatinHypercube(d=3, rng=np.random.default_rng(rng)).random(int(n))
    return c + (sample - 0.5) * edge_m


@dataclass(frozen=True, eq=False)
class SystemCalibration:
    """What :func:`calibrate_system` produced: the calibrated cameras and the calibration records."""

    cameras: tuple[CalibratedCamera, ...]
    samples: tuple[TurntableSamples, ...]
    extrinsics: tuple[ExtrinsicCalibration, ...]
    control_points_W: np.ndarray
    control_points_measured_W: np.ndarray



def calibrate_system(
    rig: CylindricalRig,
    control_points_W: ArrayLike,
    *,
    rng: np.random.Generator | int | None = None,
    turntable: dict | None = None,
    rbf: dict | None = None,
    n_scans: int = 20,
    extrinsic_method: str = "rotvec",
    method: str = "threshold_centroid",
) -> SystemCalibration:
    """Calibrate every camera of a simulated rig: turntable RBF intrinsics, then control-point extrinsics.

    The control points are measured by the laser tracker (at the world origin, error
    :func:`tracker_sigma_m` of their distance) and, lit one at a time, by every camera (spot centres
    averaged over ``n_scans`` scans, mapped to angles by the camera's fresh RBF calibration).

    Parameters
    ----------
    rig : CylindricalRig
    control_points_W : (n, 3) array
        True control-point positions (m).
    turntable, rbf : dict, optional
        Keyword options for :func:`simulate_turntable_calibration` and :func:`fit_intrinsic_rbf`.
    """
    rng = np.random.default_rng(rng)
    X = _as_points(control_points_W, "control_points_W")
    seeds = rng.spawn(2 * rig.n_cameras + 1)
    X_meas = X + seeds[-1].standard_normal(X.shape) * tracker_sigma_m(np.linalg.norm(X, axis=-1))[..., None]
    uv_true = rig.true_pixels(X)
    cams, samples, extr = [], [], []
    for c, hw in enumerate(rig.cameras):
        s = simulate_turntable_calibration(hw, rng=seeds[2 * c], method=method, **(turntable or {}))
        intr = fit_intrinsic_rbf(s.uv_px, s.alpha_beta_rad, rng=seeds[2 * c], **(rbf or {}))
        uv = measure_spot_centres(hw, uv_true[:, c, :], rng=seeds[2 * c + 1], n_scans=n_scans, method=method)
        ab = intr.angles_from_pixels(uv)
        seen = np.isfinite(ab).all(-1)
        e = calibrate_extrinsics(X_meas[seen], ab[seen], method=extrinsic_method)
        cams.append(CalibratedCamera(intr, e.R_CW, e.t_CW))
        samples.append(s)
        extr.append(e)
    return SystemCalibration(tuple(cams), tuple(samples), tuple(extr), X, X_meas)


def rig_detections(
    rig: CylindricalRig,
    X_W: ArrayLike,
    *,
    rng: np.random.Generator | int | None = None,
    lit: ArrayLike | None = None,
    method: str = "threshold_centroid",
) -> list[tuple[LineSpots, LineSpots]]:
    """One frame of the rig: full line signals of every CCD with all lit targets, and their spots.

    Parameters
    ----------
    X_W : (K, 3) array
        Target (LED) positions (m).
    lit : (K,) bool array, optional
        Which targets are on (sequential lighting); default all.

    Returns
    -------
    list over cameras of (spots on CCD1, spots on CCD2)
    """
    rng = np.random.default_rng(rng)
    X = _as_points(X_W, "X_W")
    uv = rig.true_pixels(X)  # (K, C, 2)
    if lit is not None:
        on = np.asarray(lit, dtype=bool)
        uv = np.where(on[:, None, None], uv, np.nan)
    out = []
    for c, cam in enumerate(rig.cameras):
        sig = render_line_signals(cam, uv[:, c, :], rng=rng)
        out.append((detect_spots(sig[0], method=method), detect_spots(sig[1], method=method)))
    return out


# =============================================================================== multi-target tracking
@dataclass(frozen=True)
class TrackerSettings:
    """Settings of the multi-target recognition of 004 §3.2 (SEEDS_SPEC flag P004-10 suggestions).

    Attributes
    ----------
    accel_psd_m2_s3 : float
        White-acceleration spectral density of the constant-velocity model (m²/s³).
    angle_sigma_rad : float
        Angle noise per channel (rad), for the measurement covariance of the triangulated points.
    gate_sigma : float
        Association gate in standard deviations of the predicted pixel coordinate.
    min_gate_px : float
        Smallest gate (px).
    overlap_px : float
        Two predicted spots closer than this on a CCD are treated as overlapped: that channel is
        dropped for both targets (004 §3.2 step 8).
    max_fwhm_px : float or None
        A detected spot wider than this is a merge of several spots and is not used.
    init_velocity_sigma_m_s : float
        Prior standard deviation of the velocity of a new track.
    """

    accel_psd_m2_s3: float = 1.0e-4
    angle_sigma_rad: float = 2.0e-6
    gate_sigma: float = 3.0
    min_gate_px: float = 3.0
    overlap_px: float = 15.0
    max_fwhm_px: float | None = 9.0
    init_velocity_sigma_m_s: float = 1.0

    def __post_init__(self) -> None:
        for name in ("accel_psd_m2_s3", "angle_sigma_rad", "gate_sigma", "min_gate_px",
                     "init_velocity_sigma_m_s"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name}: must be positive, got {v!r}")
        if self.overlap_px < 0:
            raise ValueError(f"overlap_px: must be >= 0, got {self.overlap_px!r}")


@dataclass(frozen=True, eq=False)
class TrackState:
    """Constant-velocity Kalman states of K targets, each at its own time.

    Attributes
    ----------
    t_s : (K,) ndarray
        Time of each state (s).
    x : (K, 6) ndarray
        ``[X, Y, Z, Ẋ, Ẏ, Ż]`` in the world frame (m, m/s).
    P : (K, 6, 6) ndarray
        Covariances.
    initialised : (K,) bool ndarray
    """

    t_s: np.ndarray
    x: np.ndarray
    P: np.ndarray
    initialised: np.ndarray

    @classmethod
    def empty(cls, n_targets: int) -> TrackState:
        if int(n_targets) != n_targets or n_targets < 1:
            raise ValueError(f"n_targets: must be a positive integer, got {n_targets!r}")
        K = int(n_targets)
        return cls(np.zeros(K), np.full((K, 6), np.nan), np.full((K, 6, 6), np.nan), np.zeros(K, bool))

    @property
    def position_W(self) -> np.ndarray:
        return self.x[:, :3]


@dataclass(frozen=True, eq=False)
class FrameTrack:
    """Result of one frame of :func:`track_frame`.

    Attributes
    ----------
    state : TrackState
        Filter states after the update (time ``t_s`` for every target).
    X_W : (K, 3) ndarray
        Triangulated target positions of this frame (m); NaN where a target had fewer than three
        independent planes (its state then only coasts).
    measured : (K,) bool ndarray
    n_planes : (K,) int ndarray
    spot_index : (K, C, 2) int ndarray
        Index of the associated spot in the detection list of each CCD, −1 when dropped.
    uv_pred_px : (K, C, 2) ndarray
        Back-projected predictions (px).
    overlapped : (K, C, 2) bool ndarray
        Channel dropped because spots overlapped (predicted closer than ``overlap_px``, one spot
        claimed by two targets, or a merged spot).
    """

    state: TrackState
    X_W: np.ndarray
    measured: np.ndarray
    n_planes: np.ndarray
    spot_index: np.ndarray
    uv_pred_px: np.ndarray
    overlapped: np.ndarray


_H = np.hstack([np.eye(3), np.zeros((3, 3))])


def _transition(dt: float, q: float) -> tuple[np.ndarray, np.ndarray]:
    F = np.eye(6)
    F[:3, 3:] = dt * np.eye(3)
    Q = Q_discrete_white_noise(dim=2, dt=max(dt, 0.0), var=q, block_size=3, order_by_dim=False)
    return F, Q


def track_predict(state: TrackState, t_s: float, *, settings: TrackerSettings = TrackerSettings()) -> TrackState:
    """Constant-velocity prediction of every initialised target to time ``t_s`` (``filterpy.kalman.predict``).

    Returns a new state; targets not yet initialised are left as they are.
    """
    x = state.x.copy()
    P = state.P.copy()
    t = state.t_s.copy()
    for k in np.flatnonzero(state.initialised):
        dt = float(t_s - state.t_s[k])
        if dt < 0:
            raise ValueError(f"t_s: {t_s!r} is before the state time {state.t_s[k]!r} of target {k}")
        if dt > 0:
            F, Q = _transition(dt, settings.accel_psd_m2_s3)
            x[k], P[k] = kf_predict(x[k], P[k], F, Q)
        t[k] = t_s
    return TrackState(t, x, P, state.initialised.copy())


def _update(state: TrackState, k: int, X: np.ndarray, cov: np.ndarray, t_s: float,
            settings: TrackerSettings) -> TrackState:
    x = state.x.copy()
    P = state.P.copy()
    t = state.t_s.copy()
    init = state.initialised.copy()
    if not init[k]:
        x[k] = np.concatenate([X, np.zeros(3)])
        P[k] = np.zeros((6, 6))
        P[k][:3, :3] = cov
        P[k][3:, 3:] = np.eye(3) * settings.init_velocity_sigma_m_s**2
        init[k] = True
    else:
        x[k], P[k] = kf_update(x[k], P[k], X, cov, _H)
    t[k] = t_s
    return TrackState(t, x, P, init)


def _positions(spots) -> tuple[np.ndarray, np.ndarray | None]:
    if isinstance(spots, LineSpots):
        return np.asarray(spots.position_px, dtype=float), np.asarray(spots.fwhm_px, dtype=float)
    arr = np.asarray(spots, dtype=float).reshape(-1)
    return arr, None


def initialise_tracks(
    cameras: Sequence[CalibratedCamera],
    n_targets: int,
    lit_frames: Sequence[tuple[int, float, Sequence]],
    *,
    settings: TrackerSettings = TrackerSettings(),
) -> TrackState:
    """Initial identification by sequential lighting (004 §3.2 step 3).

    Parameters
    ----------
    cameras : sequence of CalibratedCamera
    n_targets : int
    lit_frames : sequence of ``(target_index, t_s, detections)``
        Frames in which only ``target_index`` is lit; ``detections`` is, per camera, a pair of spot
        lists (``LineSpots`` or arrays of centres, px) for CCD1 and CCD2.  The brightest/only spot of
        each CCD is that target's.  Repeating the sequence gives the tracks a velocity.

    Returns
    -------
    TrackState
        Raises ``ValueError`` if a target never got a 3-D fix.
    """
    state = TrackState.empty(n_targets)
    for target, t_s, det in lit_frames:
        if not 0 <= int(target) < n_targets:
            raise ValueError(f"lit_frames: target index {target!r} outside [0, {n_targets})")
        uv = np.full((len(cameras), 2), np.nan)
        for c, pair in enumerate(det):
            for k in range(2):
                pos, _ = _positions(pair[k])
                if isinstance(pair[k], LineSpots) and len(pos) > 1:
                    pos = pos[[int(np.argmax(pair[k].peak_dn))]]
                if pos.size == 1:
                    uv[c, k] = pos[0]
        fix = measure_points(cameras, uv[None], angle_sigma_rad=settings.angle_sigma_rad)
        if not fix.ok[0]:
            continue
        state = track_predict(state, t_s, settings=settings) if state.initialised[target] else state
        state = _update(state, int(target), fix.X_W[0], fix.covariance_m2[0], t_s, settings)
    if not np.all(state.initialised):
        missing = np.flatnonzero(~state.initialised).tolist()
        raise ValueError(f"lit_frames: targets {missing} were never located during sequential lighting")
    return state


def _pixel_jacobian(cam: CalibratedCamera, X: np.ndarray, h: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """Back-projected pixels ``(K, 2)`` and their Jacobian ``(K, 2, 3)`` (finite differences)."""
    pts = np.concatenate([X[:, None, :], X[:, None, :] + h * np.eye(3)[None]], axis=1)  # (K, 4, 3)
    uv = cam.pixels_from_world(pts)
    J = (uv[:, 1:, :] - uv[:, :1, :]) / h  # (K, 3, 2)
    return uv[:, 0, :], np.swapaxes(J, -1, -2)


def track_frame(
    cameras: Sequence[CalibratedCamera],
    state: TrackState,
    detections: Sequence[Sequence],
    t_s: float,
    *,
    settings: TrackerSettings = TrackerSettings(),
) -> FrameTrack:
    """One frame of multi-target recognition and measurement (004 §3.2 steps 5–9).

    1. Predict every target to ``t_s`` (constant-velocity KF).
    2. Back-project the predictions into every camera: eq (15), eq (1)–(2), inverse RBF.
    3. On each CCD separately (the measurement is 1-D, flag P004-10c) associate each target with
       the nearest detected spot inside its gate (``gate_sigma`` × the predicted pixel standard
       deviation from ``P``, at least ``min_gate_px``).  The channel is dropped for targets whose
       predictions lie closer than ``overlap_px``, that claim the same spot, or whose spot is wider
       than ``max_fwhm_px`` (overlap, step 8).
    4. Map each camera's ``(u, v)`` to ``(α, β)`` with the RBF (a dropped coordinate is replaced by its
       prediction, and the angle of the dropped channel is not used), intersect the planes, and
       update the filter of each target with at least three independent planes.

    Parameters
    ----------
    cameras : sequence of CalibratedCamera
    state : TrackState
        All targets initialised.
    detections : per camera, (spots of CCD1, spots of CCD2)
        ``LineSpots`` or arrays of spot centres (px).
    t_s : float
        Frame time (s).
    """
    if not np.all(state.initialised):
        raise ValueError("state: every target must be initialised (see initialise_tracks)")
    C = len(cameras)
    if len(detections) != C:
        raise ValueError(f"detections: expected one entry per camera ({C}), got {len(detections)}")
    pred = track_predict(state, t_s, settings=settings)
    K = pred.x.shape[0]
    Xp = pred.x[:, :3]
    Pp = pred.P[:, :3, :3]
    uv_pred = np.full((K, C, 2), np.nan)
    gate = np.full((K, C, 2), settings.min_gate_px)
    for c, cam in enumerate(cameras):
        uvc, J = _pixel_jacobian(cam, Xp)
        uv_pred[:, c, :] = uvc
        var = np.einsum("kai,kij,kaj->ka", J, Pp, J)
        gate[:, c, :] = np.maximum(settings.gate_sigma * np.sqrt(np.maximum(var, 0.0)), settings.min_gate_px)
    spot_index = np.full((K, C, 2), -1, dtype=int)
    overlapped = np.zeros((K, C, 2), dtype=bool)
    uv_meas = np.full((K, C, 2), np.nan)
    for c in range(C):
        for ch in range(2):
            pos, fwhm = _positions(detections[c][ch])
            p = uv_pred[:, c, ch]
            finite = np.isfinite(p)
            dp = np.abs(p[:, None] - p[None, :])
            np.fill_diagonal(dp, np.inf)
            close = np.any(np.where(finite[:, None] & finite[None, :], dp < settings.overlap_px, False), axis=1)
            claim = np.full(K, -1)
            if pos.size:
                dist = np.abs(p[:, None] - pos[None, :])
                j = np.argmin(np.where(np.isfinite(dist), dist, np.inf), axis=1)
                dj = dist[np.arange(K), j]
                claim = np.where(finite & (dj <= gate[:, c, ch]), j, -1)
            counts = np.bincount(claim[claim >= 0], minlength=max(pos.size, 1))
            shared = (claim >= 0) & (counts[np.maximum(claim, 0)] > 1)
            wide = np.zeros(K, bool)
            if fwhm is not None and settings.max_fwhm_px is not None and pos.size:
                wide = (claim >= 0) & (fwhm[np.maximum(claim, 0)] > settings.max_fwhm_px)
            drop = close | shared | wide
            overlapped[:, c, ch] = drop
            use = (claim >= 0) & ~drop
            spot_index[:, c, ch] = np.where(use, claim, -1)
            uv_meas[use, c, ch] = pos[claim[use]]
    # angles per camera: the RBF needs both coordinates; a dropped one is replaced by its prediction
    ab = np.full((K, C, 2), np.nan)
    for c, cam in enumerate(cameras):
        have = np.isfinite(uv_meas[:, c, :])
        filled = np.where(have, uv_meas[:, c, :], uv_pred[:, c, :])
        a = cam.angles_from_pixels(filled)
        ab[:, c, :] = np.where(have, a, np.nan)
    R = np.stack([cam.R_CW for cam in cameras])
    t = np.stack([cam.t_CW for cam in cameras])
    fix = intersect_planes(R, t, ab, angle_sigma_rad=settings.angle_sigma_rad)
    new = pred
    for k in np.flatnonzero(fix.ok):
        new = _update(new, int(k), fix.X_W[k], fix.covariance_m2[k], t_s, settings)
    return FrameTrack(new, fix.X_W, fix.ok.copy(), fix.n_planes, spot_index, uv_pred, overlapped)


# =============================================================================== attitude from three targets
def virtual_point(a: ArrayLike, b: ArrayLike, c: ArrayLike) -> np.ndarray:
    """Virtual point ``c′`` of 004 eq (5), corrected form of flag P004-1.

    ``c′`` lies in the plane ``abc`` with ``bc′ ⊥ ab`` and ``|bc′| = |bc|``: the *vector* ``bc`` is
    rotated about the plane normal ``N = ab × bc / |ab × bc|`` through ``b`` by the complement
    ``θ₁ = π/2 − θ₀`` of the angle θ₀ between the vectors ``ab = b − a`` and ``bc = c − b``, with the
    Hamilton product: ``(0, c′ − b) = S ⊗ (0, c − b) ⊗ S̄``, ``S = [cos θ₁/2, N sin θ₁/2]``.

    Parameters
    ----------
    a, b, c : (..., 3) array
        Target positions (m).

    Returns
    -------
    (..., 3) ndarray
        ``c′``; NaN where ``a, b, c`` are collinear (no plane).
    """
    a = _as_points(a, "a")
    b = _as_points(b, "b")
    c = _as_points(c, "c")
    ab = b - a
    bc = c - b
    cr = np.cross(ab, bc)
    ncr = np.linalg.norm(cr, axis=-1, keepdims=True)
    scale = np.linalg.norm(ab, axis=-1, keepdims=True) * np.linalg.norm(bc, axis=-1, keepdims=True)
    degenerate = ncr[..., 0] <= 1e-12 * np.maximum(scale[..., 0], 1e-300)
    with np.errstate(invalid="ignore", divide="ignore"):
        N = cr / ncr
        cos0 = np.clip(np.sum(ab * bc, -1) / scale[..., 0], -1.0, 1.0)
    theta1 = np.pi / 2 - np.arccos(cos0)
    S = np.concatenate([np.cos(theta1 / 2)[..., None], N * np.sin(theta1 / 2)[..., None]], -1)
    P = np.concatenate([np.zeros_like(bc[..., :1]), bc], -1)
    rotated = quat_multiply(quat_multiply(S, P), quat_conjugate(S))[..., 1:]
    return np.where(degenerate[..., None], np.nan, b + rotated)


def _cayley_solve(n_t: np.ndarray, n_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Batched Cayley LS ``[(n^t + n^s)×] σ = n^t − n^s`` over the pairs axis; returns σ, cond, null dir."""
    M = skew(n_t + n_s).reshape(n_t.shape[:-2] + (-1, 3))  # (..., 3·pairs, 3)
    rhs = (n_t - n_s).reshape(n_t.shape[:-2] + (-1,))
    U, s, Vt = np.linalg.svd(M, full_matrices=False)
    cond = s[..., 2] / np.maximum(s[..., 0], 1e-300)
    inv = np.where(s > 1e-12 * np.maximum(s[..., :1], 1e-300), 1.0 / np.where(s > 0, s, 1.0), 0.0)
    sigma = np.einsum("...ji,...j,...kj,...k->...i", Vt, inv, U, rhs)
    return sigma, cond, Vt[..., 2, :]


def sigma_from_vector_pairs(n_t: ArrayLike, n_s: ArrayLike = N_S_BODY, *, gibbs_set: ArrayLike = 0) -> np.ndarray:
    """Rodrigues parameters from vector pairs ``n^t = A n^s`` (flag P004-4), in parameter set ``i``.

    Solves the stacked Cayley equations ``[(n^t + R^(i) n^s)×] σ = n^t − R^(i) n^s`` by least squares,
    where ``A = A(σ) R^(i)`` is the Shuster attitude matrix of the set (001 eq 8′; ``i = 0`` is 004's
    eq 8 with the sign of flag P004-2 corrected).

    Parameters
    ----------
    n_t : (..., P, 3) array
        Unit vectors in the reference frame.
    n_s : (P, 3) or (..., P, 3) array
        The same vectors in the body frame (default 004 eq 6).
    gibbs_set : int or (...,) int array
        Parameter set 0..3.

    Returns
    -------
    (..., 3) ndarray
    """
    n_t = np.asarray(n_t, dtype=float)
    if n_t.ndim < 2 or n_t.shape[-1] != 3:
        raise ValueError(f"n_t: expected shape (..., P, 3), got {n_t.shape}")
    i = np.broadcast_to(np.asarray(gibbs_set, dtype=int), n_t.shape[:-2])
    if np.any((i < 0) | (i > 3)):
        raise ValueError(f"gibbs_set: must be 0..3, got {gibbs_set!r}")
    n_s = np.broadcast_to(np.asarray(n_s, dtype=float), n_t.shape)
    n_s_i = np.einsum("...ij,...pj->...pi", GIBBS_SET_MATRICES[i], n_s)
    return _cayley_solve(n_t, n_s_i)[0]


def yaw_roll_pitch_from_sigma(sigma: ArrayLike) -> np.ndarray:
    """004 eq (9)–(11), corrected (flags P004-2, P004-3): ``(yaw, roll, pitch)`` rad from σ (set 0).

    ``yaw = atan2(2(σ₃ − σ₁σ₂), 1 − σ₁² + σ₂² − σ₃²)``,
    ``roll = arcsin(2(σ₂σ₃ + σ₁)/(1 + |σ|²))``,
    ``pitch = atan2(2(σ₂ − σ₁σ₃), 1 − σ₁² − σ₂² + σ₃²)``: the 3-1-2 angles of
    ``R_ob = R_y(pitch) R_x(roll) R_z(yaw)`` (frame rotations).
    """
    s = np.asarray(sigma, dtype=float)
    if s.ndim == 0 or s.shape[-1] != 3:
        raise ValueError(f"sigma: expected shape (..., 3), got {s.shape}")
    s1, s2, s3 = s[..., 0], s[..., 1], s[..., 2]
    n2 = s1 * s1 + s2 * s2 + s3 * s3
    yaw = np.arctan2(2 * (s3 - s1 * s2), 1 - s1 * s1 + s2 * s2 - s3 * s3)
    roll = np.arcsin(np.clip(2 * (s2 * s3 + s1) / (1 + n2), -1.0, 1.0))
    pitch = np.arctan2(2 * (s2 - s1 * s3), 1 - s1 * s1 - s2 * s2 + s3 * s3)
    return np.stack([yaw, roll, pitch], -1)


def yaw_roll_pitch_from_matrix(R_ob: ArrayLike) -> np.ndarray:
    """The same angles from the matrix (flag P004-3): ``yaw = atan2(−R₂₁, R₂₂)``, ``roll = arcsin R₂₃``,
    ``pitch = atan2(−R₁₃, R₃₃)`` (1-based), i.e. ``euler_from_matrix(R_obᵀ, "312")``."""
    R = np.asarray(R_ob, dtype=float)
    if R.ndim < 2 or R.shape[-2:] != (3, 3):
        raise ValueError(f"R_ob: expected shape (..., 3, 3), got {R.shape}")
    return euler_from_matrix(np.swapaxes(R, -1, -2), "312")[0]


@dataclass(frozen=True, eq=False)
class ThreePointAttitude:
    """Attitude of a target from three points (004 §2.2).

    Attributes
    ----------
    R_OS : (..., 3, 3) ndarray
        004's ``R_ob``: body-to-reference, ``n^t = R_OS n^s`` (eq 7).
    q_OS : (..., 4) ndarray
        Hamilton quaternion of ``R_OS`` (scalar first).
    sigma : (..., 3) ndarray
        Rodrigues parameters in the parameter set ``gibbs_set`` (001 eq 4).
    gibbs_set : (...,) int ndarray
        0 = 004's plain σ; 1..3 after switching near 180° (001).
    yaw_roll_pitch_rad : (..., 3) ndarray
        Corrected 004 eq (9)–(11) (3-1-2 sequence).
    gimbal_lock : (...,) bool ndarray
        Roll within ``1e-6`` of ±90°.
    virtual_point_W : (..., 3) ndarray
        ``c′`` (eq 5).
    condition : (...,) ndarray
        Smallest over largest singular value of the Cayley system that was solved.
    ok : (...,) bool ndarray
        False where the three points are collinear.
    """

    R_OS: np.ndarray
    q_OS: np.ndarray
    sigma: np.ndarray
    gibbs_set: np.ndarray
    yaw_roll_pitch_rad: np.ndarray
    gimbal_lock: np.ndarray
    virtual_point_W: np.ndarray
    condition: np.ndarray
    ok: np.ndarray


def attitude_from_three_points(a: ArrayLike, b: ArrayLike, c: ArrayLike, *, switch_eta: float = 0.0,
                               singular_tol: float = 1e-9) -> ThreePointAttitude:
    """Attitude of a target carrying LEDs ``a, b, c`` (004 eq 5–11, flags P004-1..4).

    1. ``c′`` = :func:`virtual_point` (corrected eq 5).
    2. ``n₁ᵗ = (c′ − b)/|c′ − b|``, ``n₂ᵗ = (b − a)/|b − a|`` (eq 7), against ``n₁ˢ = [0, 1, 0]``,
       ``n₂ˢ = [−1, 0, 0]`` (eq 6).
    3. Cayley least squares for σ (flag P004-4) in set 0.  Near 180° (``|σ_j| > 1 + switch_eta``, or a
       numerically singular system, whose null direction is then the rotation axis) the
       parameter set is switched with 001's rule (``attitude.gibbs.gibbs_switch``) and the Cayley
       system is solved again in the new set, where every ``|σ_j| ≤ 1``.
    4. ``R_ob = A(σ) R^(i)`` and the corrected eq (9)–(11) from its elements.

    Parameters
    ----------
    a, b, c : (..., 3) array
        Target positions in the reference frame (m).
    """
    a = _as_points(a, "a")
    b = _as_points(b, "b")
    c = _as_points(c, "c")
    if switch_eta < 0:
        raise ValueError(f"switch_eta: must be >= 0, got {switch_eta!r}")
    batch = np.broadcast_shapes(a.shape, b.shape, c.shape)[:-1]
    a, b, c = (np.broadcast_to(v, batch + (3,)).reshape(-1, 3) for v in (a, b, c))
    cp = virtual_point(a, b, c)
    ok = np.isfinite(cp).all(-1)
    safe_cp = np.where(ok[..., None], cp, b + np.array([0.0, 1.0, 0.0]))
    safe_a = np.where(ok[..., None], a, b + np.array([1.0, 0.0, 0.0]))
    n1 = safe_cp - b
    n2 = b - safe_a
    n_t = np.stack([n1 / np.linalg.norm(n1, axis=-1, keepdims=True),
                    n2 / np.linalg.norm(n2, axis=-1, keepdims=True)], -2)
    n_s = np.broadcast_to(N_S_BODY, n_t.shape)
    sigma0, cond0, null0 = _cayley_solve(n_t, n_s)
    singular = cond0 < singular_tol
    probe = np.where(singular[..., None], null0 / singular_tol, sigma0)
    _, i_new = gibbs_switch(probe, np.zeros(probe.shape[:-1], dtype=int), eta=switch_eta)
    i_new = np.asarray(i_new)
    sigma = sigma0.copy()
    cond = cond0.copy()
    for i in (1, 2, 3):
        m = i_new == i
        if np.any(m):
            n_s_i = np.einsum("ij,...pj->...pi", GIBBS_SET_MATRICES[i], n_s[m])
            s_i, c_i, _ = _cayley_solve(n_t[m], n_s_i)
            sigma[m] = s_i
            cond[m] = c_i
    R_ob = shuster_matrix_from_gibbs_set(sigma, i_new)
    q_OS = quat_conjugate(quat_from_gibbs_set(sigma, i_new))
    angles, lock = euler_from_matrix(np.swapaxes(R_ob, -1, -2), "312")
    nan = ~ok

    def shape(x, tail=()):
        return x.reshape(batch + tail)

    return ThreePointAttitude(
        shape(np.where(nan[:, None, None], np.nan, R_ob), (3, 3)),
        shape(np.where(nan[:, None], np.nan, q_OS), (4,)),
        shape(np.where(nan[:, None], np.nan, sigma), (3,)),
        shape(i_new),
        shape(np.where(nan[:, None], np.nan, angles), (3,)),
        shape(lock & ok),
        shape(cp, (3,)),
        shape(np.where(nan, 0.0, cond)),
        shape(ok),
    )
