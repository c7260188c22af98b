"""One Experiment A sweep in a few numbers: the summary rows of docs/reproduction.md's map tables.

Per cell each quantity is the median over the trials that stored it (a trial with every step
refused stores none), as the maps show it; then, per view count, min / median / max over the cells:

* e_Δθ (003 eq 33), per-step RMS error, Cramér–Rao bound per step, tracks per epoch;
* the per-step error over the bound: per cell the median of the per-trial ratios;
* steps refused: of every step of the cell, a trial refused outright counting all its steps, as the
  maps' fourth column does (:func:`experiments.scenarios.formation.figures._refused_percent`), and the
  trials with every step refused;

and the cells where three views do at least as well as two, the cells where three views reach 0.2°
(e_Δθ), e_Δθ in the paper's window (40–80 m, γ = 10–15°) and the refused steps per distance (mean over
γ).

    python -m experiments.studies.map_summary runs/003_fig5_fig6_calibrated runs/003_fig5_fig6_calibrated_ml
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from experiments.studies.rendered_vs_calibrated import cell_medians, open_store, steps_per_trial

__all__ = ["summary", "summary_text", "main"]


def _spread(x: np.ndarray) -> tuple[float, float, float]:
    x = x[np.isfinite(x)]
    return (float(np.min(x)), float(np.median(x)), float(np.max(x))) if x.size else (np.nan,) * 3


def summary(ds: xr.Dataset) -> dict:
    """The summary of one sweep's store (dims distance_m, axis_angle_deg, n_views, trial)."""
    med = cell_medians(ds)
    ratio = (ds["step_rms_deg"] / ds["crlb_deg"]).median("trial", skipna=True)
    steps = steps_per_trial(ds)
    failed = ds["failed_steps"].fillna(float(steps))                  # a trial refused outright: every step
    refused = 100.0 * failed.sum("trial") / (steps * ds.sizes["trial"])
    every = (failed >= steps).sum("trial")
    views = [int(v) for v in ds["n_views"].values]
    out = {"per_views": {}}
    for v in views:
        at = {"n_views": v}
        out["per_views"][v] = {
            "e_dtheta_deg": _spread(med["e"].sel(at).values), "step_rms_deg": _spread(med["step"].sel(at).values),
            "step_over_crlb": _spread(ratio.sel(at).values), "crlb_deg": _spread(med["crlb"].sel(at).values),
            "tracks": _spread(med["tracks"].sel(at).values), "refused_percent": _spread(refused.sel(at).values),
            "trials_every_step_refused": _spread(every.sel(at).values.astype(float)),
            "refused_percent_by_distance": [round(float(x), 1) for x in refused.sel(at).mean("axis_angle_deg").values],
        }
    if len(views) == 2:
        two, three = ({"n_views": v} for v in views)
        out["three_better_than_two"] = {k: int((med[k].sel(three) <= med[k].sel(two)).sum())
                                        for k in ("e", "step", "crlb")}
        out["three_views_within_0_2_deg"] = int((med["e"].sel(three) <= 0.2).sum())
    window = med["e"].sel(distance_m=slice(40.0, 80.0), axis_angle_deg=slice(10, 15))
    out["window_e_dtheta_deg"] = {v: (float(window.sel(n_views=v).min()), float(window.sel(n_views=v).max()))
                                  for v in views}
    out["cells"] = int(med["e"].sel(n_views=views[0]).size)
    return out


def summary_text(s: dict) -> str:
    """:func:`summary` as lines of text, one quantity per line."""
    lines = []
    for v, q in s["per_views"].items():
        lines.append(f"{v} views, min / median / max over the {s['cells']} cells:")
        for k, (lo, mid, hi) in ((k, q[k]) for k in ("e_dtheta_deg", "step_rms_deg", "step_over_crlb", "crlb_deg",
                                                     "tracks", "refused_percent", "trials_every_step_refused")):
            lines.append(f"  {k}: {lo:.3g} / {mid:.3g} / {hi:.3g}")
        lines.append(f"  refused_percent_by_distance: {q['refused_percent_by_distance']}")
        lo, hi = s["window_e_dtheta_deg"][v]
        lines.append(f"  e_dtheta_deg in 40-80 m, 10-15 deg: {lo:.3g}-{hi:.3g}")
    if "three_better_than_two" in s:
        b = s["three_better_than_two"]
        lines.append(f"three views at least as good as two: e_dtheta {b['e']}, step RMS {b['step']}, CRLB {b['crlb']} "
                     f"of {s['cells']} cells; three views within 0.2 deg: {s['three_views_within_0_2_deg']}")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m experiments.studies.map_summary", description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", type=Path, help="sweep output folders (each with sweep.zarr)")
    args = ap.parse_args(argv)
    for run in args.runs:
        if not (run / "sweep.zarr").is_dir():
            ap.error(f"runs: no sweep store at {run / 'sweep.zarr'}")
        print(f"== {run}")
        print(summary_text(summary(open_store(run))))


if __name__ == "__main__":
    main()
