"""Rendered-mode statistics measured against the renderer's per-pixel truth (``coobs calibrate``).

For each target, range and random attitude (with a random Sun direction, phase angle at most
``sun_phase_max_deg``) one reference view A is rendered and SIFT keypoints detected as the rendered
observation mode does (:func:`vision.render.render`, :func:`vision.rendered.foreground_mask`,
:func:`vision.features.detect`); then

* **detection density**: keypoints per m² of visible surface, binned by the cosine of the view
  angle and of the Sun incidence (shadowed surface its own bin), and per surface material, from the
  per-pixel depth, triangle and ``lit`` truth (the area of a pixel is ``(z/f)² / cos(view angle)``);
* **cross-view matching** with a second camera at ``cross_view_deg`` from A about the target (the
  same epoch, so the same lighting): :func:`vision.features.match_pair` (ratio 0.6, epipolar gate
  1.5 px); a match is correct when the surface points cast through both keypoints reproject within
  ``truth_tol_px`` of each other's keypoint (the test of :func:`vision.rendered.label_tracks`).
  *Survival* is correct matches over A's keypoints whose surface point the second camera sees
  (in the image, unoccluded); the *false-match rate* is wrong over all matches.  The same counts
  are kept per Sun phase bin of the pair (the Sun's angle from the pair's mean line of sight), with
  the keypoints the second camera detects again within ``truth_tol_px`` of their surface point, and
  per surface material and relative brightness of A's keypoint, and jointly per (phase, material,
  brightness, view angle) (:mod:`vision.calibration.survival_factors`);
* **keypoint localisation σ per SIFT size**: for correct matches, the residual between B's keypoint
  and the projection of the surface point under A's keypoint has variance σ²(size_A) + σ²(size_B)
  per axis; σ² per size bin is the non-negative least-squares solution over all matches;
* **three views**: a third camera at the first cross-view angle from both A and B; the tracks of the
  three views (:func:`vision.features.match_views`) against the matches of A and B alone tell how
  strongly the pair matches of one feature are correlated, with the share seen in all three;
* **track persistence**: the tracks of the first cross-view pair that are matched again between the
  same two cameras after the first epoch change (over those both cameras still see);
* **inter-epoch association**: A's matched keypoints (the tracks of the 10° pair) against the
  keypoints of A's camera after the target turned by ``epoch_change_deg`` about a random axis (the
  Sun fixed in H, so the lighting changes as in orbit), ratio test without a geometric gate as in
  :func:`reconstruction.association.associate`; survival is correct associations over those
  tracks still visible, the false-association rate wrong over all.

:func:`calibrate` returns the JSON-ready dict that :mod:`vision.calibration` reads; ``coobs
calibrate`` writes it to ``vision/calibration/rendered_sift.json``.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from attitude.quaternion import matrix_from_quat, quat_from_rotvec, quat_multiply, quat_normalize
from experiments.sweep import child_seeds
from vision.calibration import (
    COS_VIEW_EDGES,
    PHASE_EDGES_DEG,
    SIZE_EDGES_PX,
    SUN_BIN_EDGES,
    SiftCalibration,
)
from vision.calibration.detection_factors import sequential_expected_keypoints
from vision.camera import PinholeCamera, look_at
from vision.face_brightness import (
    BRIGHTNESS_EDGES,
    brightness_bin,
    face_radiance,
    material_optics,
    reference_radiance,
)
from vision.features import Keypoints, detect, fundamental_from_poses, match_pair, match_views
from vision.render import RenderResult, cast_body_points, render
from vision.rendered import foreground_mask
from vision.sensor import SensorModel
from vision.target import Target, fy1_target, load_mesh

__all__ = ["CalibrationSpec", "calibrate", "load_calibration_target", "QUICK", "DEFAULT"]

_QUANTILES = np.linspace(0.0, 1.0, 21)
#: size bins with fewer keypoints in correct matches get no σ (the model takes the nearest bin's)
_MIN_PAIRS_PER_BIN = 20


@dataclass(frozen=True)
class CalibrationSpec:
    """What ``coobs calibrate`` measures.

    Attributes
    ----------
    targets : tuple of str
        ``"fy1"`` (procedural FY-1-like) and/or bundled meshes (``"topex"``, ``"hubble"``).
    ranges_m : tuple of float
        Camera ranges, m.
    attitudes : int
        Random attitudes (each with its own Sun direction) per target and range.
    cross_view_deg : tuple of float
        Angles between the two cameras of the cross-view pairs, degrees (the first one also gives
        the tracks of the association test).
    epoch_change_deg : tuple of float
        Rotations of the target between the two epochs of the association test, degrees.
    seed : int
        Root seed.
    image_px, fov_deg : int, float
        Square camera and its field of view.
    sun_phase_max_deg : float
        Largest angle between the directions to the Sun and to the reference camera.
    ratio, epipolar_tol_px, truth_tol_px : float
        Ratio test, epipolar gate and the truth tolerance of a correct match.
    nees_attitudes, nees_angles_deg : int, tuple of float
        The σ² inflation step (:mod:`experiments.studies.nees_calibration`): its attitudes (the first
        ones of each range; 0 skips it) and the angles between its three cameras, degrees.
    """

    targets: tuple[str, ...] = ("fy1", "topex")
    ranges_m: tuple[float, ...] = (40.0, 80.0)
    attitudes: int = 96
    cross_view_deg: tuple[float, ...] = (10.0, 20.0)
    epoch_change_deg: tuple[float, ...] = (1.0, 2.0, 5.0, 10.0, 20.0, 30.0, 45.0, 60.0)
    seed: int = 2016
    image_px: int = 1024
    fov_deg: float = 20.0
    sun_phase_max_deg: float = 150.0
    ratio: float = 0.6
    epipolar_tol_px: float = 1.5
    truth_tol_px: float = 2.0
    nees_attitudes: int = 96
    nees_angles_deg: tuple[float, ...] = (10.0, 20.0)

    def __post_init__(self) -> None:
        if not self.targets:
            raise ValueError("targets: name at least one target")
        if not self.ranges_m or min(self.ranges_m) <= 0:
            raise ValueError(f"ranges_m: need positive ranges, got {self.ranges_m!r}")
        if int(self.attitudes) < 1:
            raise ValueError(f"attitudes: must be >= 1, got {self.attitudes!r}")
        if not self.cross_view_deg or not all(0 < a < 90 for a in self.cross_view_deg):
            raise ValueError(f"cross_view_deg: need angles in (0, 90), got {self.cross_view_deg!r}")
        if not self.epoch_change_deg or not all(0 < a <= 90 for a in self.epoch_change_deg):
            raise ValueError(f"epoch_change_deg: need angles in (0, 90], got {self.epoch_change_deg!r}")


#: ``coobs calibrate``'s default (≈ 8 min for the tables and 4 min for the σ² inflation on one core; the survival per phase needs 96 attitudes)
DEFAULT = CalibrationSpec()
#: ``coobs calibrate --quick``: one attitude per target and range, two epoch changes (a test)
QUICK = CalibrationSpec(attitudes=1, cross_view_deg=(10.0,), epoch_change_deg=(2.0, 20.0), nees_attitudes=1,
                        nees_angles_deg=(10.0,))


def load_calibration_target(name: str) -> Target:
    """The target a calibration names: ``"fy1"`` or a bundled mesh."""
    return fy1_target() if name == "fy1" else load_mesh(name)


def _render(cam: PinholeCamera, T_CW: np.ndarray, target: Target, q_HT: np.ndarray, sun_H: np.ndarray,
            rng: np.random.Generator) -> tuple[RenderResult, Keypoints]:
    r = render(cam, T_CW, target, q_HT, sun_H, rng=rng)
    if not r.ok:
        return r, detect(np.zeros((8, 8), np.uint8))
    return r, detect(r.image, roi=r.roi, mask=foreground_mask(r.image))


def _project(r: RenderResult, q_HT: np.ndarray, X_T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel position and z-depth of body points in a rendered view."""
    X_C = (r.T_CW[:3, :3] @ (matrix_from_quat(q_HT) @ X_T.T)).T + r.T_CW[:3, 3]
    return r.camera.project(X_C), X_C[:, 2]


