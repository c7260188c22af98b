"""The rendered observation mode: where a camera-frame's time goes, and the faster path beside today's.

Scene of ``bench_experiments``' frame-rate row (issue 16 item 7): the 003 Experiment A config
(``experiments/configs/003_fig5_fig6.toml``) in the rendered mode, 3 views on the symmetric cone
(γ = 10°), FY-1, 1024 × 1024 px over 20°, Sun along H = [1, −0.5, 0.6], random attitudes; at 40 m
and at 80 m.  A *camera-frame* is one view rendered, its features detected, and its share of the
epoch's cross-view matching and ground-truth labelling (``vision.rendered.observe_renders``).

Paths
-----
- today's (the baseline, before issue 16): ``render_views(batched=False)`` (one
  ``vision.render.render`` per view) and the views' SIFT one after the other, OpenCV with its
  default thread count;
- fast: ``render_views`` (all views in one ``vision.render.render_batch``: one Open3D cast, rays
  only over the projected triangles, the mip level at the hit pixels; bit-identical images) and the
  views detected on two threads (``detect_views(threads=2)``, OpenCV one thread each);
- fast, one thread: the same with one detection thread and OpenCV on one thread: the work saved,
  which is what a sweep worker gains when every core already runs a worker.

Both paths are timed alternately in the same run (best of ``repeat``); every row checks that the
two give the same tracks (pixel positions and truth labels) on every epoch.
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


def _observe(scene, *, batched: bool, threads: int, cv_threads: int, stages: dict | None = None):
    """The observations of every epoch of ``scene`` by one path (stage times added to ``stages``)."""
    import cv2

    from vision.features import match_views
    from vision.rendered import detect_views, label_tracks, render_views

    cam, target, T, qs, sun = scene
    before = cv2.getNumThreads()
    cv2.setNumThreads(cv_threads)
    out = []
    try:
        for k, q in enumerate(qs):
            t0 = time.perf_counter()
            renders = render_views(cam, T, target, q, sun, rng=k, batched=batched)
            t1 = time.perf_counter()
            kps = detect_views(renders, threads=threads)
            t2 = time.perf_counter()
            obs = match_views(kps, cam, T)
            t3 = time.perf_counter()
            if obs.ok:
                obs = label_tracks(obs, renders, target, q)
            t4 = time.perf_counter()
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
    import cv2

    epochs, repeat = (2, 1) if quick else (8, 3)
    default_threads = cv2.getNumThreads()
    rows: list[BenchRow] = []
    for d in DISTANCES_M:
        scene = _scene(d, epochs)
        frames = epochs * len(scene[2])
        today = {"batched": False, "threads": 1, "cv_threads": default_threads}
        paths = {"today": today, "fast": {"batched": True, "threads": 2, "cv_threads": 1},
                 "today, 1 thread": {**today, "cv_threads": 1},
                 "fast, 1 thread": {"batched": True, "threads": 1, "cv_threads": 1}}
        _observe(scene, **paths["fast"])  # warm-up: scene BVH, texture pyramid, imports
        best = dict.fromkeys(paths, float("inf"))
        cpu = dict.fromkeys(paths, float("inf"))
        stages: dict[str, float] = {}
        results = {}
        for _ in range(repeat):
            for name, kw in paths.items():
                t0, c0 = time.perf_counter(), time.process_time()
                results[name] = _observe(scene, **kw, stages=stages if name == "today, 1 thread" else None)
                best[name] = min(best[name], time.perf_counter() - t0)
                cpu[name] = min(cpu[name], time.process_time() - c0)
        same = all(_same_tracks(results["today"], results[k]) for k in paths)
        tracks = int(np.median([o.n_tracks for o in results["today"]]))
        check = f"same tracks on all {epochs} epochs: {'yes' if same else 'NO'}; median {tracks} tracks per epoch"
        rows.append(throughput_row(
            f"rendered mode, 3 views at {d:.0f} m: batched render, 2 detection threads", best["fast"],
            best["today"], frames, "camera-frames/s", f"today's path (view by view, OpenCV {default_threads} threads)",
            note=check + "; target >= 2x"))
        rows.append(throughput_row(
            f"rendered mode, 3 views at {d:.0f} m: batched render, one thread", best["fast, 1 thread"],
            best["today, 1 thread"], frames, "camera-frames/s", "today's path on one thread",
            note=check + "; Open3D casts on its own threads in both"))
        rows.append(throughput_row(
            f"rendered mode, 3 views at {d:.0f} m: CPU time, batched render, one thread", cpu["fast, 1 thread"],
            cpu["today, 1 thread"], frames, "camera-frames per CPU-s", "today's path on one thread",
            note="process CPU time (all threads): the work per frame, what a sweep worker gains; "
                 "insensitive to other jobs on the machine"))
        per_frame = {k: 1e3 * v / (repeat * frames) for k, v in stages.items()}
        rows.append(BenchRow(
            f"today's path at {d:.0f} m, one thread: ms per camera-frame", sum(per_frame.values()), "ms",
            note=", ".join(f"{k} {v:.1f}" for k, v in per_frame.items())))
    return rows
