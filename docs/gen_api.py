"""The API reference pages of the science packages, generated from their ``__all__`` with griffe.

One page per package: first the names the package itself exports (its ``__all__``, the face a
notebook imports from), then, for every public sub-module (no ``_`` in its dotted path), the names
that module exports and the package does not already show.  Each group is a mkdocstrings
``::: module`` block with an explicit ``members`` list, so a name added to an ``__all__`` appears on
the next build and a name removed disappears.  griffe reads the sources statically: nothing is
imported, so Open3D, casadi and OpenCV are never loaded by the build.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import griffe

__all__ = ["PACKAGES", "HIDDEN", "ApiBlock", "ApiPage", "api_pages", "api_index"]

#: the notebook API, then the science packages in the order of the layering (bottom up), a page each
PACKAGES = ("coobs", "attitude", "orbits", "vision", "filters", "reconstruction", "formation", "chaser", "closed_loop")
#: sub-packages left off the pages: the command line (``coobs.cli``) is documented by ``coobs --help``
#: and the README, not as Python names
HIDDEN = ("coobs.cli",)


@dataclass(frozen=True)
class ApiBlock:
    """One ``::: module`` block: the module's dotted path and the names it renders."""

    module: str
    members: tuple[str, ...]


@dataclass(frozen=True)
class ApiPage:
    """The API page of one package: its summary line and its blocks, in order."""

    package: str
    summary: str
    blocks: tuple[ApiBlock, ...] = field(default_factory=tuple)

    def markdown(self) -> str:
        """The page as Markdown with mkdocstrings blocks."""
        lines = [f"# `{self.package}`", "",
                 f"{self.summary}", "",
                 "Generated from the package's `__all__` and those of its public sub-modules; "
                 "each name is shown once, under the module a notebook imports it from.", ""]
        for block in self.blocks:
            root = block.module == self.package
            lines += [f"::: {block.module}", "    options:",
                      f"      members: [{', '.join(block.members)}]" if block.members else "      members: false",
                      "      show_submodules: false",
                      f"      show_root_heading: {'false' if root else 'true'}",
                      ""]
        return "\n".join(lines)

    def names(self) -> set[str]:
        """``module.name`` for every name the page renders."""
        return {f"{b.module}.{n}" for b in self.blocks for n in b.members}


def _is_public_path(path: str) -> bool:
    hidden = any(path == h or path.startswith(h + ".") for h in HIDDEN)
    return not hidden and not any(part.startswith("_") for part in path.split("."))


def _exports(module: griffe.Module) -> list[str]:
    """The names a module exports: its ``__all__``, else its public names defined there."""
    if module.exports is not None:
        return [str(n) for n in module.exports]
    return [n for n, m in module.members.items()
            if not n.startswith("_") and not m.is_alias and not m.is_module]


def _canonical(module: griffe.Module, name: str) -> tuple[str, bool]:
    """The dotted path where ``module.name`` is defined, and whether it is a module."""
    obj = module.members[name]
    if obj.is_alias:
        try:
            obj = obj.final_target
        except (griffe.AliasResolutionError, griffe.CyclicAliasError):
            return obj.target_path, False
    return obj.path, obj.is_module


def _submodules(module: griffe.Module) -> list[griffe.Module]:
    """Every public sub-module below ``module`` (depth first, sorted by name)."""
    found = []
    for name in sorted(module.modules):
        sub = module.modules[name]
        if sub.is_alias or not _is_public_path(sub.path):
            continue
        found.append(sub)
        found.extend(_submodules(sub))
    return found


def _summary(module: griffe.Module) -> str:
    doc = module.docstring.value.strip() if module.docstring else ""
    return doc.split("\n\n")[0].replace("\n", " ") if doc else ""


def _page(package: griffe.Module) -> ApiPage:
    seen: set[str] = set()
    blocks = []
    for module in [package, *_submodules(package)]:
        members = []
        for name in _exports(module):
            if name not in module.members:
                raise ValueError(f"{module.path}.__all__: {name!r} is not defined in the module")
            path, is_module = _canonical(module, name)
            if is_module or path in seen:
                continue
            seen.add(path)
            members.append(name)
        if members or module is package:
            blocks.append(ApiBlock(module.path, tuple(members)))
    return ApiPage(package.path, _summary(package), tuple(blocks))


def api_pages(root: Path | str = ".", packages: tuple[str, ...] = PACKAGES) -> list[ApiPage]:
    """The API pages of ``packages``, read statically from the sources under ``root``.

    Parameters
    ----------
    root : Path or str
        The repository root (the folder holding the packages).
    packages : tuple of str
        The packages, one page each.

    Returns
    -------
    list of ApiPage
        One page per package, in the order given.
    """
    loader = griffe.GriffeLoader(search_paths=[str(root)], docstring_parser=griffe.Parser.numpy,
                                 extensions=griffe.load_extensions("griffe_sphinx"))
    modules = [loader.load(p) for p in packages]
    loader.resolve_aliases(implicit=False, external=False)
    return [_page(m) for m in modules]


def api_index(pages: list[ApiPage]) -> str:
    """The API reference's landing page: one row per package with its summary."""
    lines = ["# API reference", "",
             "`coobs` is the entry point for notebooks (run a bundled scenario, sweep it, plot it); the "
             "science packages below it are the building blocks: plain functions and small frozen "
             "dataclasses over numpy arrays, importable on their own (the [architecture](../architecture.md) "
             "says which imports which). Every page is generated at build time from the packages' "
             "`__all__` and numpydoc docstrings.", "",
             "| package | names | what it does |", "|---|---|---|"]
    for page in pages:
        lines.append(f"| [`{page.package}`]({page.package}.md) | {len(page.names())} | {page.summary} |")
    return "\n".join(lines) + "\n"
