"""What a scenario run returns, and how it is written: ``result.nc`` and ``summary.json``."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

__all__ = ["Progress", "no_progress", "ScenarioResult", "check_output_dir", "write_result", "write_summary",
           "json_default", "strict_json", "summary_json", "summary_text"]

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


def strict_json(o: Any) -> Any:
    """``o`` as plain JSON values: numpy scalars and arrays as numbers and lists, paths as strings,
    tuples as lists, and every NaN or infinity as ``None`` (JSON ``null``).

    Parameters
    ----------
    o : Any
        A summary: dicts, lists and tuples of numbers, strings, booleans, ``None``, numpy values, paths.

    Returns
    -------
    Any
        The same structure with nothing that strict JSON cannot hold.

    Raises
    ------
    TypeError
        A value of another type (see :func:`json_default`).
    """
    if isinstance(o, dict):
        return {str(k): strict_json(v) for k, v in o.items()}
    if isinstance(o, list | tuple):
        return [strict_json(v) for v in o]
    if isinstance(o, np.ndarray | np.generic | Path):
        return strict_json(json_default(o))
    if isinstance(o, float) and not np.isfinite(o):
        return None
    if o is None or isinstance(o, str | bool | int | float):
        return o
    return strict_json(json_default(o))


def summary_json(summary: dict[str, Any]) -> str:
    """The text of ``summary.json``: indented, strict JSON (``null`` for NaN and infinities), a final newline."""
    return json.dumps(strict_json(summary), indent=2, allow_nan=False) + "\n"


def _shown(path: Path) -> str:
    text = repr(str(path))
    return text if len(text) <= 60 else text[:57] + "..."


def _stored_config(nc: Path) -> str | None:
    """The ``config_toml`` attribute of a stored ``result.nc`` (``None`` when it cannot be read)."""
    try:
        with xr.open_dataset(nc, engine="h5netcdf") as ds:
            text = ds.attrs.get("config_toml")
    except Exception:  # noqa: BLE001 - any unreadable file counts as another run's
        return None
    return text if isinstance(text, str) else None


def _probe(folder: Path) -> None:
    """Create and remove an empty folder in ``folder``: the only sure test that it can be written."""
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".coobs-probe-", dir=folder))
    except OSError as exc:
        raise ValueError(f"out: cannot write in {_shown(folder)} ({exc.strerror or type(exc).__name__})") from None


def check_output_dir(out: Path, *, config_toml: str | None = None, force: bool = False,
                     foreign: Sequence[str] = ()) -> None:
    """Check, before any computing, that :func:`write_result` can write into ``out``; writes nothing.

    Parameters
    ----------
    out : Path
        The output folder (it may not exist yet).
    config_toml : str, optional
        The text of the config to be run: a folder holding a ``result.nc`` of the same config text
        may be written again (the run is repeated); one of another config needs ``force``.
    force : bool
        Replace the results of another run.
    foreign : sequence of str
        Names whose presence in ``out`` marks another command's results (e.g. a sweep store); they
        need ``force`` too.

    Raises
    ------
    ValueError
        One line starting ``out:``: ``out`` or one of its parents is a file, the folder cannot be
        written, or it holds another run's results and ``force`` is false.
    """
    out = Path(os.path.abspath(out))
    try:
        if out.exists() and not out.is_dir():
            raise ValueError(f"out: {_shown(out)} is a file, not a folder")
        if out.is_dir():
            if not force:
                for name in foreign:
                    if (out / name).exists():
                        raise ValueError(f"out: {_shown(out)} holds {name} of another command; choose another "
                                         "folder or pass --force")
                nc = out / "result.nc"
                if nc.exists() and (config_toml is None or _stored_config(nc) != config_toml):
                    raise ValueError(f"out: {_shown(out)} holds the results of another run; choose another "
                                     "folder or pass --force to replace them")
            _probe(out)
        parent = out.parent
        while not parent.exists():
            parent = parent.parent
        if not parent.is_dir():
            raise ValueError(f"out: {_shown(parent)} is a file, not a folder")
        _probe(parent)
    except OSError as exc:
        raise ValueError(f"out: {_shown(out)} cannot be used ({exc.strerror or type(exc).__name__})") from None


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
        (tmp / "summary.json").write_text(summary_json(result.summary))
        out.mkdir(parents=True, exist_ok=True)
        for name in ("result.nc", "summary.json"):
            shutil.move(str(tmp / name), str(out / name))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def write_summary(out: Path, summary: dict[str, Any]) -> Path:
    """Write ``out/summary.json`` atomically (a temp file then rename); returns its path."""
    path = out / "summary.json"
    tmp = out / ".summary.json.tmp"
    tmp.write_text(summary_json(summary))
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
