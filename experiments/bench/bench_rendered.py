"""The rendered observation mode: where a camera-frame's time goes, and the faster path beside today's.

Scene of ``bench_experiments``' frame-rate row (issue 16 item 7): the 003 Experiment A config
(``experiments/configs/003_fig5_fig6.toml``) in the rendered mode, 3 views on the symmetric cone
(γ = 10°), FY-1, 1024 × 1024 px over 20°, Sun along H = [1, −0.5, 0.6], random attitudes; at 40 m
and at 80 m.  A *camera-frame* is one view rendered, its features detected, and its share of the
epoch's cross-view matching and ground-truth labelling (``vision.rendered.observe_renders``).

Paths
-----
- today's (the baseline, before issue 16 item 7): ``render_views(batched=False)`` (one
  ``vision.render.render`` per view: rays over the whole ROI, full-size arrays) with the sensor's
  ``noise_stream="tiles"`` (one NumPy generator per 32 × 32 tile, a normal for every ROI pixel);
- new: ``render_views`` (all views in one ``vision.render.render_batch``: one Open3D cast, rays
  only where a projected triangle can cover the pixel, mip levels at the hit pixels, ROI-sized
  arrays) with the default ``noise_stream="pixel"`` (counter-based normals on the pixels with
  signal, the rare dark-pixel exceedances drawn directly: the same noise law, other draws).

Both detect with ``detect_views`` (SIFT over each view's ROI, the foreground mask over the ROI) on
one thread with OpenCV on one thread: like for like, the work per camera-frame, which is what a sweep
worker gains when every core already runs a worker.  They are timed alternately in the same run
(best of ``repeat``), in process CPU time (all threads; little disturbed by other jobs on the
machine) and in wall time.

Same matches: the noise draws differ, so the check is (1) with a noise-free sensor (no shot or read
noise) both paths give identical tracks (pixel positions and truth labels) on every epoch, and
(2) the noise law is the same (``tests/vision/test_pixel_noise.py``: mean, variance and the dark-pixel
exceedance rate against their analytic values); with noise, the rows give both paths' median tracks
per epoch.
"""

from __future__ import annotations

import time

import numpy as np

from experiments.bench import BenchRow, throughput_row

DISTANCES_M = (40.0, 80.0)


def _scene(distance_m: float, epochs: int):
    from experiments.bench.bench_experiments import _config
    from experiments.scenarios.formation.error_map import random_attitudes
    from experiments.scenarios.formation.parts import make_observer, symmetric_T_CW

    cfg = _config(**{"observation.mode": "rendered", "formation.distance_m": distance_m})
    obs = make_observer(cfg)
    sun = np.asarray(cfg.observation.sun_H, dtype=float)
    qs = random_attitudes(np.random.default_rng(0), epochs)
    return obs.camera, obs.target, symmetric_T_CW(cfg), qs, sun / np.linalg.norm(sun)


def _observe(scene, *, batched: bool, sensor, stages: dict | None = None):
    """The observations of every epoch of ``scene`` by one path (CPU seconds per stage added to ``stages``)."""
    import cv2

    from vision.features import match_views
    from vision.rendered import detect_views, label_tracks, render_views

    cam, target, T, qs, sun = scene
    before = cv2.getNumThreads()
    cv2.setNumThreads(1)
    out = []
    try:
        for k, q in enumerate(qs):
            t0 = time.process_time()
            renders = render_views(cam, T, target, q, sun, rng=k, batched=batched, sensor=sensor)
            t1 = time.process_time()
            kps = detect_views(renders)
            t2 = time.process_time()
            obs = match_views(kps, cam, T)
            t3 = time.process_time()
            if obs.ok:
                obs = label_tracks(obs, renders, target, q)
            t4 = time.process_time()
            out.append(obs)
            if stages is not None:
                for name, dt in (("render", t1 - t0), ("SIFT", t2 - t1), ("match", t3 - t2), ("label", t4 - t3)):
                    stages[name] = stages.get(name, 0.0) + dt
    finally:
        cv2.setNumThreads(before)
    return out


def _same_tracks(a, b) -> bool:
    return all(np.array_equal(x.uv_px, y.uv_px, equal_nan=True) and np.array_equal(x.feature_id, y.feature_id)
               for x, y in zip(a, b, strict=True))


def run(*, quick: bool = False) -> list[BenchRow]:
    from vision.sensor import SensorModel

    epochs, repeat = (2, 1) if quick else (8, 3)
    sensors = {"today": SensorModel(noise_stream="tiles"), "new": SensorModel()}
    batched = {"today": False, "new": True}
    rows: list[BenchRow] = []
    for d in DISTANCES_M:
        scene = _scene(d, epochs)
        frames = epochs * len(scene[2])
        _observe(scene, batched=True, sensor=None)  # warm-up: scene BVH, texture pyramid, compiled kernels
        wall = dict.fromkeys(sensors, float("inf"))
        cpu = dict.fromkeys(sensors, float("inf"))
        stages = {name: {} for name in sensors}
        results = {}
        for _ in range(repeat):
            for name in sensors:
                t0, c0 = time.perf_counter(), time.process_time()
                results[name] = _observe(scene, batched=batched[name], sensor=sensors[name], stages=stages[name])
                wall[name] = min(wall[name], time.perf_counter() - t0)
                cpu[name] = min(cpu[name], time.process_time() - c0)
        quiet = {name: SensorModel(shot_noise=False, read_noise_e=0.0, noise_stream=s.noise_stream)
                 for name, s in sensors.items()}
        same = _same_tracks(*(_observe(scene, batched=batched[n], sensor=quiet[n]) for n in sensors))
        med = {n: int(np.median([o.n_tracks for o in results[n]])) for n in sensors}
        check = (f"noise-free: same tracks on all {epochs} epochs: {'yes' if same else 'NO'}; with noise, median "
                 f"tracks per epoch {med['new']} (today {med['today']})")
        rows.append(throughput_row(
            f"rendered mode, 3 views at {d:.0f} m: CPU time, new path", cpu["new"], cpu["today"], frames,
            "camera-frames per CPU-s", "today's path (view by view, tile noise), one thread",
            note=check + "; target >= 2x"))
        rows.append(throughput_row(
            f"rendered mode, 3 views at {d:.0f} m: wall time, new path, one thread", wall["new"], wall["today"],
            frames, "camera-frames/s", "today's path, one thread",
            note="wall time on a shared machine: other jobs slow both"))
        for name in sensors:
            per_frame = {k: 1e3 * v / (repeat * frames) for k, v in stages[name].items()}
            rows.append(BenchRow(
                f"{'today' if name == 'today' else 'new'} path at {d:.0f} m, one thread: CPU ms per camera-frame", sum(per_frame.values()), "ms",
                note=", ".join(f"{k} {v:.1f}" for k, v in per_frame.items())))
    return rows
