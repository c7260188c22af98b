"""The scenario kinds: one sub-package per ``kind`` of config, each running and drawing its scenario."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

from experiments.config import KINDS, kind_module

__all__ = ["KINDS", "kind_module", "lazy_getattr"]


def lazy_getattr(package: str, names: Mapping[str, str]) -> Callable[[str], Any]:
    """A module-level ``__getattr__`` for a kind package that imports its heavy sub-modules on first use.

    Parameters
    ----------
    package : str
        The kind package (its ``__name__``).
    names : mapping of str to str
        Public name → the sub-module of ``package`` that defines it (``{"run": "run", "plot": "figures"}``).

    Returns
    -------
    callable
        ``__getattr__(name)``: the attribute from its sub-module; ``AttributeError`` for other names.
    """

    def __getattr__(name: str) -> Any:
        if name in names:
            return getattr(importlib.import_module(f"{package}.{names[name]}"), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__
