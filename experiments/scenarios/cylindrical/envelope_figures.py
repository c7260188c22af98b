"""Maps of the ``envelope`` sweep of ``cylindrical_004``, drawn from the stored sweep only.

Every figure is a grid of maps, one per rig (a column per value of the first swept key, a row per
value of the second), each map over lateral offset (x) and depth (y) of the target; the panels of a
figure share one colour range and one colour bar (arrows for clipped values); blank cells are
positions where no LED fix (or not every pose) was available.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import xarray as xr

__all__ = ["plot_sweep", "envelope_maps"]

_X, _Y = "offset_m", "depth_m"
#: 004's maxima (yaw, roll, pitch), degrees
_PAPER = {"yaw": 0.20, "roll": 0.12, "pitch": 0.23}


def envelope_maps(ds: xr.Dataset) -> dict[str, tuple[xr.DataArray, str, str, str, tuple[float | None, float | None]]]:
    """The reduced maps: name → (map over grid × depth × offset, title, colour-bar label, cmap, (lo, hi))."""
    rot = ds["rotation_error_deg"]
    out = {
        "point_error": (ds["point_error_rms_mm"].median("trial"), "3-D point error, RMS over LEDs (median of trials)",
                        "point error [mm]", "viridis", (0.0, None)),
        "availability": (ds["available"].mean("trial"), "LED fixes available", "fraction available", "cividis",
                         (0.0, 1.0)),
        "rotation_error": (np.sqrt((rot**2).mean(("trial", "pose"), skipna=False)),
                           "rotation angle of R_est R_true^T, RMS over poses and trials",
                           "rotation-angle error [deg]", "viridis", (0.0, None)),
        "rotation_over_bound": (np.sqrt((rot**2).mean(("trial", "pose"), skipna=False)
                                        / (ds["rotation_crlb_deg"] ** 2).mean("pose", skipna=False)),
                                "rotation-angle error RMS / Cramér–Rao bound", "error / bound", "viridis",
                                (1.0, None)),
        "efficiency": (np.sqrt((ds["rotation_scatter_deg"] ** 2).mean("pose", skipna=False)
                               / (ds["rotation_crlb_deg"] ** 2).mean("pose", skipna=False)),
                       "rotation scatter about the mean / Cramér–Rao bound (noise part)", "scatter / bound",
                       "cividis", (0.5, 1.5)),
        "point_efficiency": (ds["point_scatter_mm"] / ds["point_crlb_mm"],
                             "3-D scatter about the mean / Cramér–Rao bound (noise part)", "scatter / bound",
                             "cividis", (0.5, 1.5)),
    }
    for name in ("yaw", "roll", "pitch"):
        m = np.abs(ds[f"{name}_error_deg"]).max(("trial", "pose"), skipna=False)
        out[f"euler_{name}"] = (m, f"{name} (3-1-2, eq 9-11): max over poses and trials; paper max {_PAPER[name]} deg",
                                f"{name} error [deg]", "viridis", (0.0, None))
    return out


def plot_sweep(dataset: xr.Dataset, fig_dir: Path, *, format: str = "png") -> list[Path]:
    """Figures of a stored ``envelope`` sweep: one file per map of :func:`envelope_maps` (and per value of
    any swept key beyond the first two), as ``format`` (``"png"``, ``"pdf"`` or ``"svg"``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from experiments.plotting import (
        check_format,
        clipped_extend,
        figure_path,
        plot_map,
        save,
        shared_range,
    )
    from experiments.plotting.sweep_overview import sweep_overview_figures

    check_format(format)
    fig_dir = Path(fig_dir)
    fig_dir.mkdir(parents=True, exist_ok=True)
    ds = dataset
    if ds.attrs.get("cell") != "envelope" or not {_X, _Y} <= set(ds.dims):
        return sweep_overview_figures(ds, fig_dir, format=format)
    grid = list(ds["done"].dims)
    col = grid[0]
    row = grid[1] if len(grid) > 1 else None
    rest = grid[2:]
    paths: list[Path] = []
    for name, (da, title, cbar, cmap, (lo, hi)) in envelope_maps(ds).items():
        vmin, vmax = shared_range(da.values, lo=lo, hi=hi)
        for combo in itertools.product(*(ds[d].values.tolist() for d in rest)):
            sel = dict(zip(rest, combo, strict=True))
            rows = ds[row].values.tolist() if row else [None]
            cols = ds[col].values.tolist()
            fig, axes = plt.subplots(len(rows), len(cols), figsize=(3.3 * len(cols) + 1.2, 2.9 * len(rows) + 0.6),
                                     layout="constrained", squeeze=False)
            shown = []
            for r, rv in enumerate(rows):
                for c, cv in enumerate(cols):
                    s = {**sel, col: cv, **({row: rv} if row else {})}
                    m = da.sel(s).transpose(_Y, _X).values
                    shown.append(m)
                    plot_map(m, ds[_X].values, ds[_Y].values, ax=axes[r, c], vmin=vmin, vmax=vmax, cmap=cmap,
                             xlabel="lateral offset [m]" if r == len(rows) - 1 else "",
                             ylabel="depth [m]" if c == 0 else "",
                             title=f"{cv:g}" + (f" / {rv:g}" if row else ""), annotate=True, fmt="{:.3g}",
                             colorbar=False, fontsize=6.0)
            fig.colorbar(axes[0, 0].collections[0], ax=axes.ravel().tolist(), label=cbar,
                         extend=clipped_extend(np.concatenate([m.ravel() for m in shown]), vmin, vmax))
            extra = ", ".join(f"{k} = {v}" for k, v in sel.items())
            fig.suptitle(f"004 envelope: {title}\npanels: {col}" + (f" / {row}" if row else "")
                         + (f" - {extra}" if extra else ""))
            suffix = "".join(f"_{k}{v}" for k, v in sel.items())
            paths.append(save(fig, figure_path(fig_dir, f"envelope_{name}{suffix}", format)))
    return paths
