"""The coobs Python API: run a scenario, sweep it, draw its figures, list the bundled configs.

Everything here is a thin layer over :mod:`experiments` (the same calls ``coobs run`` and
``coobs sweep`` make), so that a notebook and the command line give the same datasets and files.
"""

from __future__ import annotations

import inspect
import os
import tempfile
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import xarray as xr

from coobs._progress import ProgressLike, progress_callback
from coobs._source import ConfigLike, config_source, config_text
from coobs._sweep import run_config_sweep
from experiments.bundled import bundled_configs
from experiments.config import ConfigError, ScenarioConfig, kind_module, load_config, shorten
from experiments.results import (
    ScenarioResult,
    check_output_dir,
    summary_text,
    write_result,
)
from experiments.sweep import STORE_NAME

__all__ = ["RunResult", "Configs", "run", "sweep", "plot", "configs"]


@dataclass(frozen=True)
class RunResult:
    """What :func:`run` returns.

    Attributes
    ----------
    dataset : xarray.Dataset
        Everything the run stored (``result.nc``): coordinates hold what was set, data variables what
        was measured, units in ``attrs``; ``attrs["kind"]`` and ``attrs["config_toml"]`` say how to
        run it again.
    summary : dict
        Scalars and small tables (``summary.json``).
    config : ScenarioConfig
        The validated config that ran (overrides applied).
    out : Path or None
        The folder holding ``result.nc`` and ``summary.json``, or ``None`` when nothing was written.
    """

    dataset: xr.Dataset
    summary: dict[str, Any]
    config: ScenarioConfig
    out: Path | None = None

    def plot(self, fig_dir: str | os.PathLike | None = None, *, format: str = "png") -> list[Path]:
        """Draw the figures of this run's scenario kind.

        Parameters
        ----------
        fig_dir : path, optional
            Folder for the figures; default ``out/figures`` when the run was written, else a new
            temporary folder (its path is in the returned paths).
        format : str
            File format of the figures (see :func:`plot`).

        Returns
        -------
        list of Path
            The figure files.
        """
        if fig_dir is None:
            fig_dir = self.out / "figures" if self.out is not None else tempfile.mkdtemp(prefix="coobs-figures-")
        return plot(self.dataset, fig_dir, format=format)

    def __str__(self) -> str:
        where = f" → {self.out}" if self.out is not None else ""
        return f"{self.config.kind} run{where}\n{summary_text(self.summary)}"


class Configs(dict[str, str]):
    """The bundled configs: name → title, shown one line each (:func:`configs`)."""

    def __repr__(self) -> str:
        width = max((len(k) for k in self), default=0)
        return "\n".join(f"{name:<{width}}  {title}" for name, title in self.items())

    __str__ = __repr__

    def _repr_pretty_(self, printer: Any, cycle: bool) -> None:  # IPython and Jupyter
        printer.text(repr(self))


def configs() -> Configs:
    """The configs shipped with coobs, by the name :func:`run` and :func:`sweep` accept.

    Returns
    -------
    Configs
        A ``dict`` of name → title (the config's ``title``, else its first comment line) that prints
        one line per config.

    Examples
    --------
    >>> import coobs
    >>> "quickstart" in coobs.configs()
    True
    """
    return Configs({name: b.title for name, b in bundled_configs().items()})


def _load(config: ConfigLike, overrides: Mapping[str, Any] | None
          ) -> tuple[Path | dict[str, Any], ModuleType, ScenarioConfig]:
    if overrides is not None and not isinstance(overrides, Mapping):
        raise ConfigError(f"overrides: must be a mapping of dotted key → value, not {type(overrides).__name__}")
    source = config_source(config)
    module, cfg = load_config(source, overrides)
    return source, module, cfg


def run(config: ConfigLike, *, overrides: Mapping[str, Any] | None = None, out: str | os.PathLike | None = None,
        progress: ProgressLike = True, force: bool = False) -> RunResult:
    """Run one scenario end to end, as ``coobs run`` does.

    Parameters
    ----------
    config : str, path, mapping or ScenarioConfig
        A bundled config's name (``"quickstart"``; see :func:`configs`), a TOML file, a parsed table
        (``{"kind": "formation", "formation": {"n_views": 2}, ...}``) or a validated config.
    overrides : mapping, optional
        Dotted key → value set before validation: ``{"observation.mode": "geometric",
        "time.duration_s": 10.0}``.
    out : path, optional
        Folder to write ``result.nc`` and ``summary.json`` into (checked before any computing);
        default: nothing is written.
    progress : bool or callable
        ``True`` a progress bar (text in a terminal, a widget in a notebook), ``False`` nothing, or a
        callable ``progress(done, total)``.
    force : bool
        Replace the results of another run in ``out``.

    Returns
    -------
    RunResult
        ``.dataset``, ``.summary``, ``.config``, ``.out`` and ``.plot()``.

    Raises
    ------
    ConfigError
        One line naming the key, for a bad config, name, path or override; nothing computed or written.
    ValueError
        One line starting ``out:``, when ``out`` cannot be written or holds another run's results.

    Examples
    --------
    >>> import coobs
    >>> res = coobs.run("quickstart", overrides={"observation.mode": "geometric", "time.duration_s": 6.0,
    ...                                          "estimator.convergence_hold_s": 2.0}, progress=False)
    >>> res.summary["epochs"]
    7
    """
    source, module, cfg = _load(config, overrides)
    text = config_text(source, cfg, overrides)
    out_path = Path(out) if out is not None else None
    if out_path is not None:
        check_output_dir(out_path, config_toml=text, force=force, foreign=(STORE_NAME,))
    update, close = progress_callback(progress, desc=cfg.kind, unit="step")
    try:
        result: ScenarioResult = module.run(cfg, progress=update)
    finally:
        close()
    result.dataset.attrs["kind"] = cfg.kind
    result.dataset.attrs["config_toml"] = text
    if out_path is not None:
        write_result(result, out_path)
    return RunResult(dataset=result.dataset, summary=result.summary, config=cfg, out=out_path)


