"""A small sweep with the Python API: paper 003's Experiment A error maps on a 2 × 2 grid.

``coobs.sweep`` runs the bundled config ``003_fig5_fig6`` (three views, geometric observation
mode) with overrides that shrink its grid to 2 observation distances × 2 line-of-sight angles and a
few trials per cell, on a Dask cluster of one worker thread.  Every cell is written to
``sweep.zarr`` as it finishes (calling again resumes).  The maps are the trial medians of the
attitude-increment error 003 eq (33) and of its Cramér–Rao bound; ``coobs.plot`` draws the
scenario kind's own maps from the same dataset.

Run it:  ``python examples/sweep_error_maps.py`` (a few seconds) → ``docs/figures/gallery/sweep_error_maps.png``
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

import coobs
from experiments.plotting import plot_map

NAME = "sweep_error_maps"
GALLERY = Path(__file__).resolve().parents[1] / "docs" / "figures" / "gallery"


def main(*, out_dir: Path = GALLERY, small: bool = True, work_dir: Path | None = None) -> dict[str, Any]:
    """Run the sweep, draw its maps; returns the key numbers, the dataset and the figures' paths.

    Parameters
    ----------
    out_dir : Path
        Folder for ``sweep_error_maps.png``.
    small : bool
        2 × 2 cells × 6 trials (seconds); ``False``: 4 × 4 cells × 50 trials.
    work_dir : Path, optional
        Folder of the sweep store (``sweep.zarr``, ``summary.json``, the kind's ``figures/``);
        default: a temporary folder, removed at the end.
    """
    # 1. configure: a bundled config, made small by dotted-key overrides
    distances_m = [30.0, 80.0] if small else [30.0, 50.0, 70.0, 90.0]
    angles_deg = [5.0, 20.0] if small else [5.0, 10.0, 15.0, 20.0]
    overrides = {
        "formation.n_views": 3,
        "error_map.filter_runs": 0,  # no EKF runs per cell: the error maps only
        "sweep.trials": 6 if small else 50,
        "sweep.grid": {"formation.distance_m": distances_m, "formation.axis_angle_deg": angles_deg},
    }
    with tempfile.TemporaryDirectory(prefix="coobs-sweep-") as tmp:
        store_dir = Path(work_dir) if work_dir is not None else Path(tmp)
        # 2. run: one worker thread (processes=False starts in a fraction of a second)
        ds = coobs.sweep("003_fig5_fig6", out=store_dir, overrides=overrides, workers=1, processes=False,
                         progress=False)
        kind_figures = coobs.plot(ds, store_dir / "figures")

    # 3. pull the outputs: trial medians, (distance, angle) → (angle, distance) for the maps
    e_deg = ds["e_dtheta_deg"].median("trial").transpose("axis_angle_deg", "distance_m")
    crlb_deg = ds["crlb_deg"].median("trial").transpose("axis_angle_deg", "distance_m")
    x, y = ds["distance_m"].values, ds["axis_angle_deg"].values

    # 4. plot: the same colour range on both maps
    fig = Figure(figsize=(9.5, 3.6), layout="constrained")
    axes = fig.subplots(1, 2)
    vmax = float(max(e_deg.max(), crlb_deg.max()))
    for ax, values, title in ((axes[0], e_deg, "e_dθ (003 eq 33), median"),
                              (axes[1], crlb_deg, "Cramér–Rao bound per step, median")):
        plot_map(values.values, x, y, ax=ax, vmin=0.0, vmax=vmax, annotate=True, fontsize=9,
                 xlabel="observation distance [m]", ylabel="line-of-sight angle [deg]", title=title,
                 cbar_label="angle [deg]")
    fig.suptitle(f"coobs.sweep: 003 Experiment A, 3 views, {ds.sizes['trial']} trials per cell")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    figure = out_dir / f"{NAME}.png"
    fig.savefig(figure, dpi=110)
    failed = int((ds["failure_reason"].values != "").sum())
    return {"figure": figure, "cells": int(ds["done"].size), "trials": int(ds.sizes["trial"]),
            "failed_trials": failed, "median_e_dtheta_deg": float(ds["e_dtheta_deg"].median()),
            "median_crlb_deg": float(ds["crlb_deg"].median()), "dataset": ds,
            "kind_figures": [f.name for f in kind_figures]}


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out-dir", type=Path, default=GALLERY, help="folder for the figure")
    parser.add_argument("--work-dir", type=Path, default=None, help="keep the sweep store here")
    parser.add_argument("--full", action="store_true", help="4 × 4 cells × 50 trials instead of 2 × 2 × 6")
    args = parser.parse_args()
    res = main(out_dir=args.out_dir, small=not args.full, work_dir=args.work_dir)
    print(f"{res['cells']} cells × {res['trials']} trials, {res['failed_trials']} failed; median e_dθ "
          f"{res['median_e_dtheta_deg']:.3f} deg, median CRLB {res['median_crlb_deg']:.3f} deg")
    print(f"figure: {res['figure']}")
