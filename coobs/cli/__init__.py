"""The ``coobs`` command line: a typer app with one module per command, over the Python API of :mod:`coobs`.

``coobs run``, ``coobs sweep`` and ``coobs plot`` parse their options, call the functions behind
:func:`coobs.run`, :func:`coobs.sweep` and :func:`coobs.plot`, and print; ``python -m coobs`` runs the
same app.
"""

from __future__ import annotations

import typer

from coobs.cli import (
    bench,
    calibrate,
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


def _show_version(value: bool) -> None:
    if value:
        import coobs

        typer.echo(f"coobs {coobs.__version__}")
        raise typer.Exit()


@app.callback()
def _main(version: bool = typer.Option(False, "--version", callback=_show_version, is_eager=True,
                                       help="Print the coobs version and exit ('coobs version' lists the libraries).")
          ) -> None:
    """coobs: cooperative observation of a tumbling, non-cooperative spacecraft by a formation of observers."""
app.command("version")(version.version)
app.command("bench")(bench.bench)
app.command("tumble")(tumble.tumble)
app.command("run")(run.run)
app.command("plot")(plot.plot)
app.command("sweep")(sweep.sweep)
app.command("filter-study")(filter_study.filter_study)
app.command("figures")(figures.figures)
app.command("calibrate")(calibrate.calibrate)
app.command("configs")(configs.configs)
app.command("export")(export.export)


def main() -> None:
    """Run the ``coobs`` app (the console-script entry point)."""
    app()
