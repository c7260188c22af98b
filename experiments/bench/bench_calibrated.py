"""Experiment A (003 Figs 5–6) in the calibrated geometric mode beside the fixed (uncalibrated) one.

Rows
----
- CPU seconds of a measured subset of the full grid — every distance (30–100 m) and view count at
  one line-of-sight angle (10°), ``SUBSET_TRIALS`` trials × 10 steps per cell, evidence checks on,
  no EKF runs — in the calibrated mode, beside the same subset in the fixed mode (ratio = how many
  times more CPU the calibrated mode needs, inverted so that > 1 means the calibrated one is faster);
- the full grid (64 cells × 100 trials × 10 steps) on 2 workers, **scaled from that subset**: its
  CPU time × 4 angles × (100 / trials) / 2 workers, the wall time an idle 2-core machine would
  take (target ≤ 120 s);
- the subset's wall time on 2 Dask workers, with the load average over the run (the machine is shared).

The cells run in this process one after the other (the CPU time of exactly the cells' work, with
``time.process_time``); the 2-worker row runs the same subset through :func:`experiments.sweep.run_sweep`.
``--quick``: 2 distances, 4 trials, 3 steps.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

from experiments.bench import BenchRow

DISTANCES_M = [30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0]
SUBSET_ANGLE_DEG = 10.0
SUBSET_TRIALS = 25
FULL_GRID_CELLS = 64
FULL_TRIALS = 100


def _config_path() -> Path:
    return Path(__file__).resolve().parents[1] / "configs" / "003_fig5_fig6.toml"


def _grid(quick: bool) -> dict:
    return {"formation.distance_m": [40.0, 80.0] if quick else DISTANCES_M,
            "formation.axis_angle_deg": [SUBSET_ANGLE_DEG], "formation.n_views": [2, 3]}


def _base(noise_model: str, steps: int) -> dict:
    return {"error_map.filter_runs": 0, "error_map.steps": steps, "observation.noise_model": noise_model}


def _cells_cpu_s(noise_model: str, grid: dict, trials: int, steps: int) -> tuple[float, float]:
    """CPU and wall seconds of the subset's cells run one after the other in this process."""
    from experiments.config import load_config
    from experiments.scenarios.formation.error_map import error_map_trials
    from experiments.sweep import cell_seed_sequences

    seeds = cell_seed_sequences(1, {}, trials)
    cfgs = [load_config(_config_path(), overrides={**_base(noise_model, steps), "formation.distance_m": d,
                                                    "formation.axis_angle_deg": a, "formation.n_views": v})[1]
            for d in grid["formation.distance_m"] for a in grid["formation.axis_angle_deg"]
            for v in grid["formation.n_views"]]
    for cfg in cfgs:  # warm-up of the per-process caches (target, feature sets and texture sites per range,
        error_map_trials(cfg, seeds[:1])  # calibration): a worker builds them once for the whole grid, so they
        # must not be timed here, where the subset's time is scaled up 16-fold
    c0, t0 = time.process_time(), time.perf_counter()
    for cfg in cfgs:
        error_map_trials(cfg, seeds)
    return time.process_time() - c0, time.perf_counter() - t0


def _sweep_wall_s(noise_model: str, grid: dict, trials: int, steps: int) -> float:
    from experiments.config import load_config
    from experiments.scenarios.formation.error_map import error_map_sweep_cell
    from experiments.sweep import run_sweep

    base = _base(noise_model, steps)
    cell = error_map_sweep_cell(load_config(_config_path(), overrides=base)[1])
    with tempfile.TemporaryDirectory(prefix="coobs-bench-") as out:
        t0 = time.perf_counter()
        run_sweep(cell, grid, trials=trials, out=out, seed=1, workers=2,
                  make_input=lambda p: load_config(_config_path(), overrides={**base, **p})[1])
        return time.perf_counter() - t0


def run(*, quick: bool = False) -> list[BenchRow]:
    grid = _grid(quick)
    trials, steps = (4, 3) if quick else (SUBSET_TRIALS, 10)
    n_cells = len(grid["formation.distance_m"]) * 2
    size = f"{n_cells} cells ({SUBSET_ANGLE_DEG:g} deg) x {trials} trials x {steps} steps"
    load0 = os.getloadavg()[0]
    cpu_cal, wall_cal = _cells_cpu_s("calibrated", grid, trials, steps)
    cpu_fix, wall_fix = _cells_cpu_s("fixed", grid, trials, steps)
    load1 = os.getloadavg()[0]
    load = f"load average {load0:.1f} -> {load1:.1f} on {os.cpu_count()} cores"
    rows = [BenchRow(f"003 Figs 5-6 subset, calibrated geometric mode, CPU ({size})", cpu_cal, "s",
                     peer="fixed (uncalibrated) geometric mode, same cells", peer_figure=cpu_fix,
                     ratio=cpu_fix / cpu_cal,
                     note=f"ratio < 1: the calibrated mode costs more; wall {wall_cal:.0f} s / {wall_fix:.0f} s "
                          f"in one process, {load}" + (" (quick: reduced grid)" if quick else ""))]
    scale = (FULL_GRID_CELLS / n_cells) * (FULL_TRIALS / trials) * (10 / steps) / 2.0
    rows.append(BenchRow("003 Figs 5-6 full grid (64 cells x 100 trials x 10 steps), calibrated, 2 workers, "
                         "scaled from the subset's CPU", cpu_cal * scale, "s",
                         peer="fixed mode, scaled the same way", peer_figure=cpu_fix * scale,
                         ratio=cpu_fix / cpu_cal,
                         note="idle 2-core estimate = subset CPU x 4 angles x trials/steps scale / 2 workers; "
                              "target <= 120 s"))
    t2 = _sweep_wall_s("calibrated", grid, trials, steps)
    rows.append(BenchRow(f"003 Figs 5-6 subset, calibrated, 2 Dask workers, wall ({size})", t2, "s",
                         note=f"shared machine: {load}; ideal = CPU/2 = {cpu_cal / 2:.0f} s"))
    return rows
