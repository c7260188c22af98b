"""The scenario configs shipped with coobs (``experiments/configs/*.toml``, package data), by name.

A bundled config is named by its file name without ``.toml`` (``"quickstart"``, ``"003_fig5_fig6"``).
The files are found with :mod:`importlib.resources`, so that they are found in an installed wheel as
well as in a source checkout.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path

from experiments.config import ConfigError, read_config_text, shorten

__all__ = ["BundledConfig", "bundled_configs", "bundled_config_path", "is_bundled_name"]

#: the package folder holding the bundled configs
_PACKAGE = "experiments"
_FOLDER = "configs"


@dataclass(frozen=True)
class BundledConfig:
    """One bundled config.

    Attributes
    ----------
    name : str
        The file name without ``.toml``: what :func:`coobs.run` accepts.
    title : str
        The config's ``title`` when it has one, else its first comment line.
    kind : str
        Its scenario kind (``formation``, ``tof_000`` ...).
    has_sweep : bool
        Whether it holds a ``[sweep]`` table (``coobs sweep`` can run it).
    path : Path
        The file.
    """

    name: str
    title: str
    kind: str
    has_sweep: bool
    path: Path


def _folder() -> Path:
    root = files(_PACKAGE) / _FOLDER
    if not isinstance(root, Path):  # setuptools installs packages as folders, never zipped
        raise ConfigError(f"config: the bundled configs are not in a folder ({shorten(str(root))})")
    return root


def _first_comment(text: str) -> str:
    for line in text.splitlines():
        stripped = line.strip()
        if stripped.startswith("#"):
            return stripped.lstrip("#").strip()
        if stripped:
            break
    return ""


def _describe(path: Path) -> BundledConfig:
    text = read_config_text(path)
    table = tomllib.loads(text)
    title = table.get("title") if isinstance(table.get("title"), str) and table.get("title") else _first_comment(text)
    return BundledConfig(name=path.stem, title=title, kind=str(table.get("kind", "")),
                         has_sweep=isinstance(table.get("sweep"), dict), path=path)


def bundled_configs() -> dict[str, BundledConfig]:
    """Every bundled config, by name, in name order.

    Returns
    -------
    dict of str to BundledConfig
        Name → its description and file.
    """
    return {p.stem: _describe(p) for p in sorted(_folder().glob("*.toml"))}


def is_bundled_name(name: str) -> bool:
    """Whether ``name`` (or ``name`` without a trailing ``.toml``) is a bundled config's name."""
    if not isinstance(name, str) or "/" in name or "\\" in name:
        return False
    stem = name[:-5] if name.endswith(".toml") else name
    return bool(stem) and (_folder() / f"{stem}.toml").is_file()


def bundled_config_path(name: str) -> Path:
    """The file of a bundled config.

    Parameters
    ----------
    name : str
        A bundled config's name (``"quickstart"``; ``"quickstart.toml"`` is accepted too).

    Returns
    -------
    Path
        The TOML file.

    Raises
    ------
    ConfigError
        No bundled config has that name (the message lists the names).
    """
    if not is_bundled_name(name):
        known = ", ".join(p.stem for p in sorted(_folder().glob("*.toml")))
        raise ConfigError(f"config: no file and no bundled config named {shorten(name)}; bundled: {known}")
    stem = name[:-5] if name.endswith(".toml") else name
    return _folder() / f"{stem}.toml"