def _phase_bin(sun: np.ndarray, line_of_sight: np.ndarray) -> int:
    """Phase bin of the Sun direction seen along ``line_of_sight`` (target to camera(s), any length)."""
    c = float(sun @ line_of_sight) / float(np.linalg.norm(line_of_sight))
    phase = np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))
    return min(int(np.searchsorted(PHASE_EDGES_DEG, phase, side="right")) - 1, len(PHASE_EDGES_DEG) - 2)


def _redetected(uv_expected: np.ndarray, uv_keypoints: np.ndarray, tol_px: float) -> int:
    """How many expected positions have a keypoint within ``tol_px``."""
    from scipy.spatial import cKDTree

    if len(uv_expected) == 0 or len(uv_keypoints) == 0:
        return 0
    d, _ = cKDTree(uv_keypoints).query(uv_expected, distance_upper_bound=tol_px)
    return int(np.sum(np.isfinite(d)))


def _count_materials(counts: np.ndarray, material: np.ndarray) -> None:
    """Add the keypoints of each material (or other class; -1: off the target) to ``counts``."""
    counts += np.bincount(material[material >= 0], minlength=len(counts))[: len(counts)]


def _count_joint(counts: np.ndarray, phase_bin: int, material: np.ndarray, *bins: np.ndarray) -> None:
    """Add keypoints to ``counts (phase, material, brightness, view)`` at the pair's phase bin (as :func:`_count_materials`)."""
    on = material >= 0
    np.add.at(counts[phase_bin], (material[on], *(b[on] for b in bins)), 1)


