"""Figures of a stored run or sweep, redrawn by its scenario kind (named in the stored attributes)."""

from __future__ import annotations

import functools
from pathlib import Path

import xarray as xr

from experiments.config import ConfigError, kind_module
from experiments.sweep import STORE_NAME
from experiments.sweep import redraw as redraw_sweep_store

__all__ = ["redraw_run", "redraw_sweep"]


def redraw_run(out: Path, *, format: str = "png") -> list[Path]:
    """Redraw the figures of a stored run from ``out/result.nc`` into ``out/figures`` as ``format``
    (``"png"``, ``"pdf"`` or ``"svg"``).

    Raises
    ------
    ConfigError
        The dataset names no scenario kind, or one that no module implements.
    """
    ds = xr.load_dataset(out / "result.nc", engine="h5netcdf")
    kind = ds.attrs.get("kind")
    if kind is None:
        raise ConfigError(f"{out / 'result.nc'}: dataset has no 'kind' attribute")
    module = kind_module(kind)
    fig_dir = out / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    return list(module.plot(ds, fig_dir, format=format))


def redraw_sweep(out: Path, *, format: str = "png") -> list[Path]:
    """Redraw the figures of a stored sweep into ``out/figures`` as ``format``.

    Uses the scenario kind's ``plot_sweep(dataset, fig_dir)`` when the sweep came from a config
    whose kind defines one, else a generic map of every per-trial metric's trial mean.
    """
    with xr.open_zarr(Path(out) / STORE_NAME, consolidated=False) as ds:
        kind = ds.attrs.get("kind")
    plot_sweep = getattr(kind_module(kind), "plot_sweep", None) if kind else None
    if plot_sweep is None:
        from experiments.plotting import sweep_overview_figures

        plot_sweep = sweep_overview_figures
    return redraw_sweep_store(out, functools.partial(plot_sweep, format=format))
