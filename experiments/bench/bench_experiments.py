"""Experiment benchmarks: the 003 Figs 5–6 sweep on Dask, rendered vs geometric frame rates, memory.

Rows
----
- the full-size Experiment A grid (8 distances × 4 axis angles × 2 view counts, 100 trials × 10
  steps per cell) in the geometric mode on 2 local workers (target: under 5 minutes on 2 cores);
  ``--quick`` runs a 2 × 2 × 2 grid with 4 trials and 3 steps and says so;
- Dask speed-up from 1 to 2 workers on the same sub-grid;
- peak resident memory per worker during the grid sweep (target: under 2 GB);
- camera-frames per second of the rendered mode (render, SIFT, matching) and of the geometric mode.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from experiments.bench import BenchRow, duration_row, throughput_row
from experiments.scenarios.formation.config import Config
from experiments.sweep import run_sweep

FULL_GRID = {"formation.distance_m": [30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0],
             "formation.axis_angle_deg": [5.0, 10.0, 15.0, 20.0], "formation.n_views": [2, 3]}
QUICK_GRID = {"formation.distance_m": [40.0, 80.0], "formation.axis_angle_deg": [5.0, 15.0],
              "formation.n_views": [2, 3]}


def _config(**over) -> Config:
    from experiments.config import load_config

    path = Path(__file__).resolve().parents[1] / "configs" / "003_fig5_fig6.toml"
    return load_config(path, overrides={"error_map.filter_runs": 0, **over})[1]


def _sweep(grid: dict, trials: int, steps: int, workers: int) -> tuple[float, dict]:
    from experiments.config import load_config
    from experiments.scenarios.formation.error_map import error_map_sweep_cell

    path = Path(__file__).resolve().parents[1] / "configs" / "003_fig5_fig6.toml"
    base = {"error_map.filter_runs": 0, "error_map.steps": steps}
    cell = error_map_sweep_cell(_config(**base))
    with tempfile.TemporaryDirectory(prefix="coobs-bench-") as out:
        t0 = time.perf_counter()
        rep = run_sweep(cell, grid, trials=trials, out=out, seed=1, workers=workers,
                        make_input=lambda p: load_config(path, overrides={**base, **p})[1])
        wall = time.perf_counter() - t0
    return wall, rep.peak_worker_rss_mb


def _frame_rates(quick: bool) -> tuple[float, float, int, int]:
    """Seconds per camera-frame in the rendered and in the geometric mode (3 views, 40 m, 10°)."""
    from experiments.scenarios.formation.error_map import random_attitudes
    from experiments.scenarios.formation.parts import make_observer, symmetric_T_CW

    epochs = 2 if quick else 6
    out = []
    for mode in ("rendered", "geometric"):
        cfg = _config(**{"observation.mode": mode, "formation.distance_m": 40.0})
        observer, T, sun = make_observer(cfg), symmetric_T_CW(cfg), np.asarray(cfg.observation.sun_H)
        rng = np.random.default_rng(0)
        qs = random_attitudes(rng, epochs)
        observer.observe(T, qs[0], sun, rng=rng)  # warm-up (feature set, scene)
        t0 = time.perf_counter()
        tracks = 0
        for q in qs:
            tracks += observer.observe(T, q, sun, rng=rng).n_tracks
        out.append((time.perf_counter() - t0) / (epochs * len(T)))
        out.append(tracks // epochs)
    return out[0], out[2], out[1], out[3]


def run(*, quick: bool = False) -> list[BenchRow]:
    rows: list[BenchRow] = []
    grid, trials, steps = (QUICK_GRID, 4, 3) if quick else (FULL_GRID, 100, 10)
    size = f"{int(np.prod([len(v) for v in grid.values()]))} cells x {trials} trials x {steps} steps"
    wall2, peak = _sweep(grid, trials, steps, workers=2)
    rows.append(BenchRow(f"003 Figs 5-6 grid, geometric mode, 2 workers ({size})", wall2, "s",
                         note="target < 300 s for the full grid" + (" (quick: reduced grid)" if quick else "")))
    sub, sub_trials, sub_steps = QUICK_GRID, (3 if quick else 25), (3 if quick else 10)
    t1, _ = _sweep(sub, sub_trials, sub_steps, workers=1)
    t2, _ = _sweep(sub, sub_trials, sub_steps, workers=2)
    rows.append(duration_row(f"Dask speed-up 1 -> 2 workers (8 cells x {sub_trials} trials x {sub_steps} steps)", t2, t1,
                             "same sweep on 1 worker", note="ratio = speed-up (ideal 2 on 2 free cores)"))
    rows.append(BenchRow("peak resident memory per worker during the grid sweep",
                         max(peak.values()) if peak else float("nan"), "MB", note="target < 2048 MB"))
    s_r, s_g, n_r, n_g = _frame_rates(quick)
    rows.append(BenchRow("rendered mode: camera-frames per second (render + SIFT + match, 1024 px)", 1.0 / s_r,
                         "frames/s", note=f"3 views at 40 m, median {n_r} tracks per epoch"))
    rows.append(throughput_row("geometric mode: camera-frames per second", s_g, s_r, 1.0, "frames/s",
                               "rendered mode (same cameras)",
                               note=f"{n_g} tracks per epoch; ratio = speed-up of the fast mode"))
    return rows
