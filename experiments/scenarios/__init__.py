"""Scenario kinds, TOML config loading and validation, and the ``coobs run`` / ``coobs plot`` commands.

Every config file names its scenario kind at the top level (``kind = "tof_000"``); the rest of the
file is validated by that kind's pydantic model before any work starts.  A kind is a module with:

``Config``
    a pydantic model (``extra="forbid"``) for the whole file, including ``kind``;
``run(cfg, *, progress) -> ScenarioResult``
    the scenario, pure computation plus the ``progress(done, total)`` callback;
``plot(dataset, fig_dir) -> list[Path]``
    figures drawn only from the stored dataset (so ``coobs plot DIR`` can redraw them).

``coobs run CONFIG --out DIR`` writes ``DIR/result.nc``, ``DIR/summary.json`` and
``DIR/figures/*.png`` (ARCHITECTURE §4).  Bad configs exit with code 2, one line naming the key, and
nothing written.
"""

from __future__ import annotations

import importlib
import json
import shutil
import tempfile
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pydantic
import typer
import xarray as xr

from experiments.cli import app, console, fail

#: scenario kind → module implementing it.
KINDS: dict[str, str] = {
    "formation": "experiments.scenario_formation",
    "tof_000": "experiments.scenario_tof",
    "rodrigues_001": "experiments.scenario_rodrigues",
    "cylindrical_004": "experiments.scenario_cylindrical",
}


class ConfigError(ValueError):
    """A config that cannot be run; the message is one line naming the key."""


@dataclass
class ScenarioResult:
    """What a scenario returns: the dataset to store and a JSON-able summary."""

    dataset: xr.Dataset
    summary: dict[str, Any] = field(default_factory=dict)


def _format_validation_error(err: pydantic.ValidationError) -> str:
    first = err.errors()[0]
    key = ".".join(str(p) for p in first["loc"]) or "<root>"
    msg = first["msg"]
    if first["type"] == "extra_forbidden":
        msg = "unknown key"
    value = first.get("input")
    shown = "" if first["type"] in ("missing", "extra_forbidden") or isinstance(value, dict) else f" (got {value!r})"
    return f"{key}: {msg}{shown}"


def kind_module(kind: str):
    """Import the module of a scenario kind; ``ConfigError`` if the kind is unknown."""
    if kind not in KINDS:
        raise ConfigError(f"kind: unknown scenario kind {kind!r}; known: {', '.join(sorted(KINDS))}")
    return importlib.import_module(KINDS[kind])


def load_config(path: Path | str, overrides: dict[str, Any] | None = None):
    """Read and validate a TOML config; returns ``(module, cfg)``.

    ``overrides`` maps dotted keys (``"formation.distance_m"``) to values, applied before validation.
    Raises ``ConfigError`` with a one-line message naming the key.
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"config: file not found: {path}")
    try:
        raw = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"config: not valid TOML ({exc})") from None
    for dotted, value in (overrides or {}).items():
        node = raw
        parts = dotted.split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = value
    if "kind" not in raw:
        raise ConfigError(f"kind: missing (one of {', '.join(sorted(KINDS))})")
    module = kind_module(raw["kind"])
    try:
        cfg = module.Config.model_validate(raw)
    except pydantic.ValidationError as exc:
        raise ConfigError(_format_validation_error(exc)) from None
    return module, cfg


def write_result(result: ScenarioResult, out: Path) -> None:
    """Write ``result.nc`` and ``summary.json`` into ``out`` atomically (a temp dir then rename)."""
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


def json_default(o: Any) -> Any:
    """``json.dumps`` fallback for numpy scalars and arrays and paths (summaries of runs and sweeps)."""
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def redraw(out: Path) -> list[Path]:
    """Redraw the figures of a stored run from ``out/result.nc``."""
    ds = xr.load_dataset(out / "result.nc", engine="h5netcdf")
    kind = ds.attrs.get("kind")
    if kind is None:
        raise ConfigError(f"{out / 'result.nc'}: dataset has no 'kind' attribute")
    module = kind_module(kind)
    fig_dir = out / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    return list(module.plot(ds, fig_dir))


def _progress_bar() -> tuple[Callable[[int, int], None], Callable[[], None]]:
    from rich.progress import (
        BarColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    prog = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                    TimeElapsedColumn(), TimeRemainingColumn(), console=console, transient=False)
    task = None

    def update(done: int, total: int) -> None:
        nonlocal task
        if task is None:
            prog.start()
            task = prog.add_task("running", total=total)
        prog.update(task, completed=done, total=total)

    def stop() -> None:
        if task is not None:
            prog.stop()

    return update, stop


@app.command()
def run(
    config: Path = typer.Argument(..., help="Scenario config (TOML); its top-level 'kind' selects the scenario."),
    out: Path = typer.Option(..., "--out", help="Output directory: result.nc, summary.json, figures/."),
    no_figures: bool = typer.Option(False, "--no-figures", help="Skip drawing figures."),
) -> None:
    """Run one scenario end to end and write result.nc, summary.json and figures/ under --out."""
    try:
        module, cfg = load_config(config)
    except ConfigError as exc:
        raise fail(str(exc)) from None
    update, stop = _progress_bar()
    try:
        result = module.run(cfg, progress=update)
    finally:
        stop()
    result.dataset.attrs["kind"] = cfg.kind
    result.dataset.attrs["config_toml"] = Path(config).read_text()
    write_result(result, out)
    figures = [] if no_figures else redraw(out)
    console.print(_summary_text(result.summary), markup=False, highlight=False)
    console.print(f"results: {out / 'result.nc'}, {out / 'summary.json'}")
    for f in figures:
        console.print(f"figure: {f}")


def _summary_text(summary: dict[str, Any]) -> str:
    lines = []
    for k, v in summary.items():
        if isinstance(v, float):
            lines.append(f"{k}: {v:.6g}")
        elif isinstance(v, dict | list):
            continue
        else:
            lines.append(f"{k}: {v}")
    return "\n".join(lines)


@app.command()
def plot(out: Path = typer.Argument(..., help="A directory written by 'coobs run' or 'coobs sweep'.")) -> None:
    """Redraw the figures of a stored run or sweep from its result files."""
    if not (out / "result.nc").is_file() and not (out / "sweep.zarr").exists():
        raise fail(f"out: no result.nc or sweep.zarr in {out}")
    if (out / "result.nc").is_file():
        try:
            figures = redraw(out)
        except ConfigError as exc:
            raise fail(str(exc)) from None
    else:
        from experiments import sweep as sweep_mod  # registered by the sweep module

        figures = sweep_mod.redraw(out)
    for f in figures:
        console.print(f"figure: {f}")
