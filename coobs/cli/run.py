"""``coobs run CONFIG --out DIR``: one scenario end to end, written as result.nc, summary.json, figures/.

The config and the output folder are checked before any computing: a bad config, an output path
that is a file or cannot be written, or a folder holding another run's results (without
``--force``) exit with code 2, one line naming the key or option, and nothing written.
"""

from __future__ import annotations

from pathlib import Path

import typer

from coobs.cli._console import console, fail, progress_bar
from coobs.cli._redraw import redraw_run
from experiments.config import ConfigError, load_config, read_config_text
from experiments.results import check_output_dir, summary_text, write_result
from experiments.sweep import STORE_NAME

__all__ = ["run"]


def run(
    config: Path = typer.Argument(..., help="Scenario config (TOML); its top-level 'kind' selects the scenario."),
    out: Path = typer.Option(..., "--out", help="Output directory: result.nc, summary.json, figures/."),
    no_figures: bool = typer.Option(False, "--no-figures", help="Skip drawing figures."),
    force: bool = typer.Option(False, "--force", help="Replace the results of another run (or a sweep) in --out."),
) -> None:
    """Run one scenario end to end and write result.nc, summary.json and figures/ under --out."""
    try:
        module, cfg = load_config(config)
        config_toml = read_config_text(config)
    except ConfigError as exc:
        raise fail(str(exc)) from None
    try:
        check_output_dir(out, config_toml=config_toml, force=force, foreign=(STORE_NAME,))
    except ValueError as exc:
        raise fail(f"--{exc}") from None
    update, stop = progress_bar()
    try:
        result = module.run(cfg, progress=update)
    finally:
        stop()
    result.dataset.attrs["kind"] = cfg.kind
    result.dataset.attrs["config_toml"] = config_toml
    try:
        write_result(result, out)
        figures = [] if no_figures else redraw_run(out)
    except OSError as exc:
        raise fail(f"--out: cannot write in {str(out)[:60]!r} ({exc.strerror or type(exc).__name__})") from None
    console.print(summary_text(result.summary), markup=False, highlight=False)
    console.print(f"results: {out / 'result.nc'}, {out / 'summary.json'}")
    for f in figures:
        console.print(f"figure: {f}")
