"""``coobs filter-study``: the validation studies of ``filters``, printed as tables and written as JSON."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import typer
from rich.table import Table

from coobs.cli._console import console, fail
from experiments.studies.filter_study import STUDIES, run_studies

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


def _table(title: str, rows: dict, cols: tuple[str, ...]) -> None:
    table = Table(title=title)
    table.add_column("case")
    for c in cols:
        table.add_column(c)
    for key, row in rows.items():
        table.add_row(key, *(_fmt(row.get(c)) for c in cols))
    console.print(table)


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
    figs = out / "figures" if figures else None
    if figs is not None:
        figs.mkdir(parents=True, exist_ok=True)
    else:
        out.mkdir(parents=True, exist_ok=True)
    summary = run_studies(selected, trials=trials, seed=seed, fig_dir=figs, on_study=_print_study)
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float) + "\n")
    console.print(f"wrote {out / 'summary.json'}")
