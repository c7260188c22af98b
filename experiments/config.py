"""Scenario configs: the frozen pydantic base every kind's ``Config`` subclasses, the kinds, and loading.

Every config file names its scenario kind at the top level (``kind = "tof_000"``); :data:`KINDS`
maps it to the module that implements it (the kind protocol is described in
:mod:`experiments.scenarios`), and the rest of the file is validated by that kind's model before any
work starts.  Bad configs raise :class:`ConfigError` with one line naming the key.
"""

from __future__ import annotations

import copy
import importlib
import json
import numbers
import re
import tomllib
from collections.abc import Iterable, Mapping
from pathlib import Path
from types import ModuleType
from typing import Annotated, Any

import pydantic
from pydantic import AfterValidator, AllowInfNan, BaseModel, BeforeValidator, ConfigDict, StrictBool

__all__ = [
    "KINDS",
    "kind_module",
    "ConfigError",
    "ConfigTable",
    "ScenarioConfig",
    "format_validation_error",
    "read_config_text",
    "read_config",
    "load_config",
    "load_cell_configs",
    "set_dotted",
    "shorten",
    "one_line",
    "key_part",
    "FiniteFloat",
    "Integer",
    "Seed",
    "Flag",
    "Length_m",
    "Length_km",
    "Length_mm",
    "Speed_m_s",
    "Speed_mm_s",
    "Rate_deg_s",
    "Angle_deg",
    "Duration_s",
    "Inertia_kg_m2",
    "MAX_FILE_BYTES",
    "MAX_DEPTH",
    "MAX_LIST_ITEMS",
    "MAX_STRING_CHARS",
    "MAX_KEY_CHARS",
    "SHOWN_CHARS",
    "MAX_MESSAGE_CHARS",
]

#: largest config file read, bytes (the shipped configs are a few kB)
MAX_FILE_BYTES = 1 << 20
#: deepest nesting of tables and arrays in a config (the shipped ones reach 4)
MAX_DEPTH = 16
#: longest array in a config
MAX_LIST_ITEMS = 100_000
#: longest string value in a config, characters
MAX_STRING_CHARS = 4096
#: longest key in a config, characters
MAX_KEY_CHARS = 256
#: characters of a bad value shown in an error message
SHOWN_CHARS = 60
#: longest error message, characters
MAX_MESSAGE_CHARS = 300


def shorten(value: Any, limit: int = SHOWN_CHARS) -> str:
    """``repr(value)`` cut to ``limit`` characters (``...`` marks a cut); safe on any value."""
    if isinstance(value, str) and len(value) > 4 * limit:
        value = value[:4 * limit]  # never repr a 10 MB string just to cut it
    elif isinstance(value, list | tuple) and len(value) > limit:
        value = type(value)(value[:limit])
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 - any object may end up in a message; its type name is enough
        text = f"<{type(value).__name__}>"
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _cut(text: str, limit: int = 2 * SHOWN_CHARS) -> str:
    return text if len(text) <= limit else text[:limit - 3] + "..."


