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
  ``noise_stream="tiles"`` (one NumPy generator per 32 × 32 tile, a normal for every ROI pixel), in a
  process with glibc's default ``malloc`` settings;
- new, default allocator: ``render_views`` (all views in one ``vision.render.render_batch``: one
  Open3D cast, rays only where a projected triangle can cover the pixel, mip levels at the hit
  pixels, ROI-sized arrays) with the default ``noise_stream="pixel"`` (counter-based normals on the
  pixels with signal, the rare dark-pixel exceedances drawn directly: the same noise law, other
  draws), FLANN neighbours as arrays (``vision.features._FlannIndex``), in a process with glibc's
  defaults: the code's share of the gain;
- new (the rendered mode as the product runs it): the same in a process where
  ``vision.allocator.retain_freed_memory`` has been called, as ``RenderedObserver`` does;
- today's, freed buffers kept: today's path with that allocator setting too (the code's share of
  the gain when both keep their buffers).

Each path runs in its own fresh (spawned) process, so that the allocator settings of one do not
reach another; the four processes take the epochs in turn, one epoch each, so that all see the same
state of a shared machine (its speed drifts by tens of per cent over seconds).  All detect with
``detect_views`` (SIFT over each view's ROI, the foreground mask over the ROI) with OpenCV on one
thread: like for like, the work per camera-frame, which is what a sweep worker gains when every core
already runs a worker.  Timed in process CPU time (all threads, user and system; little disturbed by
other jobs on the machine) and in wall time, best of ``repeat`` passes over the epochs.

Same matches: the noise draws differ, so the check is (1) with a noise-free sensor (no shot or read
noise) today's and the new path give identical tracks (pixel positions and truth labels) on every
epoch, and (2) the noise law is the same (``tests/vision/test_pixel_noise.py``: mean, variance and
the dark-pixel exceedance rate against their analytic values); with noise, the rows give the paths'
median tracks per epoch.
"""

from __future__ import annotations

import contextlib
import time

import numpy as np

from experiments.bench import BenchRow, duration_row, throughput_row

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


def _observe_epoch(scene, k: int, *, batched: bool, sensor, stages: dict | None = None):
    """The observation of epoch ``k`` of ``scene`` by one path (CPU seconds per stage added to ``stages``)."""
    from vision.features import match_views
    from vision.rendered import detect_views, label_tracks, render_views

    cam, target, T, qs, sun = scene
    t0 = time.process_time()
    renders = render_views(cam, T, target, qs[k], sun, rng=k, batched=batched, sensor=sensor)
    t1 = time.process_time()
    kps = detect_views(renders)
    t2 = time.process_time()
    obs = match_views(kps, cam, T)
    t3 = time.process_time()
    if obs.ok:
        obs = label_tracks(obs, renders, target, qs[k])
    t4 = time.process_time()
    if stages is not None:
        for name, dt in (("render", t1 - t0), ("SIFT", t2 - t1), ("match", t3 - t2), ("label", t4 - t3)):
            stages[name] = stages.get(name, 0.0) + dt
    return obs


def _observe(scene, *, batched: bool, sensor):
    """The observations of every epoch of ``scene`` by one path."""
    return [_observe_epoch(scene, k, batched=batched, sensor=sensor) for k in range(len(scene[3]))]


@contextlib.contextmanager
def _one_thread():
    """OpenCV (SIFT, FLANN) on one thread inside the block, as in a sweep worker beside other workers."""
    import cv2

    before = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(before)


def _same_tracks(a, b) -> bool:
    return all(np.array_equal(x.uv_px, y.uv_px, equal_nan=True) and np.array_equal(x.feature_id, y.feature_id)
               for x, y in zip(a, b, strict=True))


_PATHS = {  # name: (batched render, sensor noise stream, retain freed memory)
    "today": (False, "tiles", False),
    "today, freed buffers kept": (False, "tiles", True),
    "new, default allocator": (True, "pixel", False),
    "new": (True, "pixel", True),
}


def _path_process(conn, name: str) -> None:
    """One path in its own process: ``("scene", distance_m, epochs)`` builds and warms a scene,
    ``("epoch", k)`` answers ``(cpu_s, wall_s, stages, n_tracks)``, ``None`` ends."""
    import os

    from vision.allocator import retain_freed_memory
    from vision.sensor import SensorModel

    batched, stream, retain = _PATHS[name]
    # the scene's RenderedObserver calls retain_freed_memory too: the switch keeps glibc's defaults
    os.environ["COOBS_MALLOC_DEFAULTS"] = "0" if retain else "1"
    retain_freed_memory()
    sensor = SensorModel(noise_stream=stream)
    scene = None
    with _one_thread():
        while (msg := conn.recv()) is not None:
            if msg[0] == "scene":
                scene = _scene(msg[1], msg[2])
                _observe(scene, batched=batched, sensor=sensor)   # warm-up: BVH, texture pyramid, kernels
                conn.send("ready")
                continue
            stages: dict = {}
            t0, c0 = time.perf_counter(), time.process_time()
            obs = _observe_epoch(scene, msg[1], batched=batched, sensor=sensor, stages=stages)
            conn.send((time.process_time() - c0, time.perf_counter() - t0, stages, obs.n_tracks))


def _same_matches(scene) -> bool:
    """Noise-free sensor: today's and the new path give the same tracks on every epoch of ``scene``."""
    from vision.sensor import SensorModel

    quiet = {b: SensorModel(shot_noise=False, read_noise_e=0.0, noise_stream=s) for b, s in ((False, "tiles"),
                                                                                           (True, "pixel"))}
    with _one_thread():
        return _same_tracks(*(_observe(scene, batched=b, sensor=quiet[b]) for b in (False, True)))


def run(*, quick: bool = False) -> list[BenchRow]:
    import multiprocessing

    epochs, repeat = (2, 1) if quick else (8, 3)
    ctx = multiprocessing.get_context("spawn")
    pipes, procs = {}, []
    for name in _PATHS:
        parent, child = ctx.Pipe()
        proc = ctx.Process(target=_path_process, args=(child, name), daemon=True)
        proc.start()
        pipes[name] = parent
        procs.append(proc)
    rows: list[BenchRow] = []
    try:
        for d in DISTANCES_M:
            for conn in pipes.values():
                conn.send(("scene", d, epochs))
            for conn in pipes.values():
                conn.recv()
            scene = _scene(d, epochs)                # the parent's copy: the views and the noise-free check
            frames = epochs * len(scene[2])
            best = {name: [float("inf"), float("inf")] for name in _PATHS}   # CPU s, wall s
            stages = {name: {} for name in _PATHS}
            tracks = {name: [] for name in _PATHS}
            for _ in range(repeat):
                run_s = {name: [0.0, 0.0] for name in _PATHS}
                for k in range(epochs):
                    for name, conn in pipes.items():
                        conn.send(("epoch", k))
                        cpu, wall, st, n = conn.recv()
                        run_s[name][0] += cpu
                        run_s[name][1] += wall
                        tracks[name].append(n)
                        for key, v in st.items():
                            stages[name][key] = stages[name].get(key, 0.0) + v
                for name in _PATHS:
                    best[name] = [min(a, b) for a, b in zip(best[name], run_s[name], strict=True)]
            rows += _rows(d, frames, repeat, best, stages, tracks, _same_matches(scene))
    finally:
        for conn in pipes.values():
            conn.send(None)
        for proc in procs:
            proc.join(timeout=30)
    if not quick:
        rows.append(_allocator_row(repeat=2))
    return rows


def _allocator_row(*, repeat: int) -> BenchRow:
    """``coobs run`` of the rendered quickstart (31 epochs × 3 views, SIFT, ML registration, EKF, figures), as
    a user runs it, with ``vision.allocator.retain_freed_memory`` (the product) and without
    (``COOBS_MALLOC_DEFAULTS=1``), alternately: CPU seconds (user + system) of the command."""
    import os
    import resource
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    import experiments

    config = Path(experiments.__file__).parent / "configs" / "quickstart.toml"
    best = {"retain": [float("inf")] * 2, "defaults": [float("inf")] * 2}    # CPU s, system s
    for _ in range(repeat):
        for name in best:
            env = {**os.environ, "COOBS_MALLOC_DEFAULTS": "1" if name == "defaults" else "0"}
            with tempfile.TemporaryDirectory() as out:
                before = resource.getrusage(resource.RUSAGE_CHILDREN)
                subprocess.run([sys.executable, "-m", "coobs", "run", str(config), "--out", out], env=env,
                               check=True, capture_output=True)
                after = resource.getrusage(resource.RUSAGE_CHILDREN)
            sys_s = after.ru_stime - before.ru_stime
            cpu_s = after.ru_utime - before.ru_utime + sys_s
            if cpu_s < best[name][0]:
                best[name] = [cpu_s, sys_s]
    return duration_row("rendered quickstart run (coobs run quickstart.toml), CPU s, freed buffers kept",
                        best["retain"][0], best["defaults"][0], "the same with glibc's default malloc settings",
                        note=f"system time {best['retain'][1]:.2f} s (defaults {best['defaults'][1]:.2f} s); "
                             "same results (the allocator changes reuse, not arithmetic)")


def _rows(d: float, frames: int, repeat: int, best: dict, stages: dict, tracks: dict, same: bool) -> list[BenchRow]:
    med = {n: int(np.median(t)) for n, t in tracks.items()}
    check = (f"noise-free: same tracks on all epochs: {'yes' if same else 'NO'}; with noise, median tracks per "
             f"epoch {med['new']} (today {med['today']})")
    rows = [
        throughput_row(f"rendered mode, 3 views at {d:.0f} m: CPU time, new path", best["new"][0], best["today"][0],
                       frames, "camera-frames per CPU-s", "today's path (view by view, tile noise), one thread",
                       note=check + "; target >= 2x"),
        throughput_row(f"rendered mode, 3 views at {d:.0f} m: CPU time, new path with glibc's default allocator",
                       best["new, default allocator"][0], best["today"][0], frames, "camera-frames per CPU-s",
                       "today's path, one thread", note="the code's share of the gain (no retain_freed_memory)"),
        throughput_row(f"rendered mode, 3 views at {d:.0f} m: CPU time, new path, both with freed buffers kept",
                       best["new"][0], best["today, freed buffers kept"][0], frames, "camera-frames per CPU-s",
                       "today's path with retain_freed_memory, one thread",
                       note="the code's share with the product's allocator setting in both"),
        throughput_row(f"rendered mode, 3 views at {d:.0f} m: wall time, new path, one thread", best["new"][1],
                       best["today"][1], frames, "camera-frames/s", "today's path, one thread",
                       note="wall time on a shared machine: other jobs slow both"),
    ]
    for name in _PATHS:
        per_frame = {k: 1e3 * v / (repeat * frames) for k, v in stages[name].items()}
        rows.append(BenchRow(f"{name} path at {d:.0f} m, one thread: CPU ms per camera-frame", sum(per_frame.values()),
                             "ms", note=", ".join(f"{k} {v:.1f}" for k, v in per_frame.items())))
    return rows
