"""Generic figures of any stored sweep: each metric's trial mean over the swept parameters."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import xarray as xr  # noqa: E402

from experiments.plotting.primitives import plot_band, plot_map, shared_range  # noqa: E402
from experiments.plotting.style import check_format, figure_path, save  # noqa: E402

__all__ = ["sweep_overview_figures"]


def _label(ds: xr.Dataset, name: str) -> str:
    var = ds[name]
    units = var.attrs.get("units", "")
    return f"{name} [{units}]" if units else name


def sweep_overview_figures(ds: xr.Dataset, fig_dir: Path, *, swept: Sequence[str] | None = None,
                           format: str = "png") -> list[Path]:
    """Generic sweep figures: for each metric, its trial mean over the swept parameters.

    One swept parameter: mean with the 10–90 % band over trials.  Two or more: a colour map over
    the first two, one panel per value of the third (further ones at their first value), all
    panels on one colour range with one colour bar.  ``format``: ``"png"``, ``"pdf"`` or ``"svg"``.
    """
    check_format(format)
    swept = list(swept) if swept is not None else list(ds["done"].dims)
    keys = json.loads(ds.attrs.get("swept_keys", "[]"))
    paths: list[Path] = []
    for name, var in ds.data_vars.items():
        if name in ("failure_reason", "done"):
            continue
        extra = [d for d in var.dims if d not in swept and d != "trial"]
        if extra:
            var = var.isel({d: -1 for d in extra})
        has_trial = "trial" in var.dims
        mean = var.mean("trial", skipna=True) if has_trial else var
        if len(swept) == 1:
            fig, ax = plt.subplots(figsize=(5.5, 4.0), layout="constrained")
            x = ds[swept[0]].values
            lo = var.quantile(0.1, "trial", skipna=True).values if has_trial else None
            hi = var.quantile(0.9, "trial", skipna=True).values if has_trial else None
            plot_band(x, mean.values, lo, hi, ax=ax, xlabel=keys[0] if keys else swept[0],
                      ylabel=_label(ds, name), title=f"{name}: trial mean, 10-90 % band")
        else:
            third = swept[2] if len(swept) > 2 else None
            mean = mean.isel({d: 0 for d in swept[3:]})
            panels = list(ds[third].values) if third else [None]
            fig, axes = plt.subplots(1, len(panels), figsize=(5.0 * len(panels), 4.0), layout="constrained",
                                     squeeze=False)
            vmin, vmax = shared_range(mean.values)
            for ax, p in zip(axes[0], panels, strict=True):
                m = mean.sel({third: p}) if third else mean
                m = m.transpose(swept[1], swept[0])
                plot_map(m.values, ds[swept[0]].values, ds[swept[1]].values, ax=ax, vmin=vmin, vmax=vmax,
                         xlabel=swept[0], ylabel=swept[1], colorbar=False,
                         title=f"{name} (trial mean)" + (f", {third} = {p}" if third else ""))
            fig.colorbar(axes[0, 0].collections[0], ax=axes[0].tolist(), label=_label(ds, name))
        paths.append(save(fig, figure_path(fig_dir, f"sweep_{name}", format)))
    return paths
