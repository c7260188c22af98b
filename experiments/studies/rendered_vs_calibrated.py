"""Rendered against calibrated geometric Experiment A grids: the two tables of docs/reproduction.md.

"Medium rendered grid (issue 16)" compares the rendered mode's grid (few trials per cell, many of them
refused outright) with the calibrated geometric mode's full-size grid.  Per cell each quantity is the
median over the trials that stored metrics (a trial with every step refused stores none), then the
first table gives min / median / max over the cells of each view count and the second the cells at
one line-of-sight angle, per distance:

* tracks per epoch (``n_tracks``), e_Δθ (003 eq 33), per-step RMS error, Cramér–Rao bound per step;
* steps refused: the refused share of the *surviving* trials' steps (``failed_steps`` summed over the
  trials that stored it, over 10 steps each); the maps' fourth column
  (:func:`experiments.scenarios.formation.figures._refused_percent`) also counts every step of a
  trial refused outright, so it is higher.

    python -m experiments.studies.rendered_vs_calibrated runs/003_fig5_fig6_rendered_medium runs/003_fig5_fig6_calibrated_v2

prints both tables as Markdown, the columns ordered 2 views rendered, 2 views calibrated, 3 views
rendered, 3 views calibrated, then a third: the two grids trial by trial (:func:`paired_table`).  The
rendered grid runs the first trials of the calibrated one (same seeds, same attitudes), so each
trial that both keep gives a ratio without the spread between the attitudes, and without the
difference between which trials survive in each mode, both of which the cell medians carry.
"""

from __future__ import annotations

import argparse
import json
import tomllib
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import xarray as xr

__all__ = ["cell_medians", "open_store", "steps_per_trial", "summary_table", "angle_table", "paired_table", "main"]

#: the distances of the per-distance table, m
DISTANCES_M = (30, 40, 50, 60, 80, 100)


def open_store(run: Path) -> xr.Dataset:
    """The sweep store of a run folder (``RUN/sweep.zarr``), loaded."""
    with warnings.catch_warnings():  # the sweeps' stores have no consolidated metadata
        warnings.simplefilter("ignore", RuntimeWarning)
        return xr.open_zarr(Path(run) / "sweep.zarr", consolidated=False).load()


def steps_per_trial(ds: xr.Dataset) -> int:
    """Registration steps per trial of the store's error map (its config and overrides; default 10)."""
    steps = tomllib.loads(ds.attrs.get("config_toml", "")).get("error_map", {}).get("steps", 10)
    return int(json.loads(ds.attrs.get("overrides", "{}")).get("error_map.steps", steps))


def cell_medians(ds: xr.Dataset) -> dict[str, xr.DataArray]:
    """Per cell: median over the surviving trials of tracks, e_Δθ, step RMS, CRLB (deg); refused %."""
    out = {k: ds[v].median("trial", skipna=True) for k, v in
           (("tracks", "n_tracks"), ("e", "e_dtheta_deg"), ("step", "step_rms_deg"), ("crlb", "crlb_deg"))}
    failed = ds["failed_steps"]  # NaN for a trial refused outright
    out["refused"] = 100.0 * failed.sum("trial", skipna=True) / (steps_per_trial(ds) * failed.notnull().sum("trial"))
    return out


def _deg(x: float) -> str:
    if not np.isfinite(x):
        return "—"
    return f"{x:#.2g}°" if x < 0.1 else (f"{x:.2f}°" if x < 10 else f"{x:.1f}°")


def _tracks(x: float) -> str:
    return "—" if not np.isfinite(x) else f"{x:.0f}"


def _pct(x: float) -> str:
    return "—" if not np.isfinite(x) else f"{x:.0f} %"


def _mmm(a: np.ndarray, fmt) -> str:
    a = a[np.isfinite(a)]
    lo, mid, hi = np.min(a), np.median(a), np.max(a)
    if fmt is _pct:
        return f"{lo:.0f} / {mid:.0f} / {hi:.0f} %"
    return f"{fmt(lo)} / {fmt(mid)} / {fmt(hi)}"


_HEAD = ("| {} | 2 views, rendered | 2 views, calibrated geometric | 3 views, rendered | "
         "3 views, calibrated geometric |\n|---|---|---|---|---|")