def _seen_in(r: RenderResult, q_HT: np.ndarray, X_T: np.ndarray) -> np.ndarray:
    """Body points inside the image of ``r`` and not hidden (depth within 1 % of the rendered depth)."""
    uv, z = _project(r, q_HT, X_T)
    H, W = r.mask.shape
    ok = np.all(np.isfinite(uv), axis=1) & (z > 0)
    ui = np.clip(np.rint(np.nan_to_num(uv[:, 0])).astype(int), 0, W - 1)
    vi = np.clip(np.rint(np.nan_to_num(uv[:, 1])).astype(int), 0, H - 1)
    ok &= (uv[:, 0] >= 0) & (uv[:, 0] <= W - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= H - 1)
    d = r.depth_z_m[vi, ui]
    return ok & np.isfinite(d) & (np.abs(d - z) <= 0.01 * z + 0.02)


def _body_points(r: RenderResult, target: Target, q_HT: np.ndarray, uv: np.ndarray) -> np.ndarray:
    X, _ = cast_body_points(r.camera, r.T_CW, target, q_HT, uv)
    miss = ~np.isfinite(X[:, 0])
    if miss.any():
        X[miss] = r.body_points_at(uv[miss])
    return X


def _correct(rA, qA, XA, uvA, rB, qB, XB, uvB, tol_px):
    """Both-way reprojection test of matched keypoints (as :func:`vision.rendered.label_tracks`)."""
    e1 = np.linalg.norm(_project(rB, qB, XA)[0] - uvB, axis=1)
    e2 = np.linalg.norm(_project(rA, qA, XB)[0] - uvA, axis=1)
    with np.errstate(invalid="ignore"):
        return (e1 <= tol_px) & (e2 <= tol_px)


def _surface_geometry(r: RenderResult, target: Target, q_HT: np.ndarray, sun_H: np.ndarray):
    """Per target pixel: view-angle bin, Sun bin, pixel area (m²), material and relative-brightness
    bin (:mod:`vision.face_brightness`); and the pixel indices."""
    R_HT = matrix_from_quat(q_HT)
    v, u = np.nonzero(r.mask)
    n_T = target.triangle_normals_T[r.triangle_id[v, u]]
    X_T = r.X_T[v, u].astype(float)
    c_T = -(R_HT.T @ r.T_CW[:3, :3].T @ r.T_CW[:3, 3])
    to_cam = c_T - X_T
    to_cam /= np.linalg.norm(to_cam, axis=1, keepdims=True)
    cos_v = np.sum(n_T * to_cam, axis=1)
    side = np.where(cos_v >= 0, 1.0, -1.0)
    cos_v = np.abs(cos_v)
    s_T = R_HT.T @ (sun_H / np.linalg.norm(sun_H))
    cos_s = side * (n_T @ s_T)
    sun_bin = np.where(r.lit[v, u], np.clip(np.searchsorted(SUN_BIN_EDGES, cos_s, side="right") - 1,
                                            1, len(SUN_BIN_EDGES) - 2), 0)
    view_bin = np.clip(np.searchsorted(COS_VIEW_EDGES, cos_v, side="right") - 1, 0, len(COS_VIEW_EDGES) - 2)
    f = np.sqrt(r.camera.K[0, 0] * r.camera.K[1, 1])
    area = (r.depth_z_m[v, u].astype(float) / f) ** 2 / np.maximum(cos_v, 0.05)
    mat = target.triangle_material[r.triangle_id[v, u]]
    h = to_cam + s_T
    h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
    n_dot_h = side * np.sum(n_T * h, axis=1)
    optics = material_optics(target)
    ref = reference_radiance(face_radiance(mat, cos_s, n_dot_h, cos_s > 0, optics))     # one weight per pixel
    b = face_radiance(mat, cos_s, n_dot_h, r.lit[v, u], optics) / ref
    return v, u, view_bin, sun_bin, area, mat, brightness_bin(b)


