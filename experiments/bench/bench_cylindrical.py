"""Cylindrical-imaging (004) benchmarks: plane intersection against OpenCV's DLT triangulation.

With all four channels, the α and β planes of one camera meet in the ray through
``(tan α, tan β, 1)``, so two-camera plane intersection and ``cv2.triangulatePoints`` on normalised
coordinates with ``P = [R_CW | t_CW]`` solve the same problem; the figure is points per second
(ours: :func:`chaser.cylindrical.intersect_planes`, vectorised over points, with range weighting and
failure reporting).  A second row times one frame of multi-target recognition (no peer).
"""

from __future__ import annotations

import cv2
import numpy as np

from experiments.bench import BenchRow, best_time, throughput_row


def run(*, quick: bool) -> list[BenchRow]:
    from chaser.cylindrical import (
        TrackerSettings,
        calibrate_system,
        control_points_in_cube,
        initialise_tracks,
        intersect_planes,
        paper_rig,
        rig_detections,
        track_frame,
    )

    rig = paper_rig()
    centre = np.array([1.0, 3.5, 0.0])
    n = 20_000 if quick else 200_000
    X = control_points_in_cube(n, centre_W=centre, rng=0)
    ab = rig.true_angles(X) + np.random.default_rng(1).normal(0.0, 1e-6, (n, 2, 2))
    tan = np.tan(ab)
    P = [np.hstack([rig.R_CW[c], rig.t_CW[c][:, None]]) for c in range(2)]

    def ours():
        return intersect_planes(rig.R_CW, rig.t_CW, ab)

    def peer():
        Xh = cv2.triangulatePoints(P[0], P[1], tan[:, 0, :].T.copy(), tan[:, 1, :].T.copy())
        return (Xh[:3] / Xh[3]).T

    t_ours = best_time(ours, repeat=3)
    t_peer = best_time(peer, repeat=3)
    diff_um = float(np.max(np.linalg.norm(ours().X_W - peer(), axis=-1)) * 1e6)
    err_ours = float(np.sqrt(np.mean(np.sum((ours().X_W - X) ** 2, -1))) * 1e6)
    err_peer = float(np.sqrt(np.mean(np.sum((peer() - X) ** 2, -1))) * 1e6)
    rows = [throughput_row(f"004 plane intersection, 2 cameras, {n} points", t_ours, t_peer, n, "points/s",
                           "cv2.triangulatePoints (DLT)",
                           f"1 µrad noise: RMS error ours {err_ours:.1f} µm, OpenCV {err_peer:.1f} µm; "
                           f"max difference {diff_um:.1f} µm")]

    # one frame of tracking: predict, back-project (inverse RBF), associate, RBF, intersect, update
    cal = calibrate_system(rig, control_points_in_cube(30, centre_W=centre, rng=2), rng=3,
                           turntable=dict(alpha_step_deg=1.0, rail_step_m=0.06))
    body = np.array([[0.3, 0.0, 0.0], [0.0, 0.0, 0.0], [-0.05, 0.3, 0.0]])
    pts = centre + body
    rng = np.random.default_rng(4)
    lit = [(k, 0.01 * f, rig_detections(rig, pts, rng=rng, lit=np.arange(3) == k))
           for f, k in enumerate([0, 1, 2, 0, 1, 2])]
    settings = TrackerSettings()
    state = initialise_tracks(cal.cameras, 3, lit, settings=settings)
    det = rig_detections(rig, pts, rng=rng)
    t_track = best_time(lambda: track_frame(cal.cameras, state, det, 0.1, settings=settings), repeat=5, number=5)
    t_det = best_time(lambda: rig_detections(rig, pts, rng=rng), repeat=5, number=5)
    rows.append(BenchRow("004 track_frame, 3 targets, 2 cameras", t_track * 1e3, "ms/frame",
                         note=f"detection of the 4 line signals (8000 px) adds {t_det * 1e3:.1f} ms"))
    return rows
