"""Scenario configs: the frozen pydantic base every kind's ``Config`` subclasses, the kinds, and loading.

Every config file names its scenario kind at the top level (``kind = "tof_000"``); :data:`KINDS`
maps it to the module that implements it (the kind protocol is described in
:mod:`experiments.scenarios`), and the rest of the file is validated by that kind's model before any
work starts.  Bad configs raise :class:`ConfigError` with one line naming the key.
"""

from __future__ import annotations

import copy
import importlib
import tomllib
from collections.abc import Mapping
from pathlib import Path
from types import ModuleType
from typing import Any

import pydantic
from pydantic import BaseModel, ConfigDict

__all__ = [
    "KINDS",
    "kind_module",
    "ConfigError",
    "ConfigTable",
    "ScenarioConfig",
    "format_validation_error",
    "read_config",
    "load_config",
]


#: scenario kind → module implementing it (imported on demand, by name, so that no kind is loaded
#: before it is used and no kind module is imported by this one).
KINDS: dict[str, str] = {
    "formation": "experiments.scenarios.formation",
    "tof_000": "experiments.scenarios.tof",
    "rodrigues_001": "experiments.scenarios.rodrigues",
    "cylindrical_004": "experiments.scenarios.cylindrical",
}


class ConfigError(ValueError):
    """A config that cannot be run; the message is one line naming the key."""


def kind_module(kind: str) -> ModuleType:
    """Import the module of a scenario kind.

    Parameters
    ----------
    kind : str
        A key of :data:`KINDS`.

    Returns
    -------
    ModuleType
        The kind module (a sub-package of :mod:`experiments.scenarios`).

    Raises
    ------
    ConfigError
        ``kind`` is not registered.

    Notes
    -----
    A kind module exposes

    ``Config``
        its config model, a subclass of :class:`ScenarioConfig` whose ``kind`` is ``Literal["<kind>"]``;
    ``run(cfg, *, progress=None) -> ScenarioResult``
        the scenario, pure computation plus the ``progress(done, total)`` callback
        (:class:`experiments.results.ScenarioResult`);
    ``plot(dataset, fig_dir) -> list[Path]``
        figures drawn only from the stored dataset (so ``coobs plot DIR`` can redraw them);

    and optionally ``sweep_cell(cfg) -> SweepCell`` (``coobs sweep``) and ``plot_sweep(dataset, fig_dir)``.
    """
    if kind not in KINDS:
        raise ConfigError(f"kind: unknown scenario kind {kind!r}; known: {', '.join(sorted(KINDS))}")
    return importlib.import_module(KINDS[kind])


class ConfigTable(BaseModel):
    """A table of a scenario config: frozen, and unknown keys are errors.

    Change a validated config with ``cfg.model_copy(update={...})``, never by assignment.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")


class ScenarioConfig(ConfigTable):
    """The whole config file of one scenario kind; every kind's ``Config`` subclasses it.

    Attributes
    ----------
    kind : str
        The scenario kind (a key of :data:`KINDS`); subclasses narrow it to
        ``Literal["<their kind>"]``.
    """

    kind: str


def format_validation_error(err: pydantic.ValidationError) -> str:
    """One line naming the first bad key of a pydantic ``ValidationError``: ``"a.b: message (got value)"``."""
    first = err.errors()[0]
    key = ".".join(str(p) for p in first["loc"]) or "<root>"
    msg = first["msg"]
    if first["type"] == "extra_forbidden":
        msg = "unknown key"
    value = first.get("input")
    shown = "" if first["type"] in ("missing", "extra_forbidden") or isinstance(value, dict) else f" (got {value!r})"
    return f"{key}: {msg}{shown}"


def read_config(source: Path | str | Mapping[str, Any],
                overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The raw table of a config, with dotted-key overrides applied; nothing validated yet.

    Parameters
    ----------
    source : path or mapping
        A TOML file, or the already parsed table (copied, never changed).
    overrides : mapping, optional
        Dotted key (``"formation.distance_m"``) → value, set in the table (missing tables are created).

    Returns
    -------
    dict
        The table.

    Raises
    ------
    ConfigError
        The file is missing or not valid TOML.
    """
    if isinstance(source, Mapping):
        raw = copy.deepcopy(dict(source))
    else:
        path = Path(source)
        if not path.is_file():
            raise ConfigError(f"config: file not found: {path}")
        try:
            raw = tomllib.loads(path.read_text())
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"config: not valid TOML ({exc})") from None
    for dotted, value in (overrides or {}).items():
        node = raw
        parts = dotted.split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = value
    return raw


def load_config(source: Path | str | Mapping[str, Any],
                overrides: Mapping[str, Any] | None = None) -> tuple[ModuleType, ScenarioConfig]:
    """Read and validate a scenario config; returns ``(kind module, cfg)``.

    Parameters
    ----------
    source : path or mapping
        A TOML file or its parsed table; its top-level ``kind`` selects the scenario kind.
    overrides : mapping, optional
        Dotted key → value, applied before validation (see :func:`read_config`).

    Returns
    -------
    module : ModuleType
        The scenario kind (:func:`kind_module`).
    cfg : ScenarioConfig
        The validated config, an instance of ``module.Config``.

    Raises
    ------
    ConfigError
        One line naming the key, when anything is wrong.
    """
    raw = read_config(source, overrides)
    if "kind" not in raw:
        raise ConfigError(f"kind: missing (one of {', '.join(sorted(KINDS))})")
    module = kind_module(raw["kind"])
    try:
        cfg = module.Config.model_validate(raw)
    except pydantic.ValidationError as exc:
        raise ConfigError(format_validation_error(exc)) from None
    return module, cfg
