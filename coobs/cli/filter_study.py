"""``coobs filter-study``: the validation studies of ``filters``, printed as tables with units.

Writes ``OUT/result.nc`` (what the figures are drawn from, ``kind = "filter_study"``; ``coobs plot OUT``
redraws them), ``OUT/summary.json`` and ``OUT/figures/``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import typer
import xarray as xr
from rich.table import Table
from rich.text import Text

from coobs import api
from coobs.cli._console import console, fail
from coobs.cli._table import print_table, split_unit
from experiments.results import check_output_dir, write_result
from experiments.studies.filter_study import KIND, STUDIES, run_studies
from experiments.sweep import STORE_NAME

__all__ = ["filter_study"]

#: title and columns of each study's table
_TABLES: dict[str, tuple[str, tuple[str, ...]]] = {
    "expbc": ("Experiments B/C (absolute attitude, 60 s)",
              ("fraction_converged", "median_convergence_time_s", "final_rms_attitude_error_deg",
               "final_rms_rate_error_deg_s", "mean_nees_after", "nees_inside_fraction", "n_rejected")),
    "increments": ("increments in H (cloning) vs chained absolute, 0.2 deg, 60 s",
                   ("time_mean_nees_after_1s", "nees_inside_fraction", "final_rms_attitude_error_deg",
                    "final_rms_rate_error_deg_s", "n_rejected")),
    "ratios": ("inertia-ratio MEKF, 0.2 deg, 120 s",
               ("max_rel_error_60s", "max_rel_error_120s", "all_trials_within_1pct_from_s",
                "fraction_converged", "n_failed")),
    "robust": ("20 % missing (5 s gaps) + 10 % outliers, 0.2 deg, 60 s",
               ("fraction_converged", "median_convergence_time_s", "n_outliers", "n_rejected",
                "n_resets", "missing_fraction_measured", "n_failed")),
}


def _fmt(v: Any) -> str:
    if isinstance(v, list | tuple):
        return ", ".join(_fmt(x) for x in v)
    if isinstance(v, float):
        if np.isnan(v):
            return "-"
        return f"{v:.4g}"
    return str(v)


def _header(key: str) -> str:
    """A column header: the key in words, its unit in brackets (``median convergence time [s]``)."""
    name, unit = split_unit(key)
    return name.replace("_", " ") + (f" [{unit}]" if unit else "")


def _table(title: str, rows: dict, cols: tuple[str, ...]) -> None:
    table = Table(title=Text(title), title_justify="left")
    table.add_column("case", overflow="fold")
    for c in cols:
        table.add_column(Text(_header(c)), justify="right", overflow="fold")
    for key, row in rows.items():
        table.add_row(Text(key), *(Text(_fmt(row.get(c))) for c in cols))
    print_table(console, table)


def _check_out(out: Path) -> None:
    """Exit 2 before any computing when ``out`` cannot be written or holds another command's results."""
    try:
        check_output_dir(out, force=True)
    except ValueError as exc:
        raise fail(f"--{exc}") from None
    if (out / STORE_NAME).exists():
        raise fail(f"--out: {str(out)[:60]!r} holds {STORE_NAME} of a sweep; choose another folder")
    if (out / "result.nc").is_file():
        try:
            with xr.open_dataset(out / "result.nc", engine="h5netcdf") as ds:
                kind = ds.attrs.get("kind")
        except (OSError, ValueError):
            kind = None
        if kind != KIND:
            raise fail(f"--out: {str(out)[:60]!r} holds the results of another command (result.nc); "
                       "choose another folder")


def _print_study(name: str, result: dict[str, Any]) -> None:
    if name == "thresholds":
        flat = {k: {c: v["fraction_converged"] for c, v in row.items()} for k, row in result.items()}
        _table("fraction converged vs threshold (spec Q)", flat, tuple(next(iter(flat.values())).keys()))
    else:
        _table(_TABLES[name][0], result, _TABLES[name][1])


def filter_study(
    out: Path = typer.Option(Path("runs/filter_study"), "--out", help="Output folder."),
    trials: int = typer.Option(100, "--trials", help="Monte Carlo runs per case."),
    seed: int = typer.Option(2026, "--seed", help="Parent seed (one stream per trial is spawned)."),
    only: list[str] = typer.Option(None, "--only", help=f"Run only these studies: {', '.join(STUDIES)}."),
    figures: bool = typer.Option(True, "--figures/--no-figures", help="Write PNG figures."),
) -> None:
    """Validate the attitude filters: 003 Experiments B/C, NEES consistency, cloning, inertia ratios, robustness."""
    if trials < 2:
        raise fail(f"--trials: need at least 2, got {trials}")
    selected = only or list(STUDIES)
    for s in selected:
        if s not in STUDIES:
            raise fail(f"--only: unknown study {s!r}; known: {', '.join(STUDIES)}")
    _check_out(out)
    result = run_studies(selected, trials=trials, seed=seed, on_study=_print_study)
    try:
        write_result(result, out)
        written = api.plot(out, format="png") if figures else []
    except OSError as exc:
        raise fail(f"--out: cannot write in {str(out)[:60]!r} ({exc.strerror or type(exc).__name__})") from None
    console.print(f"results: {out / 'result.nc'}, {out / 'summary.json'}", markup=False, highlight=False)
    for f in written:
        console.print(f"figure: {f}", markup=False, highlight=False)
