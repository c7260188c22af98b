"""Registration by geometry: a frame against a keyframe when descriptors cannot associate them.

When a face comes back after a tumble, or the target after an eclipse, the change of viewpoint is
beyond what descriptors survive (≈ 30° for SIFT on rendered images).  The two clouds are then
aligned by their shape with Open3D: ICP started from the smoother's predicted increment, and a
global FPFH + RANSAC alignment (:func:`reconstruction.registration.register_fpfh_ransac`).  For
each candidate motion the points are paired with their nearest neighbour within three σ of their
combined triangulation covariance, and the pairs are fitted by maximum likelihood
(:func:`reconstruction.registration.fit_rigid_ml`) and checked like any registration
(:func:`closed_loop.evidence.check_evidence`); the candidate with the most inliers is returned.
The caller still gates it against the predicted attitude before use.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from closed_loop.evidence import Evidence, check_evidence
from closed_loop.frames import Frame
from closed_loop.registrars import RegistrationIncrement
from reconstruction.registration import fit_rigid_ml, register_fpfh_ransac, register_icp

__all__ = ["register_by_geometry"]


def _valid(frame: Frame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    v = np.asarray(frame.tri.valid, bool) & np.all(np.isfinite(frame.tri.X_W), -1)
    return frame.tri.X_W[v], frame.tri.cov_W[v], np.flatnonzero(v)


def _pairs(P: np.ndarray, Q: np.ndarray, CP: np.ndarray, CQ: np.ndarray, R: np.ndarray, t: np.ndarray):
    """Nearest-neighbour pairs of ``R P + t`` in ``Q`` within 3σ of the pair's covariance."""
    d, j = cKDTree(Q).query(P @ R.T + t)
    sig = np.sqrt(np.trace(CQ[j], axis1=-2, axis2=-1) + np.trace(CP, axis1=-2, axis2=-1))
    keep = d < 3.0 * sig
    # one partner per Q point: the nearest claim wins
    order = np.argsort(d)
    first = np.zeros(len(Q), bool)
    sel = np.zeros(len(P), bool)
    for i in order[keep[order]]:
        if not first[j[i]]:
            first[j[i]] = True
            sel[i] = True
    return np.flatnonzero(sel), j[sel]


def register_by_geometry(kf: Frame, frame: Frame, dR_H_pred: np.ndarray, *, rng: np.random.Generator,
                         evidence: Evidence = Evidence(), voxel_size_m: float = 0.25) -> RegistrationIncrement:
    """The increment ``ρ_H(now) = ΔR ρ_H(keyframe)`` from the two clouds' shapes (module docstring).

    Parameters
    ----------
    kf, frame : closed_loop.frames.Frame
        The keyframe and the current epoch.
    dR_H_pred : ndarray (3, 3)
        Predicted increment (the ICP start).
    rng : numpy.random.Generator
        RANSAC draws.
    evidence : closed_loop.evidence.Evidence
    voxel_size_m : float
        FPFH scale (down-sampling voxel), m.

    Returns
    -------
    closed_loop.registrars.RegistrationIncrement
        ``n_matches`` is the number of nearest-neighbour pairs of the kept candidate.
    """
    if not (kf.ok and frame.ok):
        return RegistrationIncrement.failed("geometry: a frame is not observed")
    P, CP, track_P = _valid(kf)
    Q, CQ, track_Q = _valid(frame)
    if len(P) < evidence.min_inliers or len(Q) < evidence.min_inliers:
        return RegistrationIncrement.failed(f"geometry: fewer than {evidence.min_inliers} points")
    starts = []
    icp = register_icp(P, Q, max_correspondence_m=4 * voxel_size_m, R0=dR_H_pred, t0=np.zeros(3))
    if icp.ok:
        starts.append((icp.R, icp.t))
    glob = register_fpfh_ransac(P, Q, voxel_size_m=voxel_size_m, rng=rng)
    if glob.ok:
        starts.append((glob.R, glob.t))
    best: RegistrationIncrement | None = None
    why = "geometry: no alignment"
    for R0, t0 in starts:
        ip, iq = _pairs(P, Q, CP, CQ, R0, t0)
        if ip.size < evidence.min_inliers:
            why = f"geometry: {ip.size} nearest-neighbour pairs, fewer than {evidence.min_inliers}"
            continue
        reg = fit_rigid_ml(P[ip], Q[iq], CP[ip], CQ[iq], R0=R0, t0=t0, rng=rng)
        if not bool(reg.ok):
            why = f"geometry: {reg.failure_reason}"
            continue
        bad = check_evidence(P[ip], Q[iq], CP[ip], CQ[iq], reg.R, reg.t, reg.inliers, evidence)
        if bad:
            why = f"geometry: {bad}"
            continue
        inl = np.asarray(reg.inliers, dtype=bool)
        inc = RegistrationIncrement(R_H=reg.R, cov_rotvec_H=reg.cov[:3, :3], n_matches=int(ip.size),
                                    n_inliers=int(reg.n_inliers), ok=True, failure_reason="",
                                    inliers_prev=track_P[ip[inl]], inliers_curr=track_Q[iq[inl]])
        if best is None or inc.n_inliers > best.n_inliers:
            best = inc
    return best if best is not None else RegistrationIncrement.failed(why)
