"""What a sweep sweeps: the ``[sweep]`` table of a config, grid ranges, ``--set`` overrides, grid cells.

The grid is the Cartesian product of the values given for some dotted config keys (e.g.
``formation.distance_m``), in the order they are given; each swept key becomes a dataset coordinate
named after its last part (the full key in ``attrs["config_key"]``).
"""

from __future__ import annotations

import itertools
import json
import math
import tomllib
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

import numpy as np
import pydantic

__all__ = ["GridRange", "SweepSpec", "parse_overrides", "coord_names", "grid_arrays", "grid_cells", "params_key"]


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
    """Inclusive arithmetic range ``{start = 30, stop = 100, step = 5}`` (or ``num`` points)."""

    model_config = pydantic.ConfigDict(extra="forbid")
    start: float
    stop: float
    step: float | None = None
    num: int | None = pydantic.Field(default=None, ge=1)

    @pydantic.model_validator(mode="after")
    def _one_of(self) -> GridRange:
        if (self.step is None) == (self.num is None):
            raise ValueError("give exactly one of step or num")
        if self.step is not None and (self.step <= 0 or self.stop < self.start):
            raise ValueError(f"needs step > 0 and stop >= start (got start={self.start}, stop={self.stop}, step={self.step})")
        return self

    def values(self) -> list[float]:
        if self.num is not None:
            return np.linspace(self.start, self.stop, self.num).tolist()
        n = int(math.floor((self.stop - self.start) / self.step + 1e-9)) + 1
        return (self.start + self.step * np.arange(n)).round(12).tolist()


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
    """

    model_config = pydantic.ConfigDict(extra="forbid")
    cell: str = pydantic.Field(min_length=1)
    trials: int = pydantic.Field(ge=1, le=1_000_000)
    seed: int = pydantic.Field(default=0, ge=0)
    seed_keys: list[str] | None = pydantic.Field(
        default=None, description="swept keys the random streams depend on (default all; [] = common random numbers)")
    grid: dict[str, list[float | int | bool | str] | GridRange]

    @pydantic.field_validator("grid")
    @classmethod
    def _check_grid(cls, grid: dict) -> dict:
        if not grid:
            raise ValueError("at least one swept key is required")
        for key, v in grid.items():
            if isinstance(v, list) and not v:
                raise ValueError(f"{key}: empty list of values")
            if key == "sweep" or key.startswith("sweep.") or key == "kind":
                raise ValueError(f"{key}: cannot be swept")
        return grid

    @pydantic.model_validator(mode="after")
    def _seed_keys_swept(self) -> SweepSpec:
        for k in self.seed_keys or []:
            if k not in self.grid:
                raise ValueError(f"seed_keys: {k!r} is not a key of sweep.grid")
        return self

    def grid_values(self) -> dict[str, list[Any]]:
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
            raise ValueError(f"--set: expected KEY=VALUE, got {item!r}")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = text.strip()
        out[key] = value
    return out
