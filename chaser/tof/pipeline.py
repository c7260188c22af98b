"""TOF-camera relative pose of a cooperative marker target from one frame (paper 000), corrected.

:func:`estimate_tof_pose` runs the whole chain of 000 §1.2 on one :class:`vision.tof.TofFrame`:
marker extraction (:mod:`chaser.tof.extraction`, 000 §2), matching to the model and its pose check
(:mod:`chaser.tof.matching`, 000 §3), the weighted SVD pose (:mod:`chaser.tof.pose`, 000
eqs 27–38, flag P000-10, docs/papers.md#p000-10) and, by default, its maximum-likelihood refinement
on the key points' pixels and ranges (:func:`chaser.tof.bound.ml_pose_refinement`).  The pose is reported as ``x, y, z``
(``r_CS_S``) and pitch, yaw, roll (3-2-1 sequence, see :mod:`chaser.tof.pose`).

Frames: ``S`` camera (OpenCV), ``C`` marker plate; ``p_S = R_SC q_C + r_CS_S`` (000 eq 1).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from chaser.tof.bound import ml_pose_refinement
from chaser.tof.extraction import ExtractionSettings, MarkerDetections, _why_none, extract_markers
from chaser.tof.matching import (
    MatchSettings,
    match_markers_hungarian,
    match_markers_mrf,
    match_markers_mrf_literal,
    verify_labels,
)
from chaser.tof.pose import pitch_yaw_roll_from_matrix, weighted_svd_pose
from vision.tof import MarkerPlate, TofCamera, TofFrame

__all__ = ["MATCHERS", "POSE_ESTIMATORS", "TofPoseResult", "estimate_tof_pose"]


#: Matcher names accepted by :func:`estimate_tof_pose`.
MATCHERS = ("mrf", "mrf-sinkhorn", "mrf-literal", "hungarian")

#: Pose estimators accepted by :func:`estimate_tof_pose`.
POSE_ESTIMATORS = ("svd", "ml")


@dataclass(frozen=True)
class TofPoseResult:
    """Pose of the marker plate from one TOF frame.

    Attributes
    ----------
    ok : bool
        False when the target was not found; ``failure_reason`` says why and the pose fields are NaN.
    failure_reason : str
        Empty when found; otherwise e.g. "all pixels saturated", "too few markers detected (2 < 3)".
    R_SC : (3, 3) ndarray
        Rotation C → S (000's ``T``).
    r_CS_S : (3,) ndarray
        Position of the plate origin in S (m): the reported x, y, z.
    pitch_yaw_roll_rad : (3,) ndarray
        3-2-1 Euler angles of ``R_SC`` in the order pitch, yaw, roll (see :mod:`chaser.tof.pose`).
    labels : (n,) int ndarray
        Model index of every detection (−1: not a model marker).
    n_matched : int
    rms_residual_m : float
        Weighted RMS 3-D residual of the matched markers after the fit.
    detections : MarkerDetections
    """

    ok: bool
    failure_reason: str
    R_SC: np.ndarray
    r_CS_S: np.ndarray
    pitch_yaw_roll_rad: np.ndarray
    labels: np.ndarray
    n_matched: int
    rms_residual_m: float
    detections: MarkerDetections

    @property
    def pitch_yaw_roll_deg(self) -> np.ndarray:
        """``pitch_yaw_roll_rad`` in degrees ``(3,)``."""
        return np.degrees(self.pitch_yaw_roll_rad)


def _not_found(failure_reason: str, det: MarkerDetections, labels: np.ndarray | None = None) -> TofPoseResult:
    nan3 = np.full(3, np.nan)
    lab = labels if labels is not None else np.full(det.n, -1, dtype=int)
    return TofPoseResult(False, failure_reason, np.full((3, 3), np.nan), nan3, nan3.copy(), lab,
                         int((lab >= 0).sum()), float("nan"), det)


def _keep_first_fits(det: MarkerDetections, det2: MarkerDetections) -> MarkerDetections:
    """``det2``, with the key points whose fit held in ``det`` but not in ``det2`` taken from ``det``
    (a poor first pose, e.g. from three markers, gives a plate plane that a dot's image rejects)."""
    back = det.centre_fitted & ~det2.centre_fitted
    if not back.any():
        return det2
    arrays = {}
    for name in ("uv_px", "range_m", "points_S", "range_sigma_m", "centroid_sigma_px", "centre_cov_px2", "centre_fitted"):
        a = getattr(det2, name).copy()
        a[back] = getattr(det, name)[back]
        arrays[name] = a
    return replace(det2, **arrays)


def estimate_tof_pose(frame: TofFrame, camera: TofCamera, plate: MarkerPlate, *, matcher: str = "mrf",
                      match_settings: MatchSettings | None = None,
                      extraction: ExtractionSettings | None = None, verify: bool = True,
                      gate_factor: float = 2.0, weighting: str = "inverse_variance",
                      pose_estimator: str = "ml") -> TofPoseResult:
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
    pose_estimator : {"ml", "svd"}
        ``"ml"`` (default): the weighted SVD pose refined to the maximum-likelihood pose of the key
        points' pixels and ranges (:func:`chaser.tof.bound.ml_pose_refinement`, weights from their
        standard errors), which reaches the Cramér–Rao bound of :func:`chaser.tof.bound.tof_pose_bound`
        on unbiased key points.  With fitted dot centres (``ExtractionSettings.centre_estimator="fit"``)
        the dots are then fitted again with the plate plane of that pose for their shape, and the ML
        step is repeated.  ``"svd"``: the weighted SVD of 000 eqs (27)–(38) alone, which weighs each 3-D
        point isotropically by its range noise and so does not use the pixels' precision.

    Returns
    -------
    TofPoseResult
        ``ok=False`` with a ``failure_reason`` (never an exception) for frames without a usable target.
    """
    if matcher not in MATCHERS:
        raise ValueError(f"matcher: must be one of {MATCHERS}, got {matcher!r}")
    if pose_estimator not in POSE_ESTIMATORS:
        raise ValueError(f"pose_estimator: must be one of {POSE_ESTIMATORS}, got {pose_estimator!r}")
    if weighting not in ("inverse_variance", "uniform"):
        raise ValueError(f"weighting: must be 'inverse_variance' or 'uniform', got {weighting!r}")
    st = match_settings or MatchSettings()
    det = extract_markers(frame, camera, plate, settings=extraction)
    if not det.ok:
        return _not_found(det.failure_reason, det)
    if det.n < 3:
        why = _why_none(frame, camera, plate.marker_radius_m * camera.fx_px / float(np.nanmedian(frame.range_m)))
        return _not_found(f"too few markers detected ({det.n} < 3){': ' + why if why else ''}", det)
    model = plate.markers_C
    if matcher == "mrf":
        match = match_markers_mrf(model, det.points_S, settings=st)
    elif matcher == "mrf-sinkhorn":
        match = match_markers_mrf(model, det.points_S, settings=replace(st, sinkhorn=True))
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
    R_SC, r_CS_S = fit.R_SC, fit.r_CS_S
    if pose_estimator != "svd":
        lab = labels[sel]
        for it in range(2 if (extraction or ExtractionSettings()).centre_estimator == "fit" else 1):
            if it:
                # the dots' shape from the plate plane of the pose of all markers instead of each dot's local
                # range plane, whose normal (0.2 deg of noise at 1 m) moves a fitted centre by about 0.003 px
                det2 = extract_markers(frame, camera, plate, settings=extraction,
                                       plate_plane_S=(R_SC[:, 2], float(R_SC[:, 2] @ r_CS_S)))
                if not (det2.ok and det2.n == det.n and np.all(np.abs(det2.uv_px - det.uv_px) < 1.0)):
                    break
                det = _keep_first_fits(det, det2)
            uv, rho = det.uv_px[sel], det.range_m[sel]
            s_px, s_rho = np.maximum(det.centroid_sigma_px[sel], 1e-5), np.maximum(det.range_sigma_m[sel], 1e-5)
            R_SC, r_CS_S = ml_pose_refinement(R_SC, r_CS_S, model[lab], uv, rho, camera, s_px, s_rho)
    return TofPoseResult(True, "", R_SC, r_CS_S, pitch_yaw_roll_from_matrix(R_SC), labels,
                         int(sel.size), float(fit.rms_residual_m), det)
