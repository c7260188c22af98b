"""The ``coobs`` command line (typer).

Subcommands: ``version``, ``bench``, ``tumble`` here; ``run``, ``sweep`` and ``plot`` are
registered by the experiments modules that implement them (ARCHITECTURE §4).  Bad input exits
with code 2 and one line naming the parameter.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

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
console = Console()
err_console = Console(stderr=True)


def fail(message: str) -> typer.Exit:
    """Print a one-line error and return the exit (code 2) to raise."""
    err_console.print(f"error: {message}", markup=False, highlight=False, soft_wrap=True)
    return typer.Exit(code=2)


@app.command()
def version() -> None:
    """Print the installed coobs version and the versions of the libraries it relies on."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as dist_version

    lines = []
    for dist in ("coobs", "numpy", "scipy", "open3d", "opencv-contrib-python-headless", "pycolmap",
                 "casadi", "filterpy", "xarray", "zarr", "dask"):
        try:
            lines.append(f"{dist} {dist_version(dist)}")
        except PackageNotFoundError:
            lines.append(f"{dist} (not installed)")
    console.print("\n".join(lines), markup=False, highlight=False)


def _fmt(x: float) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    ax = abs(x)
    if ax != 0 and (ax >= 1e5 or ax < 1e-2):
        return f"{x:.3g}"
    return f"{x:.3f}" if ax < 10 else f"{x:.1f}"


@app.command()
def bench(
    only: list[str] = typer.Option(None, "--only", help="Run only these topics (repeatable)."),
    out: Path = typer.Option(Path("bench.json"), "--out", help="Where to write the JSON table."),
    quick: bool = typer.Option(False, "--quick", help="Smaller problem sizes, for a smoke run."),
) -> None:
    """Run the benchmarks and print a table: ours beside the peer library, as ratios (> 1: ours better)."""
    from experiments import bench as bench_mod

    known = bench_mod.topics()
    selected = only or known
    for topic in selected:
        if topic not in known:
            raise fail(f"--only: unknown benchmark topic {topic!r}; known: {', '.join(known)}")
    rows = []
    table = Table(title="coobs bench (ratio > 1: coobs better than the peer)")
    for col in ("topic", "benchmark", "figure", "unit", "peer", "peer figure", "ratio", "note"):
        table.add_column(col)
    for topic in selected:
        console.print(f"[bold]bench[/bold] {topic} …")
        for row in bench_mod.run_topic(topic, quick=quick):
            rows.append({"topic": topic, **row.as_dict()})
            table.add_row(topic, row.benchmark, _fmt(row.figure), row.unit, row.peer,
                          _fmt(row.peer_figure), _fmt(row.ratio), row.note)
    Console(width=max(console.width, 180)).print(table)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(rows, indent=2, default=float) + "\n")
    console.print(f"wrote {out}")


def main() -> None:  # pragma: no cover - console-script shim
    app()


# Subcommands implemented in other modules register themselves on ``app`` when imported.
from experiments import commands as _commands  # noqa: E402,F401