def one_line(message: str, limit: int = MAX_MESSAGE_CHARS) -> str:
    """``message`` on one line (runs of white space become one space), cut to ``limit`` characters."""
    text = " ".join(message[:4 * limit].split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


# --- value types shared by every scenario kind's config ------------------------------------------

def _real_number(v: Any) -> Any:
    if isinstance(v, bool) or not isinstance(v, numbers.Real):
        raise ValueError(f"must be a number, not {type(v).__name__}")
    if isinstance(v, numbers.Integral) and abs(int(v)) > 1e308:
        raise ValueError("must be a finite number")
    return v


def _integer(v: Any) -> Any:
    if isinstance(v, bool) or not isinstance(v, numbers.Real):
        raise ValueError(f"must be an integer, not {type(v).__name__}")
    return v


def _magnitude(limit: float, unit: str) -> AfterValidator:
    def check(v: float) -> float:
        if abs(v) > limit:
            raise ValueError(f"must lie within ±{limit:g} {unit}")
        return v

    return AfterValidator(check)


#: a finite number (bool and text refused; NaN and ±inf refused)
FiniteFloat = Annotated[float, BeforeValidator(_real_number), AllowInfNan(False)]
#: an integer (bool and text refused; an integral float such as a grid range value is accepted)
Integer = Annotated[int, BeforeValidator(_integer)]
#: a seed of the random streams: an integer in [0, 2**63 - 1]
Seed = Annotated[int, BeforeValidator(_integer), pydantic.Field(ge=0, le=2**63 - 1)]
#: true or false (0, 1 and text refused)
Flag = StrictBool
#: a length or coordinate, m: finite, within ±1e8 m (a quarter of the way to the Moon)
Length_m = Annotated[FiniteFloat, _magnitude(1e8, "m")]
#: a length, km: finite, within ±1e5 km (the 1e8 m of :data:`Length_m`)
Length_km = Annotated[FiniteFloat, _magnitude(1e5, "km")]
#: a length or coordinate, mm: finite, within ±1e11 mm (the 1e8 m of :data:`Length_m`)
Length_mm = Annotated[FiniteFloat, _magnitude(1e11, "mm")]
#: a speed or velocity component, m/s: finite, within ±1e4 m/s (above any orbital speed about the Earth)
Speed_m_s = Annotated[FiniteFloat, _magnitude(1e4, "m/s")]
#: a speed or velocity component, mm/s: finite, within ±1e7 mm/s (the 1e4 m/s of :data:`Speed_m_s`)
Speed_mm_s = Annotated[FiniteFloat, _magnitude(1e7, "mm/s")]
#: an angular rate, deg/s: finite, within ±1e3 deg/s (about 2.8 turns per second)
Rate_deg_s = Annotated[FiniteFloat, _magnitude(1e3, "deg/s")]
#: an angle, deg: finite, within ±360 deg
Angle_deg = Annotated[FiniteFloat, _magnitude(360.0, "deg")]
#: a duration or time, s: finite, within ±1e7 s (about 116 days)
Duration_s = Annotated[FiniteFloat, _magnitude(1e7, "s")]
#: a moment of inertia, kg m^2: finite, within ±1e12 kg m^2 (the ISS has about 1e8)
Inertia_kg_m2 = Annotated[FiniteFloat, _magnitude(1e12, "kg m^2")]


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
    if not isinstance(kind, str):
        raise ConfigError(f"kind: must be a string naming a scenario kind ({', '.join(sorted(KINDS))}), "
                          f"got {shorten(kind)}")
    if kind not in KINDS:
        raise ConfigError(f"kind: unknown scenario kind {shorten(kind)}; known: {', '.join(sorted(KINDS))}")
    return importlib.import_module(KINDS[kind])


class ConfigTable(BaseModel):
    """A table of a scenario config: frozen, unknown keys are errors, NaN and ±inf are refused.

    Change a validated config with ``cfg.model_copy(update={...})``, never by assignment.  Fields use
    the value types of this module (:data:`FiniteFloat`, :data:`Length_m`, :data:`Integer`, ...),
    so that every number is finite and inside a physical range with its unit.
    """

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


class ScenarioConfig(ConfigTable):
    """The whole config file of one scenario kind; every kind's ``Config`` subclasses it.

    Attributes
    ----------
    kind : str
        The scenario kind (a key of :data:`KINDS`); subclasses narrow it to
        ``Literal["<their kind>"]``.
    """

    kind: str

    def check_swept_values(self, table: str = "sweep") -> None:
        """Each value of the ``table`` grid must give a valid config on its own.

        Combinations are checked by the sweep (:func:`load_cell_configs`); this catches a bad value
        at validation, naming it.  Call it from a kind's ``model_validator(mode="after")``.

        Raises
        ------
        ValueError
            ``sweep.grid: <key> = <value>: <why>`` (one line), or ``sweep.grid: '<key>' is not a
            config key``.
        """
        spec = getattr(self, table, None)
        if spec is None:
            return
        base = self.model_dump(exclude={table})
        for key, values in spec.grid_values().items():
            *parents, leaf = key.split(".")
            for value in values:
                raw = copy.deepcopy(base)
                node: Any = raw
                for part in parents:
                    node = node.get(part) if isinstance(node, dict) else None
                if not isinstance(node, dict) or leaf not in node:
                    raise ValueError(f"{table}.grid: {key!r} is not a config key")
                node[leaf] = value
                try:
                    type(self).model_validate(raw)
                except pydantic.ValidationError as exc:
                    msg = str(exc.errors(include_url=False)[0]["msg"]).removeprefix("Value error, ")
                    raise ValueError(one_line(f"{table}.grid: {key} = {shorten(value)}: {msg}")) from None


_KEY_AT_START = re.compile(r"([A-Za-z_]\w*(?:\.\w+)*): (.*)", re.DOTALL)
_PREFIXES = ("Value error, ", "Assertion failed, ")


def format_validation_error(err: pydantic.ValidationError) -> str:
    """One line naming the first bad key of a pydantic ``ValidationError``: ``"a.b: message (got value)"``.

    A model-level validator names its key by starting its message with it (``"min_active: ..."``);
    that key is appended to the location.  Keys and values are cut to :data:`SHOWN_CHARS`
    characters, the line to :data:`MAX_MESSAGE_CHARS`.
    """
    first = err.errors(include_url=False)[0]
    loc = [key_part(p) for p in first["loc"]]
    msg = str(first["msg"])
    for prefix in _PREFIXES:
        if msg.startswith(prefix):
            msg = msg[len(prefix):]
    value = first.get("input")
    if first["type"] == "extra_forbidden":
        msg = "unknown key"
    m = _KEY_AT_START.match(msg)
    if m is not None and isinstance(value, Mapping):
        loc.append(m.group(1))
        msg = m.group(2)
    key = ".".join(loc) or "config"
    shown = "" if first["type"] in ("missing", "extra_forbidden") or isinstance(value, Mapping) else shorten(value)
    shown = f" (got {shown})" if shown and shown not in msg else ""
    return one_line(f"{key}: {msg}{shown}")


def read_config_text(path: Path | str) -> str:
    """The text of a config file: at most :data:`MAX_FILE_BYTES`, UTF-8.

    Raises
    ------
    ConfigError
        The file is missing, unreadable, too large or not UTF-8 text.
    """
    shown = shorten(str(path))
    try:
        p = Path(path)
        if not p.is_file():
            raise ConfigError(f"config: file not found: {shown}")
        with p.open("rb") as f:
            data = f.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise ConfigError(f"config: cannot read {shown} ({exc.strerror or type(exc).__name__})") from None
    if len(data) > MAX_FILE_BYTES:
        raise ConfigError(f"config: {shown} is larger than {MAX_FILE_BYTES} bytes")
    try:
        # universal newlines, as Path.read_text gives them
        return data.decode("utf-8").replace("\r\n", "\n").replace("\r", "\n")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"config: {shown} is not UTF-8 text (byte {exc.object[exc.start]:#04x} at "
                          f"offset {exc.start})") from None


