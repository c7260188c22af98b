"""The coobs Python API: run a scenario, sweep it, draw its figures, list the bundled configs.

Everything here is a thin layer over :mod:`experiments` (the same calls ``coobs run`` and
``coobs sweep`` make), so that a notebook and the command line give the same datasets and files.
"""

from __future__ import annotations

import inspect
import os
import tempfile
import warnings
from collections.abc import Callable, Mapping
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
from experiments.sweep import STORE_NAME, open_sweep

__all__ = ["RunResult", "Configs", "run", "sweep", "plot", "configs", "folder_dataset"]


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
    module, cfg, text, out_path = prepare_run(config, overrides, out, force)
    update, close = progress_callback(progress, desc=cfg.kind, unit="step")
    try:
        result = compute_run(module, cfg, text, update)
    finally:
        close()
    return store_run(result, cfg, out_path)


def prepare_run(config: ConfigLike, overrides: Mapping[str, Any] | None, out: str | os.PathLike | None,
               force: bool) -> tuple[ModuleType, ScenarioConfig, str, Path | None]:
    """The first step of :func:`run` (and of ``coobs run``): validate the config, check ``out``.

    Parameters
    ----------
    config, overrides, out, force
        As in :func:`run`.

    Returns
    -------
    tuple
        ``(module, cfg, text, out_path)``: the scenario kind's module, the validated config, the
        config text stored with the result, and ``out`` as a path (``None`` when not given).

    Raises
    ------
    ConfigError
        A bad config, name, path or override (one line naming the key).
    ValueError
        One line starting ``out:`` when ``out`` cannot be written; nothing is computed or written.
    """
    source, module, cfg = _load(config, overrides)
    text = config_text(source, cfg, overrides)
    out_path = Path(out) if out is not None else None
    if out_path is not None:
        check_output_dir(out_path, config_toml=text, force=force, foreign=(STORE_NAME,))
    return module, cfg, text, out_path


def compute_run(module: ModuleType, cfg: ScenarioConfig, text: str,
             progress: Callable[[int, int], None] | None) -> ScenarioResult:
    """The second step of :func:`run`: the scenario kind's ``run``, its dataset labelled with the kind and config.

    Parameters
    ----------
    module, cfg, text
        From :func:`prepare_run`.
    progress : callable or None
        ``progress(done, total)``.

    Returns
    -------
    ScenarioResult
        The dataset (``attrs["kind"]``, ``attrs["config_toml"]`` set) and the summary.
    """
    result: ScenarioResult = module.run(cfg, progress=progress)
    result.dataset.attrs["kind"] = cfg.kind
    result.dataset.attrs["config_toml"] = text
    return result


def store_run(result: ScenarioResult, cfg: ScenarioConfig, out_path: Path | None) -> RunResult:
    """The last step of :func:`run`: write ``result.nc`` and ``summary.json`` into ``out_path`` (when given).

    Parameters
    ----------
    result : ScenarioResult
        From :func:`compute_run`.
    cfg : ScenarioConfig
        The validated config.
    out_path : Path or None
        The output folder, or ``None`` for nothing written.

    Returns
    -------
    RunResult
        What :func:`run` returns.

    Raises
    ------
    OSError
        The files could not be written.
    """
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
        ds, report, _, _ = run_config_sweep(config, out, overrides, workers=workers, scheduler=scheduler,
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


def _shown(path: Path) -> str:
    return repr(str(path)) if len(str(path)) <= 58 else repr(str(path)[:55]) + "..."


def folder_dataset(folder: str | os.PathLike) -> xr.Dataset:
    """The stored dataset of an output folder: ``result.nc`` of ``coobs run`` or ``coobs filter-study``,
    else ``sweep.zarr`` of ``coobs sweep``.

    Raises
    ------
    ValueError
        One line starting ``out:``: the folder holds neither, or it cannot be read.
    """
    out = Path(folder)
    try:
        is_run = (out / "result.nc").is_file()
        is_sweep = (out / STORE_NAME).exists()
    except OSError as exc:
        raise ValueError(f"out: {_shown(out)} cannot be used ({exc.strerror or type(exc).__name__})") from None
    if not is_run and not is_sweep:
        raise ValueError(f"out: no result.nc or {STORE_NAME} in {_shown(out)}")
    what = "result.nc" if is_run else STORE_NAME
    try:
        return xr.load_dataset(out / "result.nc", engine="h5netcdf") if is_run else open_sweep(out)
    except (OSError, ValueError, KeyError) as exc:
        raise ValueError(f"out: {what} in {_shown(out)} cannot be read ({type(exc).__name__}: {exc})") from None


def _drawer(dataset: xr.Dataset) -> Callable[..., list[Path]]:
    """The function that draws ``dataset``'s figures, from its ``kind`` attribute."""
    from experiments.plotting import sweep_overview_figures  # matplotlib only when drawing
    from experiments.studies import filter_study

    kind = dataset.attrs.get("kind")
    if not kind:
        raise ConfigError("dataset: no 'kind' attribute (a dataset of coobs.run or coobs.sweep has one)")
    if kind == filter_study.KIND:
        return filter_study.plot
    module = kind_module(kind)
    if _is_sweep(dataset):
        return getattr(module, "plot_sweep", None) or sweep_overview_figures
    return module.plot


def plot(dataset: xr.Dataset | str | os.PathLike, fig_dir: str | os.PathLike | None = None, *,
         format: str = "png") -> list[Path]:
    """Draw the figures of a run's, a sweep's or a filter study's dataset, as ``coobs plot`` does.

    Parameters
    ----------
    dataset : xarray.Dataset or path
        ``RunResult.dataset``, the dataset :func:`sweep` returns, or either read back from
        ``result.nc`` / ``sweep.zarr``; or the output folder of ``coobs run``, ``coobs sweep`` or
        ``coobs filter-study``, whose stored dataset is read.  Its ``kind`` attribute picks the
        figures (a sweep of a kind without its own maps gets a map of every metric's trial mean).
    fig_dir : path, optional
        Folder for the figures (created when missing); default ``<folder>/figures`` when
        ``dataset`` is a folder (required for a dataset).
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
        ``format`` is not one the kind's figures can be drawn in, ``fig_dir`` is missing for a
        dataset, or the folder holds no readable results (one line starting ``out:``); nothing written.
    """
    from experiments.plotting import check_format  # matplotlib only when drawing

    if isinstance(dataset, str | os.PathLike):
        folder = Path(dataset)
        dataset = folder_dataset(folder)
        if fig_dir is None:
            fig_dir = folder / "figures"
    elif not isinstance(dataset, xr.Dataset):
        raise TypeError(f"dataset: must be an xarray.Dataset or an output folder, not {type(dataset).__name__}")
    if fig_dir is None:
        raise ValueError("fig_dir: needed to draw a dataset (a folder's figures go to <folder>/figures)")
    draw = _drawer(dataset)
    check_format(format)
    kwargs: dict[str, Any] = {}
    if "format" in inspect.signature(draw).parameters:
        kwargs["format"] = format
    elif format != "png":
        raise ValueError(f"format: the figures of {dataset.attrs['kind']!r} are drawn as PNG only, got "
                         f"{shorten(format)}")
    folder = Path(fig_dir)
    folder.mkdir(parents=True, exist_ok=True)
    return [Path(p) for p in draw(dataset, folder, **kwargs)]
