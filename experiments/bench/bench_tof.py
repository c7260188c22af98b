"""TOF cooperative-marker (000) benchmarks at the SR4000 resolution (176 × 144).

* the whole pose chain on one frame (:func:`chaser.tof.estimate_tof_pose`: extraction, corrected
  MRF matching, pose verification, weighted SVD), frames per second, against the same chain with
  OpenCV's ``SimpleBlobDetector`` for the dots (range: mean over a disc of the detected size, eq 5),
  the Hungarian baseline with verification and the SVD pose — the off-the-shelf way of doing it —
  with the attitude accuracy of both in the note;
* marker extraction alone against ``cv2.SimpleBlobDetector``;
* the weighted SVD pose batched over problems against ``scipy.spatial.transform.Rotation.align_vectors``
  called per problem;
* the corrected MRF matcher batched over 1000 problems, per problem, against the Hungarian baseline;
* rendering one frame (Open3D ray casting, 3 × 3 sub-rays), no peer.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from experiments.bench import BenchRow, best_time, throughput_row


def _blob_detector(min_area_px: float, max_area_px: float):
    p = cv2.SimpleBlobDetector_Params()
    p.filterByColor, p.blobColor = True, 0
    p.filterByArea, p.minArea, p.maxArea = True, min_area_px, max_area_px
    p.filterByCircularity = p.filterByConvexity = False
    p.filterByInertia, p.minInertiaRatio = True, 0.3
    return cv2.SimpleBlobDetector_create(p)


def run(*, quick: bool) -> list[BenchRow]:
    from attitude.matrix import rotation_angle
    from chaser.tof import (
        estimate_tof_pose,
        extract_markers,
        match_markers_hungarian,
        match_markers_mrf,
        random_matching_trials,
        verify_labels,
        weighted_svd_pose,
    )
    from vision.tof import CooperativeTarget, points_from_pixel_range, render_tof_frame, sr4000

    cam = sr4000()
    target = CooperativeTarget()
    plate = target.plate
    r_true = np.array([0.0, 0.0, 0.7])
    n_frames = 4 if quick else 16
    frames = [render_tof_frame(cam, target, np.eye(3), r_true, rng=s) for s in range(n_frames)]
    dot_px = plate.marker_radius_m * cam.fx_px / 0.7
    detector = _blob_detector(0.3 * np.pi * dot_px**2, 3.0 * np.pi * dot_px**2)
    model = plate.markers_C

    def peer_pose(frame):
        img = np.clip(frame.amplitude_dn / np.percentile(frame.amplitude_dn, 99.5) * 255, 0, 255).astype(np.uint8)
        kps = detector.detect(img)
        if len(kps) < 3:
            return None
        uv = np.array([k.pt for k in kps])
        v, u = np.indices(frame.range_m.shape)
        rho = np.array([np.nanmean(frame.range_m[(u - a) ** 2 + (v - b) ** 2 <= (k.size / 2) ** 2])
                        for (a, b), k in zip(uv, kps, strict=True)])
        pts = points_from_pixel_range(uv[:, 0], uv[:, 1], rho, cam)
        lab = verify_labels(model, pts, match_markers_hungarian(model, pts).labels, gate_m=0.02)
        sel = lab >= 0
        return weighted_svd_pose(model[lab[sel]], pts[sel]) if sel.sum() >= 3 else None

    def ours_all():
        return [estimate_tof_pose(f, cam, plate) for f in frames]

    def peer_all():
        return [peer_pose(f) for f in frames]

    t_ours = best_time(ours_all, repeat=3) / n_frames
    t_peer = best_time(peer_all, repeat=3) / n_frames
    err_ours = [np.degrees(rotation_angle(r.R_SC)) for r in ours_all()]
    err_peer = [np.degrees(rotation_angle(r.R_SC)) if r is not None else np.nan for r in peer_all()]
    rows = [throughput_row(
        "000 TOF pose chain, 176x144 frame (extract + MRF match + verify + SVD)", t_ours, t_peer, 1, "frames/s",
        "cv2.SimpleBlobDetector + disc-mean range + Hungarian + SVD",
        f"700 mm, {n_frames} frames: RMS attitude error ours {np.sqrt(np.mean(np.square(err_ours))):.3f} deg, "
        f"peer {np.sqrt(np.nanmean(np.square(err_peer))):.3f} deg")]

    t_ext = best_time(lambda: [extract_markers(f, cam, plate) for f in frames], repeat=3) / n_frames
    t_blob = best_time(lambda: [detector.detect(np.clip(f.amplitude_dn / 60, 0, 255).astype(np.uint8))
                                for f in frames], repeat=3) / n_frames
    rows.append(throughput_row("000 marker extraction, 176x144 frame", t_ext, t_blob, 1, "frames/s",
                               "cv2.SimpleBlobDetector (2-D keypoints only)",
                               "ours adds contrast-weighted centroids, plate-plane ranges and eq-5 points"))

    n_pose = 2_000 if quick else 20_000
    rng = np.random.default_rng(5)
    R = Rotation.random(n_pose, random_state=rng).as_matrix()
    p = np.einsum("tij,mj->tmi", R, model) + r_true + 0.001 * rng.standard_normal((n_pose, len(model), 3))
    w = rng.uniform(0.5, 2.0, (n_pose, len(model)))

    def peer_svd():
        out = []
        for k in range(n_pose):
            qb, pb = (w[k, :, None] * model).sum(0) / w[k].sum(), (w[k, :, None] * p[k]).sum(0) / w[k].sum()
            out.append(Rotation.align_vectors(p[k] - pb, model - qb, weights=w[k])[0])
        return out

    t_svd = best_time(lambda: weighted_svd_pose(model, p, w), repeat=3)
    t_svd_peer = best_time(peer_svd, repeat=1)
    rows.append(throughput_row(f"000 weighted SVD pose (eqs 27-38), batch of {n_pose}", t_svd, t_svd_peer, n_pose,
                               "poses/s", "scipy Rotation.align_vectors per problem", "6 planar markers"))

    n_match = 200 if quick else 1000
    trials = random_matching_trials(plate, n_match, n_missing=1, n_spurious=1, rng=6)
    t_mrf = best_time(lambda: match_markers_mrf(model, trials.points_S), repeat=1)
    t_hun = best_time(lambda: match_markers_hungarian(model, trials.points_S), repeat=1)
    ok_mrf = np.mean(np.all(match_markers_mrf(model, trials.points_S).labels == trials.truth, axis=1))
    ok_hun = np.mean(np.all(match_markers_hungarian(model, trials.points_S).labels == trials.truth, axis=1))
    rows.append(throughput_row(f"000 MRF annealing matcher, batch of {n_match} (6 markers, 1 missing, 1 spurious)",
                               t_mrf, t_hun, n_match, "problems/s", "Hungarian baseline (scipy linear_sum_assignment)",
                               f"all labels correct: MRF {100 * ok_mrf:.1f} %, Hungarian {100 * ok_hun:.1f} % (no verification)"))

    t_render = best_time(lambda: render_tof_frame(cam, target, np.eye(3), r_true, rng=1), repeat=3)
    rows.append(BenchRow("000 TOF frame rendering, 176x144, 3x3 sub-rays (Open3D)", 1.0 / t_render, "frames/s",
                         note="SR4000 model: mixed pixels, shot noise, saturation, phase wrap"))
    return rows
