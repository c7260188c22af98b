"""The registry of scenario kinds: which module runs, and draws, each ``kind`` of config.

A kind module exposes

``Config``
    its config model, a subclass of :class:`experiments.config.ScenarioConfig` whose ``kind`` is
    ``Literal["<kind>"]``;
``run(cfg, *, progress=None) -> ScenarioResult``
    the scenario, pure computation plus the ``progress(done, total)`` callback
    (:class:`experiments.results.ScenarioResult`);
``plot(dataset, fig_dir) -> list[Path]``
    figures drawn only from the stored dataset (so ``coobs plot DIR`` can redraw them);

and optionally ``sweep_cell(cfg) -> SweepCell`` (``coobs sweep``) and ``plot_sweep(dataset, fig_dir)``.
Kind modules are imported on demand, by name, so importing the registry loads none of them.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from types import ModuleType
from typing import Any

__all__ = ["KINDS", "UnknownKindError", "kind_module", "lazy_getattr"]

#: scenario kind → module implementing it.
KINDS: dict[str, str] = {
    "formation": "experiments.scenarios.formation",
    "tof_000": "experiments.scenarios.tof",
    "rodrigues_001": "experiments.scenarios.rodrigues",
    "cylindrical_004": "experiments.scenarios.cylindrical",
}


class UnknownKindError(ValueError):
    """A ``kind`` that no module implements; the message names the known kinds."""


def kind_module(kind: str) -> ModuleType:
    """Import the module of a scenario kind.

    Parameters
    ----------
    kind : str
        A key of :data:`KINDS`.

    Returns
    -------
    ModuleType
        The kind module (``Config``, ``run``, ``plot``, optionally ``sweep_cell``, ``plot_sweep``).

    Raises
    ------
    UnknownKindError
        ``kind`` is not registered.
    """
    if kind not in KINDS:
        raise UnknownKindError(f"kind: unknown scenario kind {kind!r}; known: {', '.join(sorted(KINDS))}")
    return importlib.import_module(KINDS[kind])


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
