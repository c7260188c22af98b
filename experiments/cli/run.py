"""``coobs run CONFIG --out DIR``: one scenario end to end, written as result.nc, summary.json, figures/.

Bad configs exit with code 2, one line naming the key, and nothing written.
"""

from __future__ import annotations

from pathlib import Path

import typer

from experiments.cli._console import console, fail, progress_bar
from experiments.cli._redraw import redraw_run
from experiments.config import ConfigError, load_config
from experiments.results import summary_text, write_result

__all__ = ["run"]


def run(
    config: Path = typer.Argument(..., help="Scenario config (TOML); its top-level 'kind' selects the scenario."),
    out: Path = typer.Option(..., "--out", help="Output directory: result.nc, summary.json, figures/."),
    no_figures: bool = typer.Option(False, "--no-figures", help="Skip drawing figures."),
) -> None:
    """Run one scenario end to end and write result.nc, summary.json and figures/ under --out."""
    try:
        module, cfg = load_config(config)
    except ConfigError as exc:
        raise fail(str(exc)) from None
    update, stop = progress_bar()
    try:
        result = module.run(cfg, progress=update)
    finally:
        stop()
    result.dataset.attrs["kind"] = cfg.kind
    result.dataset.attrs["config_toml"] = Path(config).read_text()
    write_result(result, out)
    figures = [] if no_figures else redraw_run(out)
    console.print(summary_text(result.summary), markup=False, highlight=False)
    console.print(f"results: {out / 'result.nc'}, {out / 'summary.json'}")
    for f in figures:
        console.print(f"figure: {f}")
