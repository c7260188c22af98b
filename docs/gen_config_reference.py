"""The config reference page, generated from the pydantic models of the scenario kinds.

Every kind of :data:`experiments.config.KINDS` names its ``Config`` model; this module walks each
model's ``model_fields`` (nested tables, arrays of tables and free-key tables recursively) and
reads, for every key, its type, unit, default, the range of its field constraints (``gt``, ``ge``,
``lt``, ``le``, lengths, ``Literal`` choices) and its description.  Nothing is written by hand: a
key, a bound or a description added to a model appears on the next build.  The shared value types
(``Length_m``, ``Angle_deg``, ...) are listed once with the description of their ``#:`` comment in
:mod:`experiments.config`, read by griffe
(with the griffe-sphinx extension, which reads ``#:`` comments).
"""

from __future__ import annotations

import importlib
import json
import types
import typing
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import annotated_types as at
import griffe
import pydantic
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

__all__ = ["KeyRow", "value_types", "reference_rows", "config_reference", "FREE_KEY"]

#: the placeholder of a key chosen by the user (a ``sweep.grid`` key, a window name)
FREE_KEY = "<key>"

#: units by key suffix (the house rule: units are in the key names), longest suffix first
_SUFFIX_UNITS = (("_kg_m2", "kg m²"), ("_deg_s", "deg/s"), ("_rad_s", "rad/s"), ("_mm_s", "mm/s"),
                 ("_m_s", "m/s"), ("_deg", "deg"), ("_rad", "rad"), ("_px", "px"), ("_mm", "mm"),
                 ("_km", "km"), ("_m", "m"), ("_s", "s"), ("_dn", "DN"), ("_hz", "Hz"))


@dataclass(frozen=True)
class KeyRow:
    """One key of a scenario kind's config."""

    key: str
    type: str
    unit: str
    default: str
    range: str
    description: str
    table: bool = False  # a table of named keys (a sub-model)
    free: bool = False   # a table whose keys the user names (dict)


def _value_type_aliases() -> dict[str, object]:
    """The shared value types of :mod:`experiments.config`: name → ``Annotated`` alias."""
    cfg = importlib.import_module("experiments.config")
    return {name: getattr(cfg, name) for name in cfg.__all__
            if typing.get_origin(getattr(cfg, name)) is typing.Annotated}


def value_types(root: Path | str = ".") -> list[tuple[str, str]]:
    """``(name, description)`` of every shared value type, descriptions from their ``#:`` comments."""
    loader = griffe.GriffeLoader(search_paths=[str(root)], extensions=griffe.load_extensions("griffe_sphinx"))
    module = loader.load("experiments.config")
    rows = []
    for name in _value_type_aliases():
        member = module.members.get(name)
        doc = member.docstring.value.strip() if member is not None and member.docstring else ""
        rows.append((name, " ".join(doc.split())))
    return rows


def _alias_of(metadata: list, aliases: dict[str, object]) -> str | None:
    """The value type whose validators all occur in ``metadata`` (pydantic copies them into the field's
    metadata: equal, the same functions); the most specific one."""
    best, size = None, 0
    for name, alias in aliases.items():
        own = [c for m in alias.__metadata__ for c in (m.metadata if isinstance(m, FieldInfo) else [m])]
        if own and all(m in metadata for m in own) and len(own) > size:
            best, size = name, len(own)
    return best


def _describe(tp: object, aliases: dict[str, object]) -> str:
    """A readable type: value-type names, ``list of``, ``one of "a", "b"``."""
    if tp is type(None):
        return "none"
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin is typing.Annotated:
        name = _alias_of(list(tp.__metadata__), aliases)
        return name if name is not None else _describe(args[0], aliases)
    if origin is typing.Literal:
        return "one of " + ", ".join(json.dumps(a) for a in args)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_describe(a, aliases) for a in args if a is not type(None))
    if origin in (list, tuple):
        items = [a for a in args if a is not Ellipsis]
        if origin is tuple and len(items) > 1:
            return "[" + ", ".join(_describe(a, aliases) for a in items) + "]"
        item = _describe(items[0], aliases) if items else "values"
        return "list of " + (f"({item})" if " or " in item else item)
    if origin is dict:
        return f"table of {FREE_KEY} → {_describe(args[1], aliases)}"
    if isinstance(tp, type) and issubclass(tp, pydantic.BaseModel):
        return "table"
    return getattr(tp, "__name__", str(tp))


def _bounds(metadata: list) -> str:
    parts = []
    for m in metadata:
        for cls, op in ((at.Gt, ">"), (at.Ge, "≥"), (at.Lt, "<"), (at.Le, "≤")):
            if isinstance(m, cls):
                bound = getattr(m, cls.__name__.lower())
                parts.append(f"{op} {bound:.15g}" if isinstance(bound, float) else f"{op} {bound}")
        if isinstance(m, at.MinLen):
            parts.append(f"length ≥ {m.min_length}")
        if isinstance(m, at.MaxLen):
            parts.append(f"length ≤ {m.max_length}")
    return ", ".join(parts)


