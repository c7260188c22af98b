"""``coobs plot DIR``: redraw the figures of a stored run or sweep from its result files."""

from __future__ import annotations

from pathlib import Path

import typer

from experiments.cli._console import console, fail
from experiments.cli._redraw import redraw_run, redraw_sweep
from experiments.config import ConfigError
from experiments.sweep import STORE_NAME

__all__ = ["plot"]


def plot(out: Path = typer.Argument(..., help="A directory written by 'coobs run' or 'coobs sweep'.")) -> None:
    """Redraw the figures of a stored run or sweep from its result files."""
    if not (out / "result.nc").is_file() and not (out / STORE_NAME).exists():
        raise fail(f"out: no result.nc or {STORE_NAME} in {out}")
    if (out / "result.nc").is_file():
        try:
            figures = redraw_run(out)
        except ConfigError as exc:
            raise fail(str(exc)) from None
    else:
        figures = redraw_sweep(out)
    for f in figures:
        console.print(f"figure: {f}")
