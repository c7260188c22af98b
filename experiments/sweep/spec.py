"""What a sweep sweeps: the ``[sweep]`` table of a config, grid ranges, ``--set`` overrides, grid cells.

The grid is the Cartesian product of the values given for some dotted config keys (e.g.
``formation.distance_m``), in the order they are given; each swept key becomes a dataset coordinate
named after its last part (the full key in ``attrs["config_key"]``).
"""

from __future__ import annotations

import itertools
import json
import math
import re
import tomllib
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

import numpy as np
import pydantic

from experiments.config import FiniteFloat, Integer, Seed, shorten

__all__ = ["GridRange", "SweepSpec", "parse_overrides", "coord_names", "grid_arrays", "grid_cells", "params_key",
           "MAX_CELLS", "MAX_RANGE_VALUES", "MAX_GRID_KEYS"]

#: default largest grid, cells (``sweep.max_cells`` raises it)
MAX_CELLS = 10_000
#: most values a ``{start, stop, step}`` range may give
MAX_RANGE_VALUES = 1_000_000
#: most swept keys
MAX_GRID_KEYS = 16
_DOTTED_KEY = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*")


def coord_names(keys: Sequence[str]) -> list[str]:
    """Dataset coordinate names of the swept dotted keys (their last parts); ``ValueError`` unless unique."""
    names = [k.split(".")[-1] for k in keys]
    for n, k in zip(names, keys, strict=True):
        if not n.isidentifier():
            raise ValueError(f"grid: key {k!r} does not end in a valid name")
        if n == "trial" or names.count(n) > 1:
            raise ValueError(f"grid: key {k!r} gives coordinate name {n!r}, which is not unique")
    return names


def grid_arrays(grid: Mapping[str, Sequence[Any]]) -> dict[str, np.ndarray]:
    """The grid as 1-D arrays; ``ValueError`` for an empty grid, a non-scalar or repeated value."""
    if not grid:
        raise ValueError("grid: at least one swept key is required")
    out = {}
    for key, values in grid.items():
        arr = np.asarray(list(values))
        if arr.ndim != 1 or arr.size == 0:
            raise ValueError(f"grid.{key}: expected a non-empty list of scalar values, got {values!r}")
        if len(set(arr.tolist())) != arr.size:
            raise ValueError(f"grid.{key}: values are not distinct: {arr.tolist()!r}")
        out[key] = arr
    return out


def grid_cells(grid: Mapping[str, np.ndarray]) -> Iterator[tuple[tuple[int, ...], dict[str, Any]]]:
    """Every cell of the grid, in C order: ``(index tuple, {dotted key: Python scalar})``."""
    keys = list(grid)
    for idx in itertools.product(*(range(len(grid[k])) for k in keys)):
        yield idx, {k: grid[k][i].item() for k, i in zip(keys, idx, strict=True)}


def params_key(params: Mapping[str, Any]) -> str:
    """A canonical text of a cell's parameters (sorted keys, ``repr`` values): hashed for its seeds."""
    return json.dumps(sorted((k, repr(v)) for k, v in params.items()))


class GridRange(pydantic.BaseModel):
    """Inclusive arithmetic range ``{start = 30, stop = 100, step = 5}`` (or ``num`` points).

    The number of values is computed arithmetically and bounded by :data:`MAX_RANGE_VALUES` before
    any of them is made.
    """

    model_config = pydantic.ConfigDict(extra="forbid", allow_inf_nan=False)
    start: FiniteFloat
    stop: FiniteFloat
    step: FiniteFloat | None = None
    num: Integer | None = pydantic.Field(default=None, ge=1, le=MAX_RANGE_VALUES)

    @pydantic.model_validator(mode="after")
    def _one_of(self) -> GridRange:
        if (self.step is None) == (self.num is None):
            raise ValueError("step: give exactly one of step or num")
        if self.step is not None:
            if self.step <= 0 or self.stop < self.start:
                raise ValueError(f"step: needs step > 0 and stop >= start (got start={self.start:g}, "
                                 f"stop={self.stop:g}, step={self.step:g})")
            q = (self.stop - self.start) / self.step
            if not math.isfinite(q) or q >= MAX_RANGE_VALUES:
                raise ValueError(f"step: {self.step:g} from {self.start:g} to {self.stop:g} gives more than "
                                 f"{MAX_RANGE_VALUES} values")
        return self

    def count(self) -> int:
        """The number of values, computed without making them."""
        if self.num is not None:
            return int(self.num)
        return int(math.floor((self.stop - self.start) / self.step + 1e-9)) + 1

    def values(self) -> list[float]:
        """The values, floats: ``num`` points from start to stop, or start, start + step, ... up to stop."""
        if self.num is not None:
            return np.linspace(self.start, self.stop, self.num).tolist()
        return (self.start + self.step * np.arange(self.count())).round(12).tolist()