def _size_bin(size_px: np.ndarray) -> np.ndarray:
    return np.clip(np.searchsorted(SIZE_EDGES_PX, size_px, side="right") - 1, 0, len(SIZE_EDGES_PX) - 2)


class _Tally:
    """Counts of one (target, range) accumulated over the attitudes."""

    def __init__(self, spec: CalibrationSpec, n_materials: int):
        nv, ns, nz = len(COS_VIEW_EDGES) - 1, len(SUN_BIN_EDGES) - 1, len(SIZE_EDGES_PX) - 1
        self.kp = np.zeros((nv, ns))
        self.area = np.zeros((nv, ns))
        self.mat_kp = np.zeros(n_materials)
        self.mat_area = np.zeros(n_materials)
        # per relative-brightness bin: keypoints, and the area per (view, Sun, material) bin the
        # density tables would fill it with (the factor's prediction, vision.calibration.model)
        self.bright_kp = np.zeros(len(BRIGHTNESS_EDGES) - 1)
        self.bright_area = np.zeros((len(BRIGHTNESS_EDGES) - 1, nv, ns, n_materials))
        self.joint_kp = np.zeros(self.bright_area.shape, dtype=np.int64)   # the joint detection factors
        self.phase_kp = np.zeros(len(PHASE_EDGES_DEG) - 1)
        self.phase_area = np.zeros(len(PHASE_EDGES_DEG) - 1)
        a, d = len(spec.cross_view_deg), len(spec.epoch_change_deg)
        self.cv = {k: np.zeros(a) for k in ("matchable", "matches", "correct")}
        # the same counts per Sun phase bin of the pair (the Sun's angle from the pair's mean line of sight)
        self.cv_phase = {k: np.zeros((a, len(PHASE_EDGES_DEG) - 1)) for k in ("matchable", "redetected", "correct")}
        # and per material of A's keypoint
        self.cv_material = {k: np.zeros((a, n_materials)) for k in ("matchable", "correct")}
        # and per relative-brightness bin of A's keypoint
        self.cv_brightness = {k: np.zeros((a, len(BRIGHTNESS_EDGES) - 1), dtype=np.int64) for k in ("matchable", "correct")}
        # and jointly per (Sun phase, material, relative brightness, view angle): the joint survival factors
        self.cv_joint = {k: np.zeros((a, len(PHASE_EDGES_DEG) - 1, n_materials, len(BRIGHTNESS_EDGES) - 1, nv),
                                     dtype=np.int64) for k in ("matchable", "correct")}
        self.ep = {k: np.zeros(d) for k in ("tracks_visible", "redetected", "associations", "correct")}
        self.pair_bins: list[np.ndarray] = []   # (k, 2) size bins of A and B
        self.pair_e2: list[np.ndarray] = []     # (k,) mean squared residual per axis, px²
        self.track_sizes: list[np.ndarray] = []
        self.nz = nz
        self.tracks2 = 0
        self.tracks3 = 0
        self.tracks3_full = 0       # of those, the tracks seen in all three views
        self.persist_num = 0
        self.persist_den = 0
        self.samples = 0