_ROWS = (("tracks per epoch", "tracks", _tracks), ("e_Δθ (003 eq 33)", "e", _deg),
         ("per-step RMS error", "step", _deg), ("Cramér–Rao bound per step", "crlb", _deg),
         ("steps refused", "refused", _pct))


def _columns(rendered: dict, calibrated: dict):
    return [(m, nv) for nv in (2, 3) for m in (rendered, calibrated)]


def summary_table(rendered: dict, calibrated: dict) -> str:
    """min / median / max over the cells of each view count."""
    lines = [_HEAD.format("per cell")]
    for label, key, fmt in _ROWS:
        cells = [_mmm(m[key].sel(n_views=nv).values.ravel().astype(float), fmt)
                 for m, nv in _columns(rendered, calibrated)]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def angle_table(rendered: dict, calibrated: dict, angle_deg: float = 10,
                distances: Sequence[float] = DISTANCES_M) -> str:
    """At one line-of-sight angle, per distance: tracks, per-step RMS error, bound, steps refused."""
    lines = [_HEAD.format("distance")]
    for d in distances:
        cells = []
        for m, nv in _columns(rendered, calibrated):
            s = {"distance_m": d, "axis_angle_deg": angle_deg, "n_views": nv}
            cells.append(", ".join(fmt(float(m[k].sel(s))) for _, k, fmt in _ROWS if k != "e"))
        lines.append(f"| {d:g} m | " + " | ".join(cells) + " |")
    return "\n".join(lines)


#: quantities of the paired table: store variable, row label
_PAIRED = (("crlb_deg", "Cramér–Rao bound per step"), ("step_rms_deg", "per-step RMS error"),
           ("e_dtheta_deg", "e_Δθ (003 eq 33)"), ("n_tracks", "tracks per epoch"))


def paired_table(rendered: xr.Dataset, calibrated: xr.Dataset, near_m: float = 50.0) -> str:
    """Per quantity: the median [quartiles] over the trials both grids keep (the rendered grid's trials,
    the same trials of the calibrated one) of the per-trial ratio rendered / calibrated, for the cells
    up to ``near_m`` and beyond it."""
    cal = calibrated.isel(trial=slice(0, rendered.sizes["trial"])).sel(
        distance_m=rendered.distance_m, axis_angle_deg=rendered.axis_angle_deg, n_views=rendered.n_views)
    lines = [f"| per trial, rendered / calibrated | cells to {near_m:g} m | cells beyond |", "|---|---|---|"]
    for var, label in _PAIRED:
        ratio = rendered[var] / cal[var]
        cells = []
        for part in (ratio.where(ratio.distance_m <= near_m), ratio.where(ratio.distance_m > near_m)):
            x = part.values.ravel()
            x = x[np.isfinite(x) & (x > 0)]
            cells.append("—" if x.size == 0 else
                         f"{np.median(x):.2f} [{np.quantile(x, 0.25):.2f}–{np.quantile(x, 0.75):.2f}], {x.size} trials")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    """Command line: the two runs' directories, the angle of the per-distance table."""
    ap = argparse.ArgumentParser(prog="python -m experiments.studies.rendered_vs_calibrated",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("rendered", type=Path, help="run directory of the rendered grid (holds sweep.zarr)")
    ap.add_argument("calibrated", type=Path, help="run directory of the calibrated geometric grid")
    ap.add_argument("--angle", type=float, default=10.0, help="line-of-sight angle of the second table, deg")
    args = ap.parse_args(argv)
    for name in ("rendered", "calibrated"):
        if not (getattr(args, name) / "sweep.zarr").is_dir():
            ap.error(f"{name}: no sweep.zarr in {str(getattr(args, name))!r}")
    r_ds, c_ds = open_store(args.rendered), open_store(args.calibrated)
    rendered, calibrated = cell_medians(r_ds), cell_medians(c_ds)
    print(summary_table(rendered, calibrated))
    print(f"\nAt γ = {args.angle:g}°, per cell: tracks per epoch, per-step RMS error, bound, steps refused:\n")
    print(angle_table(rendered, calibrated, args.angle))
    print("\nTrial by trial, the trials both grids keep:\n")
    print(paired_table(r_ds, c_ds))


if __name__ == "__main__":
    main()