_PLAIN_KEY = re.compile(r"[\w-]+")


def key_part(part: Any) -> str:
    """One part of a dotted key as shown in messages: bare when plain (``distance_m``, ``0``), else quoted
    (``"3 views"``) and cut to :data:`SHOWN_CHARS` characters."""
    text = str(part)
    if isinstance(part, int) or (len(text) <= SHOWN_CHARS and _PLAIN_KEY.fullmatch(text)):
        return text
    return json.dumps(text if len(text) <= SHOWN_CHARS else text[:SHOWN_CHARS - 3] + "...", ensure_ascii=False)


def _check_shape(value: Any, where: str = "") -> None:
    """Refuse tables and arrays nested deeper than :data:`MAX_DEPTH`, long arrays, strings and keys.

    Iterative (no recursion), so that any nesting depth gives a :class:`ConfigError`.
    """
    stack: list[tuple[Any, str, int]] = [(value, where, 0)]
    while stack:
        node, at, depth = stack.pop()
        name = _cut(at or "config")
        if isinstance(node, Mapping | list | tuple) and depth >= MAX_DEPTH:
            raise ConfigError(f"{name}: tables and arrays nested deeper than "
                              f"{MAX_DEPTH} levels")
        if isinstance(node, Mapping):
            for k, v in node.items():
                if not isinstance(k, str):
                    raise ConfigError(f"{name}: keys must be strings, got {shorten(k)}")
                if len(k) > MAX_KEY_CHARS:
                    raise ConfigError(f"{name}: key {shorten(k)} is longer than {MAX_KEY_CHARS} characters")
                stack.append((v, f"{at}.{key_part(k)}" if at else key_part(k), depth + 1))
        elif isinstance(node, list | tuple):
            if len(node) > MAX_LIST_ITEMS:
                raise ConfigError(f"{name}: {len(node)} items, at most {MAX_LIST_ITEMS}")
            stack.extend((v, f"{at}[{i}]", depth + 1) for i, v in enumerate(node))
        elif isinstance(node, str) and len(node) > MAX_STRING_CHARS:
            raise ConfigError(f"{name}: string of {len(node)} characters, "
                              f"at most {MAX_STRING_CHARS} (got {shorten(node)})")