def _sample(spec: CalibrationSpec, target: Target, cam: PinholeCamera, range_m: float,
            ss: np.random.SeedSequence, t: _Tally) -> None:
    s_geo, s_img = child_seeds(ss, 2)
    g = np.random.default_rng(s_geo)
    # one stream per image: A, the cross-view cameras, the epoch changes, the third camera, then B after
    # the first epoch change (appended last, so the other images keep their streams)
    n_img = 1 + len(spec.cross_view_deg) + len(spec.epoch_change_deg)
    img_rngs = np.random.default_rng(s_img).spawn(n_img + 2)
    q = quat_normalize(g.normal(size=4))
    eA = g.normal(size=3)
    eA /= np.linalg.norm(eA)
    while True:  # Sun within the phase limit of camera A
        sun = g.normal(size=3)
        sun /= np.linalg.norm(sun)
        if np.degrees(np.arccos(np.clip(sun @ eA, -1, 1))) <= spec.sun_phase_max_deg:
            break
    up = np.cross(eA, g.normal(size=3))
    up /= np.linalg.norm(up)
    T_A = look_at(range_m * eA, np.zeros(3), up)
    rA, kA = _render(cam, T_A, target, q, sun, img_rngs[0])
    t.samples += 1
    if not rA.ok:
        return
    v, u, vb, sb, area, mat, bb = _surface_geometry(rA, target, q, sun)
    np.add.at(t.area, (vb, sb), area)
    np.add.at(t.bright_area, (bb, vb, sb, mat), area)
    np.add.at(t.mat_area, mat, area)
    pb = _phase_bin(sun, eA)
    t.phase_area[pb] += area.sum()
    pix = np.full(rA.mask.shape, -1, dtype=np.int64)
    pix[v, u] = np.arange(len(v))
    ki = np.clip(np.rint(kA.uv_px).astype(int), 0, np.array(rA.mask.shape[::-1]) - 1)
    on = pix[ki[:, 1], ki[:, 0]]
    hit = on >= 0
    np.add.at(t.kp, (vb[on[hit]], sb[on[hit]]), 1.0)
    np.add.at(t.mat_kp, mat[on[hit]], 1.0)
    np.add.at(t.bright_kp, bb[on[hit]], 1.0)
    np.add.at(t.joint_kp, (bb[on[hit]], vb[on[hit]], sb[on[hit]], mat[on[hit]]), 1)
    t.phase_kp[pb] += hit.sum()
    # material, relative-brightness bin and view-angle bin under each keypoint (-1: off the target)
    kp_mat, kp_bb, kp_vb = (np.where(hit, x[np.maximum(on, 0)], -1) for x in (mat, bb, vb))
    if len(kA) < 2:
        return
    XA = _body_points(rA, target, q, kA.uv_px)
    fin = np.all(np.isfinite(XA), axis=1)
    tracks = np.zeros(0, dtype=np.int64)
    # cross-view pairs: the second camera turned about the target by the angle, about a random axis ⟂ eA
    axis = np.cross(eA, g.normal(size=3))
    axis /= np.linalg.norm(axis)
    for a, ang in enumerate(spec.cross_view_deg):
        R = matrix_from_quat(quat_from_rotvec(np.radians(ang) * axis))
        T_B = look_at(range_m * (R @ eA), np.zeros(3), R @ up)
        rB, kB = _render(cam, T_B, target, q, sun, img_rngs[1 + a])
        if not rB.ok or len(kB) < 2:
            continue
        seenB = np.zeros(len(kA), bool)
        seenB[fin] = _seen_in(rB, q, XA[fin])
        t.cv["matchable"][a] += seenB.sum()
        pp = _phase_bin(sun, eA + R @ eA)
        t.cv_phase["matchable"][a, pp] += seenB.sum()
        t.cv_phase["redetected"][a, pp] += _redetected(_project(rB, q, XA[seenB])[0], kB.uv_px, spec.truth_tol_px)
        _count_materials(t.cv_material["matchable"][a], kp_mat[seenB])
        _count_materials(t.cv_brightness["matchable"][a], kp_bb[seenB])
        _count_joint(t.cv_joint["matchable"][a], pp, kp_mat[seenB], kp_bb[seenB], kp_vb[seenB])
        F = fundamental_from_poses(cam.K, T_A, cam.K, T_B)
        m = match_pair(kA, kB, ratio=spec.ratio, F_AB=F, epipolar_tol_px=spec.epipolar_tol_px)
        if len(m) == 0:
            continue
        XB = _body_points(rB, target, q, kB.uv_px[m[:, 1]])
        ok = _correct(rA, q, XA[m[:, 0]], kA.uv_px[m[:, 0]], rB, q, XB, kB.uv_px[m[:, 1]], spec.truth_tol_px)
        t.cv["matches"][a] += len(m)
        t.cv["correct"][a] += ok.sum()
        t.cv_phase["correct"][a, pp] += ok.sum()
        _count_materials(t.cv_material["correct"][a], kp_mat[m[ok, 0]])
        _count_materials(t.cv_brightness["correct"][a], kp_bb[m[ok, 0]])
        _count_joint(t.cv_joint["correct"][a], pp, kp_mat[m[ok, 0]], kp_bb[m[ok, 0]], kp_vb[m[ok, 0]])
        mc = m[ok]
        res = kB.uv_px[mc[:, 1]] - _project(rB, q, XA[mc[:, 0]])[0]
        t.pair_e2.append(np.mean(res**2, axis=1))
        t.pair_bins.append(np.stack([_size_bin(kA.size_px[mc[:, 0]]), _size_bin(kB.size_px[mc[:, 1]])], axis=1))
        if a == 0:
            T_B0 = T_B
            tracks = mc[:, 0]
            t.track_sizes.append(kA.size_px[tracks])
            # a third camera at the same angle from A and B: 3-view tracks against 2-view ones
            R60 = matrix_from_quat(quat_from_rotvec(np.radians(60.0) * eA))
            Rc = matrix_from_quat(quat_from_rotvec(np.radians(ang) * (R60 @ axis)))
            T_C = look_at(range_m * (Rc @ eA), np.zeros(3), Rc @ up)
            rC, kC = _render(cam, T_C, target, q, sun, img_rngs[n_img])
            if rC.ok and len(kC) >= 2:
                obs3 = match_views([kA, kB, kC], cam, np.stack([T_A, T_B, T_C]), ratio=spec.ratio,
                                   epipolar_tol_px=spec.epipolar_tol_px)
                t.tracks2 += len(m)
                t.tracks3 += obs3.n_tracks
                t.tracks3_full += int(np.sum(obs3.seen.all(axis=1)))
    if len(tracks) == 0:
        return
    kT = kA.subset(tracks)
    XT = XA[tracks]
    ax2 = g.normal(size=3)
    ax2 /= np.linalg.norm(ax2)
    for d, ang in enumerate(spec.epoch_change_deg):
        q2 = quat_normalize(quat_multiply(quat_from_rotvec(np.radians(ang) * ax2), q))
        r2, k2 = _render(cam, T_A, target, q2, sun, img_rngs[1 + len(spec.cross_view_deg) + d])
        if not r2.ok or len(k2) < 2:
            continue
        vis = _seen_in(r2, q2, XT)
        t.ep["tracks_visible"][d] += vis.sum()
        uv2 = _project(r2, q2, XT)[0]
        if vis.any():
            dist = np.linalg.norm(uv2[vis][:, None, :] - k2.uv_px[None, :, :], axis=2)
            t.ep["redetected"][d] += np.sum(dist.min(axis=1) <= spec.truth_tol_px)
        m = match_pair(kT, k2, ratio=spec.ratio)
        if len(m) == 0:
            continue
        X2 = _body_points(r2, target, q2, k2.uv_px[m[:, 1]])
        ok = _correct(rA, q, XT[m[:, 0]], kT.uv_px[m[:, 0]], r2, q2, X2, k2.uv_px[m[:, 1]], spec.truth_tol_px)
        t.ep["associations"][d] += len(m)
        t.ep["correct"][d] += ok.sum()
        if d == 0:
            _persistence(spec, target, cam, T_A, T_B0, q2, sun, r2, k2, XT, img_rngs[n_img + 1], t)