def sweep(config: ConfigLike, *, out: str | os.PathLike, overrides: Mapping[str, Any] | None = None,
          workers: int = 1, scheduler: str | None = None, processes: bool = True, retries: int = 1,
          progress: ProgressLike = True, dashboard_address: str | None = None) -> xr.Dataset:
    """Run (or resume) the ``[sweep]`` table of a config on Dask, as ``coobs sweep`` does.

    Every cell's config is validated before any work starts; each finished cell is written to
    ``out/sweep.zarr`` at once, so that calling again with the same arguments resumes (finished
    cells are not recomputed; a sweep started by ``coobs sweep`` resumes too).  ``out/summary.json``
    is written at the end; draw the maps with :func:`plot`.

    Parameters
    ----------
    config : str, path, mapping or ScenarioConfig
        A config with a ``[sweep]`` table (``cell``, ``trials``, ``seed``, ``grid``), given as in
        :func:`run`.
    out : path
        Output folder (``sweep.zarr``, ``summary.json``).
    overrides : mapping, optional
        Dotted key → value for every cell, e.g. ``{"sweep.trials": 3}`` or
        ``{"sweep.grid": {"formation.n_views": [2, 3]}}``.
    workers : int
        Workers of the local Dask cluster (one thread each).
    scheduler : str, optional
        Address of a running Dask scheduler instead of a local cluster.
    processes : bool
        Local workers as processes (default) or as threads of this process (starts faster; for
        small sweeps).
    retries : int
        Times a cell lost to a worker failure is resubmitted.
    progress : bool or callable
        As in :func:`run`, counting cells.
    dashboard_address : str, optional
        ``HOST:PORT`` of the local cluster's Dask dashboard; default none.

    Returns
    -------
    xarray.Dataset
        The stored sweep: the grid's coordinates and ``trial``, every metric, ``failure_reason`` and
        ``done``.  A :class:`RuntimeWarning` says when cells were lost to worker failures (call
        again to compute them).

    Raises
    ------
    ConfigError
        One line naming the key, for a bad config or a config without a ``[sweep]`` table.
    ValueError
        One line naming the argument (``out``, ``workers``, ``scheduler`` ...); nothing written.
    """
    update, close = progress_callback(progress, desc="sweep", unit="cell")
    try:
        ds, report, _ = run_config_sweep(config, out, overrides, workers=workers, scheduler=scheduler,
                                         processes=processes, retries=retries, progress=update,
                                         dashboard_address=dashboard_address)
    finally:
        close()
    if report.n_undone:
        warnings.warn(f"{report.n_undone} of {report.n_cells} cells not done ({report.undone_reason}); call "
                      "coobs.sweep again with the same arguments to compute them", RuntimeWarning, stacklevel=2)
    return ds


def _is_sweep(dataset: xr.Dataset) -> bool:
    return "done" in dataset.data_vars and "trial" in dataset.dims


def plot(dataset: xr.Dataset, fig_dir: str | os.PathLike, *, format: str = "png") -> list[Path]:
    """Draw the figures of a run's or a sweep's dataset, as ``coobs plot`` does.

    Parameters
    ----------
    dataset : xarray.Dataset
        ``RunResult.dataset``, the dataset :func:`sweep` returns, or either read back from
        ``result.nc`` / ``sweep.zarr``; its ``kind`` attribute picks the scenario kind's figures
        (a sweep of a kind without its own maps gets a map of every metric's trial mean).
    fig_dir : path
        Folder for the figures (created when missing).
    format : str
        File format, one of :data:`experiments.plotting.FORMATS` (``"png"``, ``"pdf"``, ``"svg"``).

    Returns
    -------
    list of Path
        The figure files.

    Raises
    ------
    ConfigError
        The dataset names no scenario kind, or an unknown one.
    ValueError
        ``format`` is not one the kind's figures can be drawn in (nothing written).
    """
    from experiments.plotting import (  # matplotlib only when drawing
        check_format,
        sweep_overview_figures,
    )

    if not isinstance(dataset, xr.Dataset):
        raise TypeError(f"dataset: must be an xarray.Dataset, not {type(dataset).__name__}")
    kind = dataset.attrs.get("kind")
    if not kind:
        raise ConfigError("dataset: no 'kind' attribute (a dataset of coobs.run or coobs.sweep has one)")
    module = kind_module(kind)
    if _is_sweep(dataset):
        draw = getattr(module, "plot_sweep", None)
        if draw is None:
            draw = sweep_overview_figures
    else:
        draw = module.plot
    check_format(format)
    kwargs: dict[str, Any] = {}
    if "format" in inspect.signature(draw).parameters:
        kwargs["format"] = format
    elif format != "png":
        raise ValueError(f"format: the figures of scenario kind {kind!r} are drawn as PNG only, got {shorten(format)}")
    folder = Path(fig_dir)
    folder.mkdir(parents=True, exist_ok=True)
    return [Path(p) for p in draw(dataset, folder, **kwargs)]
