"""What a scenario run returns, and how it is written: ``result.nc`` and ``summary.json``."""

from __future__ import annotations

import json
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

__all__ = ["Progress", "no_progress", "ScenarioResult", "write_result", "write_summary", "json_default",
           "summary_text"]

#: ``progress(done, total)``: how far a scenario run is (the CLI draws it as a bar)
Progress = Callable[[int, int], None]


def no_progress(done: int, total: int) -> None:
    """The :data:`Progress` callback that reports nothing (the default of every scenario's ``run``)."""


@dataclass
class ScenarioResult:
    """What a scenario returns: the dataset to store and a JSON-able summary.

    Attributes
    ----------
    dataset : xarray.Dataset
        Coordinates hold what was set, data variables what was measured, units in ``attrs``.
    summary : dict
        Scalars and small tables (numpy scalars and arrays are allowed; see :func:`json_default`).
    """

    dataset: xr.Dataset
    summary: dict[str, Any] = field(default_factory=dict)


def json_default(o: Any) -> Any:
    """``json.dumps`` fallback for numpy scalars and arrays and paths (summaries of runs and sweeps)."""
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def write_result(result: ScenarioResult, out: Path) -> None:
    """Write ``result.nc`` and ``summary.json`` into ``out`` atomically (a temp dir then rename).

    Parameters
    ----------
    result : ScenarioResult
        The run's dataset and summary.
    out : Path
        Output directory (created when missing).
    """
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".coobs-", dir=out.parent))
    try:
        result.dataset.to_netcdf(tmp / "result.nc", engine="h5netcdf")
        (tmp / "summary.json").write_text(json.dumps(result.summary, indent=2, default=json_default) + "\n")
        out.mkdir(parents=True, exist_ok=True)
        for name in ("result.nc", "summary.json"):
            shutil.move(str(tmp / name), str(out / name))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def write_summary(out: Path, summary: dict[str, Any]) -> Path:
    """Write ``out/summary.json`` atomically (a temp file then rename); returns its path."""
    path = out / "summary.json"
    tmp = out / ".summary.json.tmp"
    tmp.write_text(json.dumps(summary, indent=2, default=json_default) + "\n")
    tmp.replace(path)
    return path


def summary_text(summary: dict[str, Any]) -> str:
    """The scalar entries of a summary, one ``key: value`` line each (floats to 6 significant digits)."""
    lines = []
    for k, v in summary.items():
        if isinstance(v, float):
            lines.append(f"{k}: {v:.6g}")
        elif isinstance(v, dict | list):
            continue
        else:
            lines.append(f"{k}: {v}")
    return "\n".join(lines)