def _persistence(spec, target, cam, T_A, T_B, q2, sun, r2, k2, XT, rng, t) -> None:
    """Tracks of the first cross-view pair that are tracks again after the first epoch change."""
    vis = _seen_in(r2, q2, XT)
    rB2, kB2 = _render(cam, T_B, target, q2, sun, rng)
    if not vis.any() or not rB2.ok or len(kB2) < 2 or len(k2) < 2:
        return
    vis &= _seen_in(rB2, q2, XT)
    t.persist_den += int(vis.sum())
    m = match_pair(k2, kB2, ratio=spec.ratio, F_AB=fundamental_from_poses(cam.K, T_A, cam.K, T_B),
                   epipolar_tol_px=spec.epipolar_tol_px)
    if len(m) == 0:
        return
    uv = _project(r2, q2, XT[vis])[0]
    d = np.linalg.norm(uv[:, None, :] - k2.uv_px[m[:, 0]][None, :, :], axis=2)
    t.persist_num += int(np.sum(d.min(axis=1) <= spec.truth_tol_px))


def _sigma_per_bin(bins: np.ndarray, e2: np.ndarray, nz: int) -> tuple[np.ndarray, np.ndarray]:
    """σ per size bin from residual pairs, ``e2_k = σ²[b_A] + σ²[b_B]`` (non-negative least squares)."""
    from scipy.optimize import nnls

    counts = np.bincount(bins.ravel(), minlength=nz).astype(float)
    used = np.nonzero(counts > 0)[0]
    if len(e2) == 0:
        return np.full(nz, np.nan), counts
    A = np.zeros((len(e2), len(used)))
    col = {b: i for i, b in enumerate(used)}
    for k in range(2):
        np.add.at(A, (np.arange(len(e2)), [col[b] for b in bins[:, k]]), 1.0)
    s2, _ = nnls(A, e2)
    sigma = np.full(nz, np.nan)
    sigma[used] = np.sqrt(s2)
    if np.any(counts >= _MIN_PAIRS_PER_BIN):  # a small run (--quick) keeps what it has
        sigma[counts < _MIN_PAIRS_PER_BIN] = np.nan
    return sigma, counts


def _coobs_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("coobs")
    except PackageNotFoundError:
        return "0+unknown"


