"""Results as tables with units: the unit of a summary key read from its name (``_deg``, ``_m_s`` …)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from rich.console import Console
from rich.table import Table
from rich.text import Text

__all__ = ["UNITS", "split_unit", "format_value", "summary_rows", "summary_table", "print_table"]

#: unit token(s) of a key, as its last ``_``-separated parts → the unit shown (longest first)
UNITS: tuple[tuple[tuple[str, ...], str], ...] = (
    (("deg", "s"), "deg/s"), (("rad", "s"), "rad/s"), (("m", "s"), "m/s"), (("mm", "s"), "mm/s"),
    (("kg", "m2"), "kg·m²"), (("kgm2",), "kg·m²"),
    (("deg",), "deg"), (("rad",), "rad"), (("urad",), "µrad"), (("mrad",), "mrad"), (("arcsec",), "arcsec"),
    (("km",), "km"), (("m",), "m"), (("mm",), "mm"), (("um",), "µm"),
    (("s",), "s"), (("ms",), "ms"), (("us",), "µs"),
    (("px",), "px"), (("pct",), "%"), (("percent",), "%"), (("hz",), "Hz"), (("mb",), "MB"), (("mib",), "MiB"),
    (("kg",), "kg"),
)

#: width of the tables written to a file or a pipe (a terminal's own width is used), characters
PIPE_WIDTH = 120


def split_unit(key: str) -> tuple[str, str]:
    """A summary key without its unit, and the unit: ``"final_rms_rate_error_deg_s"`` →
    ``("final_rms_rate_error", "deg/s")``.

    The unit is the last run of ``_``-separated parts that names one (so ``rms_attitude_error_deg_plane``
    → ``("rms_attitude_error_plane", "deg")``); a key's first part is never a unit (``n_failed``,
    ``m_ratio``), and a key without one gives ``(key, "")``.
    """
    parts = key.split("_")
    for end in range(len(parts), 1, -1):
        for tokens, unit in UNITS:
            start = end - len(tokens)
            if start >= 1 and tuple(p.lower() for p in parts[start:end]) == tokens:
                return "_".join(parts[:start] + parts[end:]), unit
    return key, ""


def format_value(v: Any) -> str:
    """A summary value as text: floats to 6 significant digits, ``None`` and NaN as ``-``, lists joined."""
    if v is None:
        return "-"
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, float):
        return "-" if math.isnan(v) else f"{v:.6g}"
    if isinstance(v, list | tuple):
        return ", ".join(format_value(x) for x in v) if v else "(none)"
    if isinstance(v, Mapping) and not v:
        return "(none)"
    try:  # numpy scalars
        return format_value(v.item())
    except AttributeError:
        return str(v)


def _leaf(v: Any) -> bool:
    """Whether ``v`` is one row: a value, an empty table or a list of values."""
    if isinstance(v, Mapping):
        return not v
    if isinstance(v, list | tuple):
        return all(not isinstance(x, Mapping | list | tuple) for x in v)
    return True


def summary_rows(summary: Mapping[str, Any]) -> list[tuple[str, str, str]]:
    """Every entry of a summary as ``(quantity, value, unit)`` rows, nested tables flattened.

    A nested entry's quantity is its path joined with `` / `` (``solvers / switching / along_los / rms``);
    its unit comes from the innermost part of the path that names one (``along_los_m`` → m).  Lists of
    numbers stay on one row; lists of tables get ``[i]`` in the path.
    """
    rows: list[tuple[str, str, str]] = []

    def walk(value: Any, path: list[str], unit: str) -> None:
        if _leaf(value):
            rows.append((" / ".join(path), format_value(value), unit))
            return
        items = value.items() if isinstance(value, Mapping) else ((f"[{i}]", x) for i, x in enumerate(value))
        for key, sub in items:
            name, own = split_unit(str(key))
            walk(sub, [*path, name], own or unit)

    for key, value in summary.items():
        name, unit = split_unit(str(key))
        walk(value, [name], unit)
    return rows


def summary_table(summary: Mapping[str, Any], title: str | None = None) -> Table:
    """A rich table of :func:`summary_rows`: quantity, value, unit; long cells fold, never cut."""
    table = Table(title=Text(title) if title else None, title_justify="left")
    table.add_column("quantity", overflow="fold")
    table.add_column("value", justify="right", overflow="fold")
    table.add_column("unit", overflow="fold")
    for row in summary_rows(summary):
        table.add_row(*(Text(cell) for cell in row))  # as text: a "[...]" in a value is no markup
    return table


def print_table(console: Console, table: Table) -> None:
    """Print ``table`` as wide as the terminal (its cells fold, nothing is cut), or :data:`PIPE_WIDTH`
    characters wide into a file or a pipe."""
    width = console.width if console.is_terminal else max(console.width, PIPE_WIDTH)
    Console(width=width, file=console.file, highlight=False).print(table)