def _grid_entry(key: Any, value: Any) -> list[Any] | GridRange:
    """One ``sweep.grid`` entry checked: a non-empty list of finite scalars, or a :class:`GridRange`."""
    if not isinstance(key, str) or not _DOTTED_KEY.fullmatch(key):
        raise ValueError(f"{shorten(key)} is not a dotted config key (formation.distance_m)")
    if key == "kind" or key.split(".")[0] == "sweep":
        raise ValueError(f"{key}: cannot be swept")
    if isinstance(value, GridRange):
        return value
    if isinstance(value, Mapping):
        try:
            return GridRange.model_validate(value)
        except pydantic.ValidationError as exc:
            err = exc.errors(include_url=False)[0]
            where = ".".join(str(p) for p in err["loc"])
            msg = str(err["msg"]).removeprefix("Value error, ")
            raise ValueError(f"{key}: {where + ': ' if where else ''}{msg}") from None
    if not isinstance(value, list | tuple):
        raise ValueError(f"{key}: expected a list of values or a {{start, stop, step or num}} table, "
                         f"got {shorten(value)}")
    if not value:
        raise ValueError(f"{key}: empty list of values")
    for v in value:
        if not isinstance(v, bool | int | float | str):
            raise ValueError(f"{key}: values must be numbers, booleans or strings, got {shorten(v)}")
        if isinstance(v, float) and not math.isfinite(v):
            raise ValueError(f"{key}: values must be finite, got {v!r}")
    if len(set(np.asarray(list(value)).tolist())) != len(value):
        raise ValueError(f"{key}: values are not distinct: {shorten(list(value))}")
    return list(value)


class SweepSpec(pydantic.BaseModel):
    """The ``[sweep]`` table of a scenario config.

    Example::

        [sweep]
        cell = "error_map"
        trials = 100
        seed = 2021
        [sweep.grid]
        "formation.distance_m" = {start = 30, stop = 100, step = 10}
        "formation.axis_angle_deg" = [5, 10, 15, 20]
        "formation.n_views" = [2, 3]

    The grid may hold at most ``max_cells`` cells (default :data:`MAX_CELLS`), counted before any
    value is made.
    """

    model_config = pydantic.ConfigDict(extra="forbid", allow_inf_nan=False)
    cell: str = pydantic.Field(min_length=1, max_length=64)
    trials: Integer = pydantic.Field(ge=1, le=1_000_000)
    seed: Seed = 0
    seed_keys: list[str] | None = pydantic.Field(
        default=None, description="swept keys the random streams depend on (default all; [] = common random numbers)")
    max_cells: Integer = pydantic.Field(
        default=MAX_CELLS, ge=1, le=10_000_000,
        description="the largest grid accepted, cells (trials not counted); raise it for a larger sweep")
    grid: dict[str, list[float | int | bool | str] | GridRange]

    @pydantic.field_validator("grid", mode="before")
    @classmethod
    def _check_grid(cls, grid: Any) -> Any:
        if not isinstance(grid, Mapping):
            return grid  # pydantic names the type error
        if not grid:
            raise ValueError("at least one swept key is required")
        if len(grid) > MAX_GRID_KEYS:
            raise ValueError(f"{len(grid)} swept keys, at most {MAX_GRID_KEYS}")
        return {key: _grid_entry(key, v) for key, v in grid.items()}

    @pydantic.model_validator(mode="after")
    def _bounded(self) -> SweepSpec:
        for k in self.seed_keys or []:
            if k not in self.grid:
                raise ValueError(f"seed_keys: {shorten(k)} is not a key of sweep.grid")
        counts = [v.count() if isinstance(v, GridRange) else len(v) for v in self.grid.values()]
        cells = math.prod(counts)
        if cells > self.max_cells:
            raise ValueError(f"grid: {cells} cells ({' x '.join(map(str, counts))}) exceed max_cells = "
                             f"{self.max_cells}; set sweep.max_cells to run a larger grid")
        return self

    def n_cells(self) -> int:
        """The number of grid cells, computed without making the values."""
        return math.prod(v.count() if isinstance(v, GridRange) else len(v) for v in self.grid.values())

    def grid_values(self) -> dict[str, list[Any]]:
        """Each swept key's values, in the order given."""
        return {k: (v.values() if isinstance(v, GridRange) else list(v)) for k, v in self.grid.items()}


def parse_overrides(items: Sequence[str] | None) -> dict[str, Any]:
    """``["formation.n_views=2", 'observation.mode="rendered"']`` → ``{dotted key: value}``.

    Values are read as TOML (numbers, booleans, quoted strings, arrays); a bare word is a string.
    Raises ``ValueError`` naming ``--set`` for an item without ``=``.
    """
    out: dict[str, Any] = {}
    for item in items or []:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"--set: expected KEY=VALUE, got {shorten(item)}")
        if not _DOTTED_KEY.fullmatch(key):
            raise ValueError(f"--set: {shorten(key)} is not a dotted config key (formation.distance_m)")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = text.strip()
        except RecursionError:
            raise ValueError(f"--set {key}: value nested too deeply") from None
        out[key] = value
    return out