def _ratio(num: np.ndarray, den: np.ndarray) -> list:
    with np.errstate(invalid="ignore", divide="ignore"):
        return [None if not d > 0 else float(n / d) for n, d in zip(np.ravel(num), np.ravel(den), strict=True)]


def calibrate(spec: CalibrationSpec = DEFAULT, *, command: str = "",
              progress: Callable[[int, int], None] | None = None) -> dict:
    """Measure the rendered mode's statistics (module docstring); a JSON-ready dict with its provenance."""
    t0 = time.perf_counter()
    cam = PinholeCamera.from_fov(spec.image_px, spec.image_px, fov_x_deg=spec.fov_deg)
    f_px = float(np.sqrt(cam.K[0, 0] * cam.K[1, 1]))
    total = len(spec.targets) * len(spec.ranges_m) * int(spec.attitudes)
    done = 0
    out_targets = {}
    root = np.random.SeedSequence(int(spec.seed))
    for ti, (name, ss_t) in enumerate(zip(spec.targets, root.spawn(len(spec.targets)), strict=True)):
        target = load_calibration_target(name)
        per_range = []
        for ss_r, range_m in zip(ss_t.spawn(len(spec.ranges_m)), spec.ranges_m, strict=True):
            t = _Tally(spec, len(target.materials))
            for ss in ss_r.spawn(int(spec.attitudes)):
                _sample(spec, target, cam, float(range_m), ss, t)
                done += 1
                if progress:
                    progress(done, total)
            per_range.append(t)
        out_targets[name] = _target_summary(spec, target, per_range, f_px)
        del ti
    data = {
        "format": "coobs rendered SIFT calibration",
        "format_version": 2,
        "size_edges_px": list(SIZE_EDGES_PX[:-1]) + ["inf"],
        "cos_view_edges": list(COS_VIEW_EDGES),
        "sun_bin_edges": list(SUN_BIN_EDGES),
        "sun_bins": "bin 0: surface not lit (shadowed or facing away); bins 1..: cosine of the Sun incidence",
        "phase_edges_deg": list(PHASE_EDGES_DEG),
        "brightness_edges": list(BRIGHTNESS_EDGES[:-1]) + ["inf"],
        "provenance": {
            "command": command,
            "coobs_version": _coobs_version(),
            "created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "wall_s": round(time.perf_counter() - t0, 1),
            "spec": {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(spec).items()},
            "renderer": {"function": "vision.render.render", "image_px": spec.image_px, "fov_deg": spec.fov_deg,
                         "ambient": 0.0, "specular": True, "shadows": True, "roi": True,
                         "sensor": dataclasses.asdict(SensorModel())},
            "detector": {"name": "sift", "opencv_options": {"enable_precise_upscale": True},
                         "mask": "vision.rendered.foreground_mask (> 3 DN, closed)"},
            "matching": {"function": "vision.features.match_pair", "ratio": spec.ratio,
                         "epipolar_tol_px": spec.epipolar_tol_px, "truth_tol_px": spec.truth_tol_px},
        },
        "targets": out_targets,
    }
    if int(spec.nees_attitudes) > 0:
        from experiments.studies.nees_calibration import NeesSpec, add_triangulation_nees

        nees = NeesSpec(attitudes=int(spec.nees_attitudes), angles_deg=tuple(spec.nees_angles_deg),
                        sun_phase_max_deg=spec.sun_phase_max_deg, ratio=spec.ratio,
                        epipolar_tol_px=spec.epipolar_tol_px, truth_tol_px=spec.truth_tol_px)
        data = add_triangulation_nees(data, nees, command=command)
        data["provenance"]["wall_s"] = round(time.perf_counter() - t0, 1)
    return data