def _field_range(info: FieldInfo) -> str:
    """Bounds of the field itself, and of the items of a list field (their ``Annotated`` metadata)."""
    text = _bounds(list(info.metadata))
    args = typing.get_args(info.annotation)
    if typing.get_origin(info.annotation) in (list, tuple) and args:
        inner = [a for a in args if typing.get_origin(a) is typing.Annotated]
        item = _bounds(list(inner[0].__metadata__)) if inner else ""
        text = ", ".join(p for p in (text, f"each item {item}" if item else "") if p)
    return text


def _unit(key: str, type_name: str) -> str:
    name = key.rsplit(".", 1)[-1]
    for source in (name, type_name.split(" ")[-1]):
        for suffix, unit in _SUFFIX_UNITS:
            if source.endswith(suffix) or source.endswith(suffix.upper()):
                return unit
    return ""


def _default(info: FieldInfo) -> str:
    if info.default_factory is not None:
        value = info.default_factory()
    elif info.default is PydanticUndefined:
        return "required"
    else:
        value = info.default
    if value is None:
        return "absent"
    if isinstance(value, pydantic.BaseModel):
        return "table"
    if isinstance(value, bool):
        return str(value).lower()
    return json.dumps(value, ensure_ascii=False, default=str)


def _models_in(tp: object) -> list[tuple[type[pydantic.BaseModel], str]]:
    """Sub-models of an annotation: ``(model, how)`` with how ``""`` (table), ``"[]"`` (array of tables)
    or ``"dict"`` (free-key table)."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if isinstance(tp, type) and issubclass(tp, pydantic.BaseModel):
        return [(tp, "")]
    if origin in (typing.Union, types.UnionType):
        return [m for a in args for m in _models_in(a)]
    if origin is list and args:
        return [(m, "[]" if how == "" else how) for m, how in _models_in(args[0])]
    if origin is dict:
        return [(m, "dict") for a in typing.get_args(args[1]) or (args[1],) for m, _ in _models_in(a)]
    return []


def _walk(model: type[pydantic.BaseModel], prefix: str, aliases: dict[str, object]) -> Iterator[KeyRow]:
    for name, info in model.model_fields.items():
        key = f"{prefix}{name}"
        type_name = _alias_of(list(info.metadata), aliases) or _describe(info.annotation, aliases)
        subs = _models_in(info.annotation)
        free = typing.get_origin(info.annotation) is dict
        description = " ".join((info.description or "").split())
        if not description and subs and not free:
            description = " ".join((subs[0][0].__doc__ or "").split("\n\n")[0].split())
        yield KeyRow(key, type_name, "" if subs else _unit(key, type_name), _default(info),
                     _field_range(info), description, table=bool(subs) and not free, free=free)
        if free:
            entry = _describe(typing.get_args(info.annotation)[1], aliases)
            yield KeyRow(f"{key}.{FREE_KEY}", entry, _unit(key, type_name), "", "",
                         f"an entry of `{key}`" + (": a list of values, or a table" if subs else ""),
                         table=bool(subs))
        for sub, how in subs:
            inner = {"": f"{key}.", "[]": f"{key}[].", "dict": f"{key}.{FREE_KEY}."}[how]
            yield from _walk(sub, inner, aliases)


def reference_rows() -> dict[str, list[KeyRow]]:
    """Every key of every scenario kind: kind → rows, in the order of the models' fields.

    A table key is followed by its own keys; an array of tables ``spacecraft`` by ``spacecraft[].name``...;
    a table whose keys the user names (``sweep.grid``) by ``sweep.grid.<key>``.
    """
    from experiments.config import KINDS, kind_module

    aliases = _value_type_aliases()
    return {kind: list(_walk(kind_module(kind).Config, "", aliases)) for kind in KINDS}


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def config_reference(root: Path | str = ".") -> str:
    """The config reference page as Markdown."""
    rows = reference_rows()
    lines = ["# Config reference", "",
             "Every key of every scenario kind, generated at build time from the pydantic models that "
             "validate the config files (`experiments.config.KINDS` → each kind's `Config`). A config "
             "file names its kind at the top (`kind = \"formation\"`); a key not listed here is an error, "
             "and so is a value outside its range. *Range* gives the bounds the model declares on the key "
             "(`≥`, `<`, lengths); the value type adds its own physical bound (table below), and some keys "
             "carry further checks across keys that are stated in the error message. Units are in the key "
             "names. `[]` marks an array of tables (`[[spacecraft]]`), and `<key>` a key the user names.",
             "", "Kinds: " + ", ".join(f"[`{k}`](#{k})" for k in rows) + ".", "",
             "## Value types", "",
             "| type | what it accepts |", "|---|---|"]
    lines += [f"| `{name}` | {_cell(doc)} |" for name, doc in value_types(root)]
    for kind, kind_rows in rows.items():
        lines += ["", f"## {kind}", "", f"`kind = \"{kind}\"`: {_cell(_kind_summary(kind))}", "",
                  "| key | type | unit | default | range | description |", "|---|---|---|---|---|---|"]
        for r in kind_rows:
            key = f"**`{r.key}`**" if r.table or r.free else f"`{r.key}`"
            lines.append(f"| {key} | {_cell(r.type)} | {r.unit} | {_cell(r.default)} | {_cell(r.range)} | "
                         f"{_cell(r.description)} |")
    return "\n".join(lines) + "\n"


def _kind_summary(kind: str) -> str:
    from experiments.config import kind_module

    doc = kind_module(kind).Config.__doc__ or ""
    return " ".join(doc.split("\n\n")[0].split())
