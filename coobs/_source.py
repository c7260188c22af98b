"""What :func:`coobs.run` and :func:`coobs.sweep` accept as a config, resolved to a file or a table."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import tomli_w

from experiments.bundled import bundled_config_path, is_bundled_name
from experiments.config import ConfigError, ScenarioConfig, one_line, read_config_text, shorten
from experiments.results import json_default

__all__ = ["ConfigLike", "config_source", "config_text"]

#: a config as the API takes it: a TOML file, a bundled config's name, a parsed table or a validated config
ConfigLike = str | os.PathLike | Mapping[str, Any] | ScenarioConfig


def _is_file(path: Path) -> bool:
    try:
        return path.is_file()
    except (OSError, ValueError):  # a name too long for the file system, a NUL byte
        return False


def config_source(config: ConfigLike) -> Path | dict[str, Any]:
    """The file or the table that ``experiments.config.load_config`` reads for ``config``.

    Parameters
    ----------
    config : str, path, mapping or ScenarioConfig
        A TOML file; a bundled config's name (``"quickstart"``, see :func:`coobs.configs`); a parsed
        table (a mapping as ``tomllib`` gives it); or a validated config (a kind's ``Config``).

    Returns
    -------
    Path or dict
        The file, or the table (a validated config becomes the table of all its values).

    Raises
    ------
    ConfigError
        ``config`` is of another type, or names neither a file nor a bundled config.
    """
    if isinstance(config, ScenarioConfig):
        return config.model_dump(mode="json", exclude_none=True)
    if isinstance(config, Mapping):
        return dict(config)
    if isinstance(config, str | os.PathLike):
        try:
            path = Path(config)
        except TypeError:
            path = None
        if path is not None and _is_file(path):
            return path
        if isinstance(config, str) and is_bundled_name(config):
            return bundled_config_path(config)
        if path is not None and path.is_dir():
            raise ConfigError(f"config: {shorten(str(config))} is a folder, not a config file")
        text = str(config)
        if "/" in text or "\\" in text or text.endswith(".toml"):
            raise ConfigError(f"config: file not found: {shorten(text)}")  # a path, not a name
        return bundled_config_path(str(config))  # raises, listing the bundled names
    raise ConfigError("config: must be a TOML file, a bundled config's name, a mapping or a validated "
                      f"config, not {type(config).__name__}")


def config_text(source: Path | Mapping[str, Any], cfg: ScenarioConfig,
                overrides: Mapping[str, Any] | None = None) -> str:
    """The TOML text stored with a result (its ``config_toml`` attribute), from which it can be run again.

    A file without overrides is stored as it is, comments included, as ``coobs run`` stores it;
    otherwise the validated config ``cfg`` is written out in full (every default spelt), after a
    comment saying where it came from.
    """
    if isinstance(source, Path) and not overrides:
        return read_config_text(source)
    origin = source.name if isinstance(source, Path) else "a table"
    if overrides:
        origin += " with " + json.dumps(dict(overrides), default=json_default)
    header = one_line(f"# written by coobs from {origin}", limit=200)
    return header + "\n" + tomli_w.dumps(cfg.model_dump(mode="json", exclude_none=True))