def set_dotted(raw: dict[str, Any], dotted: str, value: Any) -> None:
    """Set ``raw[a][b][c] = value`` for ``dotted = "a.b.c"``, creating missing tables.

    Raises
    ------
    ConfigError
        ``dotted`` is not a dotted key, or one of its parts names a value instead of a table.
    """
    if not isinstance(dotted, str) or not dotted or len(dotted) > MAX_KEY_CHARS:
        raise ConfigError(f"config: {shorten(dotted)} is not a dotted key (a.b.c, at most {MAX_KEY_CHARS} "
                          "characters)")
    parts = dotted.split(".")
    if any(not p.strip() for p in parts):
        raise ConfigError(f"{_cut(dotted)}: not a dotted key (an empty part)")
    node = raw
    for i, p in enumerate(parts[:-1]):
        child = node.get(p)
        if child is None:
            child = node[p] = {}
        elif not isinstance(child, dict):
            raise ConfigError(f"{_cut(dotted)}: {_cut('.'.join(parts[:i + 1]))} is a value, "
                              f"not a table (got {shorten(child)})")
        node = child
    node[parts[-1]] = value


def read_config(source: Path | str | Mapping[str, Any],
                overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The raw table of a config, with dotted-key overrides applied; nothing validated yet.

    Parameters
    ----------
    source : path or mapping
        A TOML file (UTF-8, at most :data:`MAX_FILE_BYTES`), or the already parsed table (copied,
        never changed).
    overrides : mapping, optional
        Dotted key (``"formation.distance_m"``) → value, set in the table (missing tables are created).

    Returns
    -------
    dict
        The table.

    Raises
    ------
    ConfigError
        The file is missing, unreadable, not UTF-8 or not valid TOML; tables or arrays nest deeper
        than :data:`MAX_DEPTH`; an array, string or key is too long; an override names a value as a
        table.
    """
    if isinstance(source, Mapping):
        _check_shape(source)
        raw = copy.deepcopy(dict(source))
    else:
        text = read_config_text(source)
        try:
            raw = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"config: not valid TOML ({exc})") from None
        except RecursionError:
            raise ConfigError(f"config: tables and arrays nested deeper than {MAX_DEPTH} levels") from None
        _check_shape(raw)
    for dotted, value in (overrides or {}).items():
        _check_shape(value, str(dotted))
        set_dotted(raw, dotted, copy.deepcopy(value))
    return raw


def _validate(module: ModuleType, raw: Mapping[str, Any]) -> ScenarioConfig:
    try:
        return module.Config.model_validate(raw)
    except pydantic.ValidationError as exc:
        raise ConfigError(format_validation_error(exc)) from None


def load_config(source: Path | str | Mapping[str, Any],
                overrides: Mapping[str, Any] | None = None) -> tuple[ModuleType, ScenarioConfig]:
    """Read and validate a scenario config; returns ``(kind module, cfg)``.

    Parameters
    ----------
    source : path or mapping
        A TOML file or its parsed table; its top-level ``kind`` (a string) selects the scenario kind.
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
        One line of at most :data:`MAX_MESSAGE_CHARS` characters naming the key, when anything is wrong.
    """
    raw = read_config(source, overrides)
    if "kind" not in raw:
        raise ConfigError(f"kind: missing (one of {', '.join(sorted(KINDS))})")
    module = kind_module(raw["kind"])
    return module, _validate(module, raw)


def load_cell_configs(source: Path | str | Mapping[str, Any], overrides: Mapping[str, Any] | None,
                      cells: Iterable[Mapping[str, Any]], *, table: str = "sweep") -> list[ScenarioConfig]:
    """The validated config of every cell of a sweep: the config with ``overrides``, then the cell's keys.

    The ``table`` describing the sweep is validated once, by :func:`load_config`, and attached to
    every cell's config unchanged, so that the cost is linear in the number of cells.

    Parameters
    ----------
    source : path or mapping
        The sweep's config (see :func:`load_config`).
    overrides : mapping or None
        Dotted key → value applied to every cell (``coobs sweep --set``).
    cells : iterable of mapping
        Each cell's dotted key → value.
    table : str
        The top-level key of the sweep table.

    Returns
    -------
    list of ScenarioConfig
        One config per cell, in the order of ``cells``.

    Raises
    ------
    ConfigError
        One line naming the key, for the first cell whose config is not valid.
    """
    module, cfg = load_config(source, overrides)
    raw = read_config(source, overrides)
    raw.pop(table, None)
    spec = getattr(cfg, table, None)
    out = []
    for params in cells:
        cell_raw = copy.deepcopy(raw)
        for dotted, value in params.items():
            _check_shape(value, str(dotted))
            set_dotted(cell_raw, dotted, value)
        cell_cfg = _validate(module, cell_raw)
        out.append(cell_cfg.model_copy(update={table: spec}) if table in type(cfg).model_fields else cell_cfg)
    return out
