"""The gallery page, generated from the example scripts in ``examples/`` at build time.

Each ``examples/<name>.py`` gives one entry: the title and text of its module docstring, the
figures it wrote to ``docs/figures/gallery/<name>*.png`` (or ``.svg``), the command that runs it, and
its source.  A new script appears on the next build; nothing here names a particular example.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Example", "examples", "gallery_page"]

#: figure formats embedded in the gallery
FIGURE_SUFFIXES = (".png", ".svg")


@dataclass(frozen=True)
class Example:
    """One example script: its file, title, text, figures (paths relative to ``docs/``) and source."""

    path: Path
    title: str
    text: str
    figures: tuple[str, ...]
    source: str


def examples(root: Path | str = ".") -> list[Example]:
    """The example scripts under ``root/examples`` (files starting with ``_`` are helpers, skipped).

    Raises
    ------
    ValueError
        A script has no module docstring (its title would be missing from the gallery).
    """
    root = Path(root)
    gallery = root / "docs" / "figures" / "gallery"
    found = []
    for path in sorted((root / "examples").glob("*.py")):
        if path.name.startswith("_"):
            continue
        source = path.read_text(encoding="utf-8")
        doc = ast.get_docstring(ast.parse(source, filename=str(path)))
        if not doc:
            raise ValueError(f"examples/{path.name}: no module docstring (its gallery title and text)")
        title, _, text = doc.partition("\n")
        figures = tuple(sorted(f"figures/gallery/{f.name}" for f in gallery.glob(f"{path.stem}*")
                               if f.suffix in FIGURE_SUFFIXES)) if gallery.is_dir() else ()
        found.append(Example(path.relative_to(root), title.strip().rstrip("."), text.strip(), figures, source))
    return found


def gallery_page(root: Path | str = ".") -> str:
    """The gallery page as Markdown."""
    items = examples(root)
    lines = ["# Gallery", "",
             "Short scripts that use coobs as a library, the way a notebook would: each builds what it needs "
             "from the Python API, computes, and draws one figure. Run one from the repository root with "
             "`.venv/bin/python examples/<name>.py`. This page is generated from the scripts in `examples/` "
             "(their docstrings, their figures in `docs/figures/gallery/` and their source) at every build.",
             ""]
    if not items:
        lines += ["No example scripts are in `examples/` yet.", ""]
    for ex in items:
        lines += [f"## {ex.title}", "", ex.text, ""]
        lines += [f"![{ex.title}]({fig})" for fig in ex.figures]
        lines += ["", "```bash", f".venv/bin/python {ex.path.as_posix()}", "```", "",
                  f'??? example "Source: `{ex.path.as_posix()}`"', "",
                  "    ```python"]
        lines += [f"    {line}" if line else "" for line in ex.source.rstrip("\n").split("\n")]
        lines += ["    ```", ""]
    return "\n".join(lines) + "\n"
