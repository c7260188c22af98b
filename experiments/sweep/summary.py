"""What a stored sweep holds, in short (``summary.json``), and its figures redrawn from the store."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from experiments.sweep.runner import SweepReport
from experiments.sweep.store import open_sweep

__all__ = ["sweep_summary", "redraw"]


def sweep_summary(ds: xr.Dataset, report: SweepReport | None = None) -> dict[str, Any]:
    """JSON-able summary of a stored sweep: sizes, failures by reason, metric ranges."""
    reasons = ds["failure_reason"].values.astype(object).ravel()
    counts: dict[str, int] = {}
    for r in reasons[reasons != ""]:
        counts[str(r)] = counts.get(str(r), 0) + 1
    swept = json.loads(ds.attrs.get("swept_keys", "[]"))
    summary: dict[str, Any] = {
        "cell": ds.attrs.get("cell", ""),
        "kind": ds.attrs.get("kind", ""),
        "grid": {str(d): ds[d].values.tolist() for d in ds["done"].dims},
        "swept_keys": swept,
        "trials": int(ds.sizes["trial"]),
        "cells": int(ds["done"].size),
        "cells_done": int(ds["done"].values.sum()),
        "trials_failed": int(sum(counts.values())),
        "failure_reasons": dict(sorted(counts.items(), key=lambda kv: -kv[1])[:20]),
        "metrics": {},
    }
    for name, var in ds.data_vars.items():
        if name in ("failure_reason", "done"):
            continue
        vals = var.values[np.isfinite(var.values)]
        summary["metrics"][name] = {
            "units": var.attrs.get("units", ""),
            "median": float(np.median(vals)) if vals.size else None,
            "min": float(vals.min()) if vals.size else None,
            "max": float(vals.max()) if vals.size else None,
        }
    if report is not None:
        summary.update({"wall_s": report.wall_s, "cells_computed_this_run": report.n_computed,
                        "workers": report.workers, "peak_worker_rss_mb": report.peak_worker_rss_mb})
    return summary



def redraw(out: Path | str, plot_sweep: Callable[[xr.Dataset, Path], list[Path]] | None = None) -> list[Path]:
    """Redraw the figures of a stored sweep from ``out/sweep.zarr`` into ``out/figures``.

    Parameters
    ----------
    out : path
        The sweep's output directory.
    plot_sweep : callable, optional
        ``plot_sweep(dataset, fig_dir) -> list[Path]``, the figures of the sweep's scenario kind;
        default: a generic map of every per-trial metric's trial mean
        (:func:`experiments.plotting.sweep_overview_figures`).

    Returns
    -------
    list of Path
        The figures written.
    """
    from experiments.plotting import sweep_overview_figures  # matplotlib only when drawing

    out = Path(out)
    ds = open_sweep(out)
    fig_dir = out / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    if plot_sweep is not None:
        return list(plot_sweep(ds, fig_dir))
    return sweep_overview_figures(ds, fig_dir)
