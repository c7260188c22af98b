"""The zarr store of a sweep: its layout, creation, one-cell writes and loading.

Coordinates are the swept parameters, ``trial`` and any extra dimensions of the cell's metrics
(e.g. ``time_s``); data variables are the metrics (units in ``attrs``), ``failure_reason`` and
``done``.  Every cell is its own chunk and zarr writes chunk files atomically; a cell's ``done``
flag is written after its metrics, so a ``SIGKILL`` at any moment leaves either a finished cell or
one that will be recomputed.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from experiments.sweep.cell import SweepCell

__all__ = ["STORE_NAME", "fingerprint_of", "store_template", "open_sweep", "write_cell", "prepare_store"]

STORE_NAME = "sweep.zarr"


def fingerprint_of(cell: SweepCell, grid: Mapping[str, np.ndarray], trials: int, seed: int, identity: str) -> str:
    """SHA-256 of everything that fixes a sweep's numbers (cell, metrics, grid, trials, seed, identity)."""
    spec = {
        "cell": cell.name,
        "metrics": {k: [m.units, list(m.dims), m.per_trial] for k, m in cell.metrics.items()},
        "coords": {k: np.asarray(v).tolist() for k, v in cell.coords.items()},
        "grid": {k: v.tolist() for k, v in grid.items()},
        "trials": trials,
        "seed": seed,
        "identity": identity,
    }
    return hashlib.sha256(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()


def store_template(cell: SweepCell, grid: Mapping[str, np.ndarray], names: list[str], trials: int,
              attrs: Mapping[str, Any]) -> tuple[xr.Dataset, dict[str, dict]]:
    """The empty store (NaN metrics, ``""`` reasons, ``done`` false) and its encoding: one chunk per cell."""
    gshape = tuple(len(v) for v in grid.values())
    coords: dict[str, Any] = {}
    for (key, values), name in zip(grid.items(), names, strict=True):
        coords[name] = xr.Variable((name,), values, attrs={"config_key": key})
    coords["trial"] = np.arange(trials)
    for d, v in cell.coords.items():
        coords[d] = xr.Variable((d,), np.asarray(v), attrs={"units": cell.coord_units.get(d, "")})
    data_vars: dict[str, Any] = {}
    encoding: dict[str, dict] = {}
    ones = (1,) * len(gshape)
    for name, m in cell.metrics.items():
        extra = tuple(len(cell.coords[d]) for d in m.dims)
        dims = (*names, "trial", *m.dims) if m.per_trial else (*names, *m.dims)
        shape = (*gshape, trials, *extra) if m.per_trial else (*gshape, *extra)
        data_vars[name] = xr.Variable(dims, np.full(shape, np.nan),
                                      attrs={"units": m.units, "long_name": m.long_name})
        encoding[name] = {"chunks": ones + shape[len(gshape):]}
    data_vars["failure_reason"] = xr.Variable((*names, "trial"), np.full((*gshape, trials), "", dtype=object),
                                              attrs={"long_name": "why the trial failed; empty when it succeeded"})
    encoding["failure_reason"] = {"chunks": (*ones, trials)}
    data_vars["done"] = xr.Variable(names, np.zeros(gshape, dtype=bool),
                                    attrs={"long_name": "cell finished and written"})
    encoding["done"] = {"chunks": ones}
    ds = xr.Dataset(data_vars, coords=coords, attrs=dict(attrs))
    return ds, encoding


def open_sweep(out: Path | str) -> xr.Dataset:
    """Load ``out/sweep.zarr`` (or the store path itself) into memory as an xarray Dataset."""
    path = Path(out)
    if path.name != STORE_NAME:
        path = path / STORE_NAME
    if not path.exists():
        raise FileNotFoundError(f"out: no {STORE_NAME} in {path.parent}")
    with xr.open_zarr(path, consolidated=False) as ds:
        loaded = ds.load()
    if "failure_reason" in loaded:
        loaded["failure_reason"] = loaded["failure_reason"].astype(object)
    return loaded


def write_cell(store: Path, idx: tuple[int, ...], names: list[str], result: Mapping[str, np.ndarray],
                cell: SweepCell) -> None:
    """Write one finished cell into its region of the store: metrics and reasons, then ``done``."""
    region = {n: slice(i, i + 1) for n, i in zip(names, idx, strict=True)}
    lead = (1,) * len(names)
    data = {}
    for name, m in cell.metrics.items():
        arr = np.asarray(result[name], dtype=float)
        dims = (*names, "trial", *m.dims) if m.per_trial else (*names, *m.dims)
        data[name] = (dims, arr.reshape(lead + arr.shape))
    reason = np.asarray(result["failure_reason"], dtype=object)
    data["failure_reason"] = ((*names, "trial"), reason.reshape(lead + reason.shape))
    xr.Dataset(data).to_zarr(store, region={**region, "trial": slice(None),
                                            **{d: slice(None) for d in cell.coords}},
                             consolidated=False)
    # the done flag goes last, in its own write: a kill before it means the cell is recomputed
    xr.Dataset({"done": (names, np.ones(lead, dtype=bool))}).to_zarr(store, region=region, consolidated=False)


def prepare_store(store: Path, cell: SweepCell, grid: Mapping[str, np.ndarray], names: list[str],
                   trials: int, fingerprint: str, attrs: Mapping[str, Any]) -> np.ndarray:
    """Create the store, or check that an existing one belongs to this sweep; return ``done``."""
    if store.exists():
        try:
            with xr.open_zarr(store, consolidated=False) as old:
                old_fp = old.attrs.get("sweepfingerprint_of")
                done = old["done"].values.astype(bool)
        except Exception as exc:  # noqa: BLE001 - an unreadable store is reported, not crashed on
            raise ValueError(f"out: {store} exists but cannot be read as a sweep ({exc})") from None
        if old_fp != fingerprint:
            raise ValueError(f"out: {store} holds a different sweep (other grid, trials, seed or config); "
                             "use another --out or delete it")
        return done
    ds, encoding = store_template(cell, grid, names, trials, {**attrs, "sweepfingerprint_of": fingerprint})
    store.parent.mkdir(parents=True, exist_ok=True)
    tmp = store.with_name(store.name + ".creating")
    shutil.rmtree(tmp, ignore_errors=True)
    ds.to_zarr(tmp, mode="w", encoding=encoding, consolidated=False)
    tmp.rename(store)  # the store appears complete or not at all
    return np.zeros(tuple(len(v) for v in grid.values()), dtype=bool)

