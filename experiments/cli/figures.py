"""``coobs figures TOPIC --out DIR``: the docs figures of a science package, computed and drawn."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import typer

from experiments.cli._console import console, fail

__all__ = ["TOPICS", "figures"]


def _orbits(out: Path) -> list[Path]:
    from experiments.studies.orbit_figures import draw_orbit_figures

    return draw_orbit_figures(out)


def _vision(out: Path) -> list[Path]:
    from experiments.studies.vision_figures import draw_vision_figures

    return draw_vision_figures(out)


#: topic → the function that computes its study and writes its figures into a folder
TOPICS: dict[str, Callable[[Path], list[Path]]] = {"orbits": _orbits, "vision": _vision}


def figures(
    topic: str = typer.Argument(..., help=f"Which docs figures: {', '.join(TOPICS)}."),
    out: Path = typer.Option(Path("docs/figures"), "--out", help="Folder the PNG files are written to."),
) -> None:
    """Compute and draw the docs figures of one topic (orbits: CW error growth; vision: three matched views)."""
    if topic not in TOPICS:
        raise fail(f"topic: unknown figures topic {topic!r}; known: {', '.join(TOPICS)}")
    for path in TOPICS[topic](out):
        console.print(f"figure: {path}")
