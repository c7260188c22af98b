"""The sweep of a config, as :func:`coobs.sweep` and ``coobs sweep`` run it: validation, then Dask."""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from types import ModuleType
from typing import Any

import xarray as xr

from coobs._source import ConfigLike, config_source, config_text
from experiments.config import ConfigError, ScenarioConfig, load_cell_configs, load_config, shorten
from experiments.results import json_default, write_summary
from experiments.sweep import SweepCell, open_sweep, run_sweep, sweep_summary
from experiments.sweep.runner import SweepReport
from experiments.sweep.spec import coord_names, grid_arrays, grid_cells, params_key

__all__ = ["prepare_config_sweep", "run_config_sweep"]


def prepare_config_sweep(config: Path | Mapping[str, Any], overrides: Mapping[str, Any] | None = None
                         ) -> tuple[ModuleType, ScenarioConfig, SweepCell, dict[str, list[Any]], list[ScenarioConfig]]:
    """Validate a sweep config and every cell's config; nothing is computed or written.

    Parameters
    ----------
    config : Path or mapping
        The TOML file or the parsed table (see :func:`coobs._source.config_source`).
    overrides : mapping, optional
        Dotted key → value, applied to the config before validation.

    Returns
    -------
    tuple
        ``(module, cfg, cell, grid, inputs)``: the scenario kind's module, the validated config,
        its sweep cell, the grid (dotted key → values) and every cell's validated config.

    Raises
    ------
    ConfigError
        One line naming the key when anything is wrong.
    """
    overrides = dict(overrides or {})
    module, cfg = load_config(config, overrides=overrides)
    spec = getattr(cfg, "sweep", None)
    if spec is None:
        raise ConfigError("sweep: missing [sweep] table (cell, trials, grid)")
    if not hasattr(module, "sweep_cell"):
        raise ConfigError(f"kind: scenario kind {cfg.kind!r} has no sweep cells")
    try:
        cell = module.sweep_cell(cfg)
    except ValueError as exc:
        raise ConfigError(f"sweep.cell: {exc}") from None
    grid = spec.grid_values()
    try:
        coord_names(list(grid))
        garr = grid_arrays(grid)
    except ValueError as exc:
        raise ConfigError(f"sweep.{exc}") from None
    try:  # linear in the cells: the [sweep] table is validated once, above
        inputs = load_cell_configs(config, overrides, (params for _, params in grid_cells(garr)))
    except ConfigError as exc:
        raise ConfigError(f"{exc} [in sweep.grid]") from None
    return module, cfg, cell, grid, inputs


def run_config_sweep(config: ConfigLike, out: str | os.PathLike, overrides: Mapping[str, Any] | None = None, *,
                     workers: int = 1, scheduler: str | None = None, processes: bool = True, retries: int = 1,
                     progress: Callable[[int, int], None] | None = None, dashboard_address: str | None = None,
                     on_connect: Callable[[str], None] | None = None
                     ) -> tuple[xr.Dataset, SweepReport, dict[str, Any], Path]:
    """Check, run (or resume) the ``[sweep]`` table of a config and write ``out/summary.json``.

    The parameters are those of :func:`coobs.sweep`, with ``progress`` a callable or ``None`` and
    ``on_connect(dashboard_url)`` called once the cluster is up.

    Returns
    -------
    tuple
        ``(dataset, report, summary, summary_path)``: the stored sweep, what
        :func:`experiments.sweep.run_sweep` did, the summary and the path of ``summary.json``.

    Raises
    ------
    ConfigError
        One line naming the key, for a bad config or a config without a ``[sweep]`` table.
    ValueError
        One line naming the argument (``out``, ``workers``, ``scheduler`` ...); nothing written.
    OSError
        The store could not be written while the sweep ran (finished cells are kept).
    """
    if overrides is not None and not isinstance(overrides, Mapping):
        raise ConfigError(f"overrides: must be a mapping of dotted key → value, not {type(overrides).__name__}")
    overrides = dict(overrides or {})
    source = config_source(config)
    out_path = Path(out)
    if (out_path / "result.nc").exists():
        raise ValueError(f"out: {shorten(str(out_path))} holds the results of a run (result.nc); use another folder")
    module, cfg, cell, grid, inputs = prepare_config_sweep(source, overrides)
    text = config_text(source, load_config(source)[1])
    by_params = {params_key(p): inp for (_, p), inp in zip(grid_cells(grid_arrays(grid)), inputs, strict=True)}
    report = run_sweep(cell, grid, trials=cfg.sweep.trials, out=out_path, seed=cfg.sweep.seed,
                       make_input=lambda params: by_params[params_key(params)],
                       identity=cfg.model_dump_json(exclude={"sweep"}), seed_keys=cfg.sweep.seed_keys,
                       attrs={"kind": cfg.kind, "config_toml": text,
                              "overrides": json.dumps(overrides, default=json_default)},
                       workers=workers, scheduler=scheduler, processes=processes, progress=progress,
                       retries=retries, dashboard_address=dashboard_address, on_connect=on_connect)
    ds = open_sweep(out_path)
    summary = sweep_summary(ds, report)
    return ds, report, summary, write_summary(out_path, summary)
