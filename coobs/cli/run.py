"""``coobs run NAME|CONFIG [--set KEY=VALUE] [--out DIR]``: one scenario end to end, as :func:`coobs.run`.

The config (a bundled config's name or a TOML file), the overrides and the output folder are checked
before any computing: a bad config, an output path that is a file or cannot be written, or a folder
holding another run's results (without ``--force``) exit with code 2, one line naming the key or
option, and nothing written.  The key results are printed as a table with units.
"""

from __future__ import annotations

from pathlib import Path

import typer

from coobs import api
from coobs._source import config_source
from coobs.cli._console import console, fail, progress_bar
from coobs.cli._table import print_table, summary_table
from experiments.config import ConfigError
from experiments.sweep import parse_overrides

__all__ = ["DEFAULT_RUNS", "run"]

#: the folder under which ``coobs run`` writes by default (``runs/<config name>``)
DEFAULT_RUNS = Path("runs")


def run(
    config: str = typer.Argument(..., help="A bundled config's name (see 'coobs configs') or a scenario config "
                                 "file (TOML); its top-level 'kind' selects the scenario."),
    out: Path = typer.Option(None, "--out", help="Output directory: result.nc, summary.json, figures/ "
                             "[default: runs/<config name>]."),
    set_: list[str] = typer.Option(None, "--set", help="Override a config key, KEY=VALUE (TOML value); repeatable."),
    no_figures: bool = typer.Option(False, "--no-figures", help="Skip drawing figures."),
    force: bool = typer.Option(False, "--force", help="Replace the results of another run (or a sweep) in --out."),
) -> None:
    """Run one scenario end to end: write result.nc, summary.json and figures/, print the key results."""
    try:
        overrides = parse_overrides(set_)
        source = config_source(config)
        if out is None:
            out = DEFAULT_RUNS / source.stem  # a bundled name or a file: config_source gives its file
        module, cfg, text, out_path = api.prepare_run(source, overrides or None, out, force)
    except ConfigError as exc:
        raise fail(str(exc)) from None
    except ValueError as exc:  # --set, or out: from the output check
        raise fail(f"--{exc}" if str(exc).startswith("out:") else str(exc)) from None
    update, stop = progress_bar()
    try:
        result = api.compute_run(module, cfg, text, update)
    finally:
        stop()
    try:
        stored = api.store_run(result, cfg, out_path)
        figures = [] if no_figures else api.plot(out)
    except OSError as exc:
        raise fail(f"--out: cannot write in {str(out)[:60]!r} ({exc.strerror or type(exc).__name__})") from None
    print_table(console, summary_table(stored.summary, title=f"{source.stem} ({cfg.kind}): key results"))
    console.print(f"results: {out / 'result.nc'}, {out / 'summary.json'}", markup=False, highlight=False)
    for f in figures:
        console.print(f"figure: {f}", markup=False, highlight=False)
