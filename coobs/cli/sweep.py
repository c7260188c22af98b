"""``coobs sweep CONFIG --out DIR``: the ``[sweep]`` table of a scenario config, run on Dask.

The scenario kind provides the cell function through ``sweep_cell(cfg) -> SweepCell``; every cell's
config, the output directory and the scheduler are checked before any work starts.  Running the
same command again resumes: finished cells are not recomputed.

Exit codes: 0 every cell done; 2 bad input (one line naming the option or key, nothing written);
3 some cells were lost to worker failures and are not done yet (the next run computes them);
1 the output could not be written while the sweep ran.
"""

from __future__ import annotations

from pathlib import Path

import typer

from coobs import api
from coobs._sweep import run_config_sweep
from coobs.cli._console import console, err_console, fail, progress_bar
from experiments.config import ConfigError
from experiments.sweep import parse_overrides
from experiments.sweep.runner import LOOPBACK_DASHBOARD

__all__ = ["sweep"]


def sweep(
    config: str = typer.Argument(..., help="A bundled config's name or a scenario config (TOML) with a sweep table "
                                 "(cell, trials, seed, grid)."),
    out: Path = typer.Option(..., "--out", help="Output directory: sweep.zarr, summary.json, figures/."),
    workers: int = typer.Option(2, "--workers", help="Dask LocalCluster workers (one thread each)."),
    scheduler: str = typer.Option(None, "--scheduler", help="Address of a running Dask scheduler instead of a LocalCluster."),
    no_figures: bool = typer.Option(False, "--no-figures", help="Skip drawing figures."),
    set_: list[str] = typer.Option(None, "--set", help="Override a config key, KEY=VALUE (TOML value); repeatable."),
    dashboard_address: str = typer.Option(
        LOOPBACK_DASHBOARD, "--dashboard-address",
        help="HOST:PORT of the local cluster's Dask dashboard (port 0: a free one; 'none': no dashboard). "
             "Loopback by default; 0.0.0.0:PORT exposes it to the network."),
    retries: int = typer.Option(1, "--retries", help="Times a cell lost to worker failures is resubmitted."),
) -> None:
    """Sweep config keys over a grid × trials on Dask, streaming each cell to DIR/sweep.zarr.

    Running the same command again resumes: finished cells are not recomputed.  Exit code 3: some
    cells were lost to worker failures; run the same command again to compute them.
    """
    if workers < 1:
        raise fail(f"--workers: must be >= 1, got {workers}")
    if retries < 0:
        raise fail(f"--retries: must be >= 0, got {retries}")
    if (out / "result.nc").exists():
        raise fail(f"--out: {str(out)[:60]} holds the results of a `coobs run` (result.nc); use another --out")
    try:
        overrides = parse_overrides(set_)
    except ValueError as exc:
        raise fail(str(exc)) from None
    update, stop = progress_bar()
    try:
        _, report, summary, path = run_config_sweep(
            config, out, overrides, workers=workers, scheduler=scheduler, retries=retries, progress=update,
            on_connect=_print_dashboard,
            dashboard_address=None if dashboard_address.lower() == "none" else dashboard_address)
    except ConfigError as exc:
        raise fail(str(exc)) from None
    except ValueError as exc:
        raise fail(_option_names(str(exc))) from None
    except OSError as exc:  # the disk filled up or went away while cells were being written
        err_console.print(f"error: out: writing {str(out)[:60]} failed ({exc.strerror or exc}); finished cells "
                          "are kept, run the same command again to resume", markup=False, highlight=False,
                          soft_wrap=True)
        raise typer.Exit(code=1) from None
    finally:
        stop()
    figures = [] if no_figures or report.n_undone == report.n_cells else api.plot(out)
    console.print(f"cells: {summary['cells_done']}/{summary['cells']} done "
                  f"({report.n_computed} computed now, {report.wall_s:.1f} s on {report.workers} workers); "
                  f"failed trials: {summary['trials_failed']}", markup=False, highlight=False)
    console.print(f"results: {report.store}, {path}", markup=False, highlight=False)
    for f in figures:
        console.print(f"figure: {f}", markup=False, highlight=False)
    if report.n_undone:
        err_console.print(f"error: {report.n_undone} of {report.n_cells} cells not done ({report.undone_reason}); "
                          "run the same command again to compute them (finished cells are kept)",
                          markup=False, highlight=False, soft_wrap=True)
        raise typer.Exit(code=3)


def _print_dashboard(url: str) -> None:
    """Say where the Dask dashboard is (nothing when there is none)."""
    if url:
        console.print(f"dashboard: {url}", markup=False, highlight=False)


def _option_names(message: str) -> str:
    """A :func:`run_sweep` error with its argument names spelt as this command's options."""
    for arg, option in (("out:", "--out:"), ("scheduler:", "--scheduler:"), ("workers/dashboard_address:",
                        "--workers/--dashboard-address:"), ("dashboard_address:", "--dashboard-address:")):
        if message.startswith(arg):
            return option + message[len(arg):]
    return message
