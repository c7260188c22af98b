"""``coobs bench``: the benchmarks beside their peer libraries, as a table and JSON rows."""

from __future__ import annotations

import json
import math
from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from coobs.cli._console import console, fail

__all__ = ["bench"]


def _fmt(x: float | None) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    ax = abs(x)
    if ax != 0 and (ax >= 1e5 or ax < 1e-2):
        return f"{x:.3g}"
    return f"{x:.3f}" if ax < 10 else f"{x:.1f}"


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
