"""``coobs configs``: the scenario configs shipped with coobs, one line each (name, kind, title)."""

from __future__ import annotations

from coobs.cli._console import console
from experiments.bundled import bundled_configs

__all__ = ["configs"]


def configs() -> None:
    """List the bundled configs: the name `coobs run` and the Python API accept, the kind, the title."""
    items = bundled_configs()
    width = max((len(n) for n in items), default=0)
    kind_width = max((len(b.kind) for b in items.values()), default=0)
    lines = [f"{name:<{width}}  {b.kind:<{kind_width}}  {'sweep ' if b.has_sweep else '      '}{b.title}"
             for name, b in items.items()]
    console.print("\n".join(lines), markup=False, highlight=False, soft_wrap=True)
