"""The ``coobs`` command line: a typer app with one module per command."""

from __future__ import annotations

import typer

from coobs.cli import (
    bench,
    configs,
    export,
    figures,
    filter_study,
    plot,
    run,
    sweep,
    tumble,
    version,
)

__all__ = ["app", "main"]

app = typer.Typer(
    name="coobs",
    help=(
        "coobs: cooperative observation of a tumbling, non-cooperative spacecraft by a formation "
        "of observers. Run scenarios, sweep distance and baseline angle, plot error and "
        "convergence maps, and benchmark against peer libraries."
    ),
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
app.command("version")(version.version)
app.command("bench")(bench.bench)
app.command("tumble")(tumble.tumble)
app.command("run")(run.run)
app.command("plot")(plot.plot)
app.command("sweep")(sweep.sweep)
app.command("filter-study")(filter_study.filter_study)
app.command("figures")(figures.figures)
app.command("configs")(configs.configs)
app.command("export")(export.export)


def main() -> None:
    """Run the ``coobs`` app (the console-script entry point)."""
    app()
