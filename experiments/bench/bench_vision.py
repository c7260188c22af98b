"""Vision benchmarks: region-of-interest versus full-frame rendering, OpenCV versus pycolmap SIFT,
and the geometric observation mode versus the rendered one.

Set-up of issue 5: FY-1-like target, 1024 × 1024 px cameras with a 20° field of view, two views with
optical axes 10° apart, Sun from the side. A *camera-frame* is one view rendered and run through
feature detection; the frames-per-second figures include matching the pair (``match_views``), shared
evenly between its two frames.
"""

from __future__ import annotations

import numpy as np

from experiments.bench import BenchRow, best_time, throughput_row


def _setup(distance_m: float):
    from attitude.quaternion import quat_from_matrix
    from vision.camera import PinholeCamera, look_at

    cam = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)
    g = np.deg2rad(5.0)
    T = np.stack([look_at(distance_m * np.array([np.cos(a), np.sin(a), 0.0]), np.zeros(3))
                  for a in (-g, g)])
    # wing normal (body +x) on the bisector of the cameras (+x) and the Sun (+z)
    a = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)
    R = np.column_stack([a, [0.0, 1.0, 0.0], np.cross(a, [0.0, 1.0, 0.0])])
    q = quat_from_matrix(R)
    return cam, T, q, np.array([0.0, 0.0, 1.0])


def _frames(cam, T, target, q, sun, *, roi: bool, rng: int):
    from vision.features import detect, match_views
    from vision.render import render
    from vision.rendered import foreground_mask

    rngs = np.random.default_rng(rng).spawn(len(T))
    renders = [render(cam, t, target, q, sun, rng=r, roi=roi) for t, r in zip(T, rngs, strict=True)]
    kps = [detect(r.image, roi=r.roi if roi else None, mask=foreground_mask(r.image)) for r in renders]
    return match_views(kps, cam, T)


def run(*, quick: bool) -> list[BenchRow]:
    from vision.geometric import observe as observe_geometric
    from vision.rendered import observe as observe_rendered
    from vision.target import fy1_target

    target = fy1_target(seed=0)
    repeat = 1 if quick else 3
    rows: list[BenchRow] = []
    for d in (50.0, 100.0):
        cam, T, q, sun = _setup(d)
        _frames(cam, T, target, q, sun, roi=True, rng=0)         # warm-up: scene, pyramid, imports
        t_roi = best_time(lambda cam=cam, T=T, q=q, sun=sun: _frames(cam, T, target, q, sun,
                                                                      roi=True, rng=0), repeat=repeat)
        t_full = best_time(lambda cam=cam, T=T, q=q, sun=sun: _frames(cam, T, target, q, sun,
                                                                       roi=False, rng=0), repeat=repeat)
        m_roi = _frames(cam, T, target, q, sun, roi=True, rng=0).n_tracks
        m_full = _frames(cam, T, target, q, sun, roi=False, rng=0).n_tracks
        rows.append(throughput_row(
            f"render + SIFT, FY-1 at {d:.0f} m, 1024 px, region of interest", t_roi, t_full, 2,
            "camera-frames/s", "full-frame render + SIFT",
            note=f"matches ROI {m_roi} vs full {m_full}; target >= 5x at 100 m"))

    # OpenCV SIFT vs pycolmap SIFT on the same rendered images (full 1024 x 1024 frames)
    import cv2
    import pycolmap

    from vision.render import render

    cam, T, q, sun = _setup(50.0)
    images = [render(cam, t, target, q, sun, rng=i, roi=False).image for i, t in enumerate(T)]
    sift_cv = cv2.SIFT_create(enable_precise_upscale=True)
    opts = pycolmap.FeatureExtractionOptions()
    opts.num_threads = 1
    sift_colmap = pycolmap.Sift(opts, pycolmap.Device.cpu)
    cv2.setNumThreads(1)
    try:
        t_cv = best_time(lambda: [sift_cv.detectAndCompute(im, None) for im in images], repeat=repeat)
    finally:
        cv2.setNumThreads(-1)
    t_colmap = best_time(lambda: [sift_colmap.extract(im) for im in images], repeat=repeat)
    n_cv = [len(sift_cv.detect(im, None)) for im in images]
    n_colmap = [len(sift_colmap.extract(im)[0]) for im in images]
    rows.append(throughput_row("SIFT detect + describe, 1024 x 1024 rendered FY-1 image, one thread",
                               t_cv, t_colmap, len(images), "images/s", "pycolmap.Sift (CPU)",
                               note=f"keypoints OpenCV {n_cv} vs pycolmap {n_colmap}"))

    # geometric versus rendered observation of one epoch (2 views, 50 m)
    n_epochs = 20 if quick else 200
    Ts = np.broadcast_to(T, (n_epochs, *T.shape))
    qs = np.broadcast_to(q, (n_epochs, 4))
    suns = np.broadcast_to(sun, (n_epochs, 3))
    from vision.geometric import observe_epochs

    observe_geometric(cam, T, target, q, sun, rng=0)                 # warm-up: feature set
    t_geo = best_time(lambda: observe_epochs(cam, Ts, target, qs, suns, rng=0), repeat=repeat)
    t_single = best_time(lambda: observe_geometric(cam, T, target, q, sun, rng=0), repeat=repeat)
    t_rend = best_time(lambda: observe_rendered(cam, T, target, q, sun, rng=0), repeat=1)
    rows.append(throughput_row("geometric observation, 2 views, FY-1 at 50 m (batched epochs)",
                               t_geo, t_rend * n_epochs, n_epochs, "epochs/s",
                               "rendered observation (render + SIFT + match)",
                               note=f"single-epoch call {1 / t_single:.0f} epochs/s"))
    return rows
