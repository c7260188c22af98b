"""``coobs figures TOPIC --out DIR``: the docs figures of a science package, computed and drawn."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import typer

from coobs.cli._console import console, fail

__all__ = ["TOPICS", "figures"]


def _orbits(out: Path, fmt: str) -> list[Path]:
    from experiments.studies.orbit_figures import draw_orbit_figures

    return draw_orbit_figures(out, format=fmt)


def _vision(out: Path, fmt: str) -> list[Path]:
    from experiments.studies.vision_figures import draw_vision_figures

    return draw_vision_figures(out, format=fmt)


#: topic → the function that computes its study and writes its figures into a folder, in a format
TOPICS: dict[str, Callable[[Path, str], list[Path]]] = {"orbits": _orbits, "vision": _vision}
#: the figure formats (those of :data:`experiments.plotting.FORMATS`, kept here so that --help loads no matplotlib)
FORMATS = ("png", "pdf", "svg")


def figures(
    topic: str = typer.Argument(..., help=f"Which docs figures: {', '.join(TOPICS)}."),
    out: Path = typer.Option(Path("docs/figures"), "--out", help="Folder the figure files are written to."),
    fmt: str = typer.Option("png", "--format", help=f"Figure file format: {', '.join(FORMATS)}."),
) -> None:
    """Compute and draw the docs figures of one topic (orbits: CW error growth; vision: three matched views)."""
    if topic not in TOPICS:
        raise fail(f"topic: unknown figures topic {topic!r}; known: {', '.join(TOPICS)}")
    if fmt not in FORMATS:
        raise fail(f"format: must be one of {', '.join(FORMATS)}, got {fmt!r}")
    for path in TOPICS[topic](out, fmt):
        console.print(f"figure: {path}")
