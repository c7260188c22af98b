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
import os
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from experiments.sweep.cell import SweepCell

__all__ = ["STORE_NAME", "FINGERPRINT_ATTR", "fingerprint_of", "store_template", "open_sweep", "write_cell",
           "check_out", "existing_done", "create_store"]

STORE_NAME = "sweep.zarr"
#: dataset attribute holding the sweep's fingerprint (stores of the first restructured release
#: wrote ``sweepfingerprint_of``; both are read)
FINGERPRINT_ATTR = "sweep_fingerprint"


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


def check_out(out: Path) -> None:
    """Check, before any work, that ``out`` is (or can become) a writable directory; write nothing.

    Raises ``ValueError`` naming ``out`` when ``out`` (or one of its parents) is a file, or when its
    nearest existing ancestor refuses a new directory (read-only file system, no permission, a
    pseudo file system such as ``/proc``).  The check creates and removes a probe directory there,
    so it holds for root as well.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"out: {_short(out)} is a file, not a directory")
    ancestor = out
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise ValueError(f"out: {_short(out)} cannot be created: {_short(ancestor)} is a file")
    try:
        probe = tempfile.mkdtemp(prefix=".coobs-write-probe-", dir=ancestor)
    except OSError as exc:
        raise ValueError(f"out: {_short(out)} is not writable ({exc.strerror or type(exc).__name__} "
                         f"in {_short(ancestor)})") from None
    os.rmdir(probe)


def existing_done(store: Path, fingerprint: str, shape: tuple[int, ...]) -> np.ndarray | None:
    """The ``done`` flags of an existing store of this very sweep; ``None`` when there is no store.

    Reads only.  Raises ``ValueError`` naming ``out`` when the store is unreadable or holds another
    sweep (its fingerprint differs).
    """
    if not store.exists():
        return None
    try:
        with xr.open_zarr(store, consolidated=False) as old:
            old_fp = old.attrs.get(FINGERPRINT_ATTR, old.attrs.get("sweepfingerprint_of"))
            done = old["done"].values.astype(bool)
    except Exception as exc:  # noqa: BLE001 - an unreadable store is reported, not crashed on
        raise ValueError(f"out: {_short(store)} exists but cannot be read as a sweep "
                         f"({type(exc).__name__}: {_short(exc)})") from None
    if old_fp != fingerprint or done.shape != shape:
        raise ValueError(f"out: {_short(store)} holds a different sweep (other grid, trials, seed or config); "
                         "use another --out or delete it")
    return done


def create_store(store: Path, cell: SweepCell, grid: Mapping[str, np.ndarray], names: list[str],
                 trials: int, fingerprint: str, attrs: Mapping[str, Any]) -> None:
    """Create the empty store of a sweep; it appears complete or not at all."""
    ds, encoding = store_template(cell, grid, names, trials, {**attrs, FINGERPRINT_ATTR: fingerprint})
    store.parent.mkdir(parents=True, exist_ok=True)
    tmp = store.with_name(store.name + ".creating")
    shutil.rmtree(tmp, ignore_errors=True)
    ds.to_zarr(tmp, mode="w", encoding=encoding, consolidated=False)
    tmp.rename(store)


def _short(value: object, n_chars: int = 60) -> str:
    """``str(value)`` on one line, cut to ``n_chars`` characters (with an ellipsis)."""
    text = " ".join(str(value).split())
    return text if len(text) <= n_chars else text[: n_chars - 1] + "…"
