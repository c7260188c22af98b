"""``coobs sweep CONFIG --out DIR``: the ``[sweep]`` table of a scenario config, run on Dask.

The scenario kind provides the cell function through ``sweep_cell(cfg) -> SweepCell``; every cell's
config is validated before any work starts.  Running the same command again resumes: finished
cells are not recomputed.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from types import ModuleType
from typing import Any

import typer

from experiments.cli._console import console, fail, progress_bar
from experiments.cli._redraw import redraw_sweep
from experiments.config import ConfigError, ScenarioConfig, load_config
from experiments.results import write_summary
from experiments.sweep import SweepCell, open_sweep, parse_overrides, run_sweep, sweep_summary
from experiments.sweep.spec import coord_names, grid_arrays, grid_cells, params_key

__all__ = ["prepare_config_sweep", "sweep"]


def prepare_config_sweep(config: Path | str, overrides: Mapping[str, Any] | None = None
                         ) -> tuple[ModuleType, ScenarioConfig, SweepCell, dict[str, list[Any]], list[ScenarioConfig]]:
    """Validate a sweep config and every cell's config; nothing is computed or written.

    ``overrides`` (dotted key → value) are applied to the file before validation.  Returns
    ``(module, cfg, cell, grid, inputs)``; raises :class:`experiments.config.ConfigError` (one line
    naming the key) when anything is wrong.
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
    inputs = []
    for _, params in grid_cells(garr):
        try:
            inputs.append(load_config(config, overrides={**overrides, **params})[1])
        except ConfigError as exc:
            raise ConfigError(f"{exc} [in sweep.grid]") from None
    return module, cfg, cell, grid, inputs


def sweep(
    config: Path = typer.Argument(..., help="Scenario config (TOML) with a sweep table (cell, trials, seed, grid)."),
    out: Path = typer.Option(..., "--out", help="Output directory: sweep.zarr, summary.json, figures/."),
    workers: int = typer.Option(2, "--workers", help="Dask LocalCluster workers (one thread each)."),
    scheduler: str = typer.Option(None, "--scheduler", help="Address of a running Dask scheduler instead of a LocalCluster."),
    no_figures: bool = typer.Option(False, "--no-figures", help="Skip drawing figures."),
    set_: list[str] = typer.Option(None, "--set", help="Override a config key, KEY=VALUE (TOML value); repeatable."),
) -> None:
    """Sweep config keys over a grid × trials on Dask, streaming each cell to DIR/sweep.zarr.

    Running the same command again resumes: finished cells are not recomputed.
    """
    if workers < 1:
        raise fail(f"--workers: must be >= 1, got {workers}")
    try:
        overrides = parse_overrides(set_)
        module, cfg, cell, grid, inputs = prepare_config_sweep(config, overrides)
    except (ConfigError, ValueError) as exc:
        raise fail(str(exc)) from None
    spec = cfg.sweep
    identity = cfg.model_dump_json(exclude={"sweep"})
    config_text = Path(config).read_text()
    by_params = {params_key(p): inp for (_, p), inp in zip(grid_cells(grid_arrays(grid)), inputs, strict=True)}
    update, stop = progress_bar()
    try:
        report = run_sweep(cell, grid, trials=spec.trials, out=out, seed=spec.seed,
                           make_input=lambda params: by_params[params_key(params)], identity=identity,
                           seed_keys=spec.seed_keys,
                           attrs={"kind": cfg.kind, "config_toml": config_text,
                                  "overrides": json.dumps(overrides)},
                           workers=workers, scheduler=scheduler, progress=update)
    except ValueError as exc:
        raise fail(str(exc)) from None
    finally:
        stop()
    ds = open_sweep(out)
    summary = sweep_summary(ds, report)
    path = write_summary(out, summary)
    figures = [] if no_figures else redraw_sweep(out)
    console.print(f"cells: {summary['cells_done']}/{summary['cells']} done "
                  f"({report.n_computed} computed now, {report.wall_s:.1f} s on {report.workers} workers); "
                  f"failed trials: {summary['trials_failed']}", markup=False, highlight=False)
    console.print(f"results: {report.store}, {path}", markup=False, highlight=False)
    for f in figures:
        console.print(f"figure: {f}", markup=False, highlight=False)
