"""``coobs plot DIR``: redraw the figures of a stored run, sweep or filter study, as :func:`coobs.plot`.

The folder's stored dataset (``result.nc`` of ``coobs run`` or ``coobs filter-study``, else
``sweep.zarr``) says what it holds; its ``kind`` picks the figures.  A folder without results, or
results that cannot be read, exit with code 2 and one line.
"""

from __future__ import annotations

from pathlib import Path

import typer

from coobs import api
from coobs.cli._console import console, fail
from experiments.config import ConfigError
from experiments.sweep import STORE_NAME

__all__ = ["plot"]


def plot(out: Path = typer.Argument(..., help="A directory written by 'coobs run', 'coobs sweep' or "
                                    "'coobs filter-study'."),
         fmt: str = typer.Option("png", "--format", help="Figure file format: png, pdf or svg.")) -> None:
    """Redraw the figures of a stored run, sweep or filter study from its result files."""
    if fmt not in ("png", "pdf", "svg"):
        raise fail(f"format: must be one of png, pdf, svg, got {fmt!r}")
    try:
        dataset = api.folder_dataset(out)
    except ValueError as exc:
        raise fail(str(exc)) from None
    what = "result.nc" if (out / "result.nc").is_file() else STORE_NAME
    try:
        figures = api.plot(dataset, out / "figures", format=fmt)
    except ConfigError as exc:
        raise fail(str(exc)) from None
    except (OSError, ValueError, KeyError) as exc:
        raise fail(f"out: {what} in {str(out)[:58]!r} cannot be read ({type(exc).__name__}: {exc})") from None
    for f in figures:
        console.print(f"figure: {f}", markup=False, highlight=False)