def _target_summary(spec: CalibrationSpec, target: Target, per_range: Sequence[_Tally], f_px: float) -> dict:
    nz = per_range[0].nz
    sig_by_range, cnt_by_range, quant = [], [], []
    all_bins, all_e2 = [], []
    for t in per_range:
        b = np.concatenate(t.pair_bins) if t.pair_bins else np.zeros((0, 2), int)
        e2 = np.concatenate(t.pair_e2) if t.pair_e2 else np.zeros(0)
        all_bins.append(b)
        all_e2.append(e2)
        s, c = _sigma_per_bin(b, e2, nz)
        sig_by_range.append([None if not np.isfinite(x) else round(float(x), 4) for x in s])
        cnt_by_range.append(c.astype(int).tolist())
        sizes = np.concatenate(t.track_sizes) if t.track_sizes else np.zeros(0)
        quant.append([round(float(x), 3) for x in np.quantile(sizes, _QUANTILES)] if sizes.size else None)
    s_all, c_all = _sigma_per_bin(np.concatenate(all_bins), np.concatenate(all_e2), nz)
    e2_all = np.concatenate(all_e2)
    out = {
        "name": target.name,
        "area_m2": round(float(target.triangle_areas_m2.sum()), 3),
        "samples_per_range": [t.samples for t in per_range],
        "ranges_m": list(spec.ranges_m),
        "footprint_m_per_px": [float(r) / f_px for r in spec.ranges_m],
        "sigma_px": [None if not np.isfinite(x) else round(float(x), 4) for x in s_all],
        "sigma_pairs_per_bin": c_all.astype(int).tolist(),
        "sigma_px_by_range": sig_by_range,
        "sigma_pairs_per_bin_by_range": cnt_by_range,
        "pair_residual_rms_px_per_axis": round(float(np.sqrt(np.mean(e2_all))), 4) if e2_all.size else None,
        "size_quantiles": list(_QUANTILES.round(3)),
        "track_size_px_quantiles_by_range": quant,
        "keypoints": [t.kp.astype(int).tolist() for t in per_range],
        "visible_area_m2": [t.area.round(4).tolist() for t in per_range],
        "materials": [m.name for m in target.materials],
        "material_keypoints": [t.mat_kp.astype(int).tolist() for t in per_range],
        "material_area_m2": [t.mat_area.round(4).tolist() for t in per_range],
        "phase_keypoints": [t.phase_kp.astype(int).tolist() for t in per_range],
        "phase_area_m2": [t.phase_area.round(3).tolist() for t in per_range],
        "brightness_keypoints": [t.bright_kp.astype(int).tolist() for t in per_range],
        "cross_view": {
            "angle_deg": list(spec.cross_view_deg),
            **{k: [t.cv[k].astype(int).tolist() for t in per_range] for k in ("matchable", "matches", "correct")},
            "survival": [_ratio(t.cv["correct"], t.cv["matchable"]) for t in per_range],
            "false_match_rate": [_ratio(t.cv["matches"] - t.cv["correct"], t.cv["matches"]) for t in per_range],
            "two_view_tracks": [t.tracks2 for t in per_range],
            "persistent_tracks": [t.persist_num for t in per_range],
            "persistence_candidates": [t.persist_den for t in per_range],
            "persistence": [None if not t.persist_den else t.persist_num / t.persist_den for t in per_range],
            "three_view_tracks": [t.tracks3 for t in per_range],
            "three_view_full_tracks": [t.tracks3_full for t in per_range],
            **{f"phase_{k}": [t.cv_phase[k].astype(int).tolist() for t in per_range]
               for k in ("matchable", "redetected", "correct")},
            **{f"{c}_{k}": [getattr(t, f"cv_{c}")[k].astype(int).tolist() for t in per_range]
               for c in ("material", "brightness") for k in ("matchable", "correct")},
        },
        "association": {
            "change_deg": list(spec.epoch_change_deg),
            **{k: [t.ep[k].astype(int).tolist() for t in per_range]
               for k in ("tracks_visible", "redetected", "associations", "correct")},
            "survival": [_ratio(t.ep["correct"], t.ep["tracks_visible"]) for t in per_range],
            "false_rate": [_ratio(t.ep["associations"] - t.ep["correct"], t.ep["associations"]) for t in per_range],
        },
    }
    # the tables so far (the range-and-angle survival, the sequential density and material factors)
    cal = SiftCalibration.from_dict({"targets": {"t": out}}, "t")
    # joint counts pooled over ranges and angles: correct, and expected at the range-and-angle table
    joint = {k: np.stack([t.cv_joint[k] for t in per_range]) for k in ("matchable", "correct")}   # (R, A, P, M, B, V)
    out["cross_view"].update(joint_expected=np.einsum("rapmbv,ra->pmbv", joint["matchable"], cal.pair_survival)
                             .round(3).tolist(), joint_correct=joint["correct"].sum(axis=(0, 1)).tolist())
    # the sequential brightness factor's denominator (files read without the joint fit), then the
    # joint counts per (brightness, view, Sun, material) bin (vision.calibration.detection_factors)
    area = np.stack([t.bright_area for t in per_range])
    out["brightness_expected_keypoints"] = sequential_expected_keypoints(
        cal.density_per_m2, cal.material_factor, area).round(2).tolist()
    out["detection_joint"] = {"area_m2": area.round(4).tolist(),
                              "keypoints": np.stack([t.joint_kp for t in per_range]).tolist()}
    return out
