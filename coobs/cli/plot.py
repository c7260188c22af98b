"""``coobs plot DIR``: redraw the figures of a stored run or sweep from its result files.

A folder without results, or results that cannot be read, exit with code 2 and one line.
"""

from __future__ import annotations

from pathlib import Path

import typer

from coobs.cli._console import console, fail
from coobs.cli._redraw import redraw_run, redraw_sweep
from experiments.config import ConfigError
from experiments.sweep import STORE_NAME

__all__ = ["plot"]


def plot(out: Path = typer.Argument(..., help="A directory written by 'coobs run' or 'coobs sweep'."),
         fmt: str = typer.Option("png", "--format", help="Figure file format: png, pdf or svg.")) -> None:
    """Redraw the figures of a stored run or sweep from its result files."""
    if fmt not in ("png", "pdf", "svg"):
        raise fail(f"format: must be one of png, pdf, svg, got {fmt!r}")
    shown = repr(str(out)) if len(str(out)) <= 58 else repr(str(out)[:55]) + "..."
    try:
        is_run = (out / "result.nc").is_file()
        is_sweep = (out / STORE_NAME).exists()
    except OSError as exc:
        raise fail(f"out: {shown} cannot be used ({exc.strerror or type(exc).__name__})") from None
    if not is_run and not is_sweep:
        raise fail(f"out: no result.nc or {STORE_NAME} in {shown}")
    try:
        figures = redraw_run(out, format=fmt) if is_run else redraw_sweep(out, format=fmt)
    except ConfigError as exc:
        raise fail(str(exc)) from None
    except (OSError, ValueError, KeyError) as exc:
        what = "result.nc" if is_run else STORE_NAME
        raise fail(f"out: {what} in {shown} cannot be read ({type(exc).__name__}: {exc})") from None
    for f in figures:
        console.print(f"figure: {f}")
