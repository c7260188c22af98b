"""The kind protocol of ``formation``: run a config's study, draw its figures, pick its sweep cell.

``study`` selects what ``coobs run`` does (:data:`STUDIES`): ``closed_loop`` (one scenario end to
end), ``error_map`` (one cell of 003 Experiment A) or ``ekf`` (003 Experiments B–D); ``sweep.cell``
selects the cell ``coobs sweep`` evaluates (:data:`SWEEP_CELLS`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import xarray as xr

from experiments.results import ScenarioResult
from experiments.scenarios.formation.config import Config
from experiments.sweep import SweepCell, cell_seed_sequences

__all__ = ["run", "plot", "sweep_cell", "plot_sweep", "SWEEP_CELLS", "STUDIES"]


def _error_map_cell(cfg: Config) -> SweepCell:
    from experiments.scenarios.formation.error_map import error_map_sweep_cell

    return error_map_sweep_cell(cfg)


def _closed_loop_cell(cfg: Config) -> SweepCell:
    from experiments.scenarios.formation.closed_loop import closed_loop_sweep_cell

    return closed_loop_sweep_cell(cfg)


def _ekf_cell(cfg: Config) -> SweepCell:
    from experiments.scenarios.formation.ekf import ekf_sweep_cell

    return ekf_sweep_cell(cfg)


#: sweep cell name (``sweep.cell``) → factory ``(base config) -> SweepCell``
SWEEP_CELLS: dict[str, Callable[[Config], SweepCell]] = {
    "error_map": _error_map_cell,
    "closed_loop": _closed_loop_cell,
    "ekf": _ekf_cell,
}


def sweep_cell(cfg: Config) -> SweepCell:
    """The sweep cell named by ``cfg.sweep.cell``; ``ValueError`` naming the known ones otherwise."""
    name = cfg.sweep.cell if cfg.sweep is not None else ""
    if name not in SWEEP_CELLS:
        raise ValueError(f"unknown cell {name!r}; known: {', '.join(SWEEP_CELLS)}")
    return SWEEP_CELLS[name](cfg)


def _run_ekf(cfg: Config, progress: Callable[[int, int], None] | None) -> tuple[xr.Dataset, dict]:
    from experiments.scenarios.formation.ekf import ekf_study

    return ekf_study(cfg, progress=progress)


def _run_error_map(cfg: Config, progress: Callable[[int, int], None] | None) -> tuple[xr.Dataset, dict]:
    from experiments.scenarios.formation.error_map import error_map_run

    return error_map_run(cfg, progress=progress)


def _run_closed_loop(cfg: Config, progress: Callable[[int, int], None] | None) -> tuple[xr.Dataset, dict]:
    from experiments.scenarios.formation.closed_loop import closed_loop

    return closed_loop(cfg, cell_seed_sequences(cfg.seed, {}, 1)[0], progress=progress)


#: study (``study``) → ``(cfg, progress) -> (dataset, summary)``
STUDIES: dict[str, Callable[[Config, Callable[[int, int], None] | None], tuple[xr.Dataset, dict]]] = {
    "closed_loop": _run_closed_loop,
    "error_map": _run_error_map,
    "ekf": _run_ekf,
}


def run(cfg: Config, *, progress: Callable[[int, int], None] | None = None) -> ScenarioResult:
    """Run the config's study once.

    ``closed_loop``: one scenario end to end (:func:`experiments.scenarios.formation.closed_loop.closed_loop`);
    ``error_map``: one cell of Experiment A at the configured distance and axis angle, ``trials``
    initial attitudes (:func:`experiments.scenarios.formation.error_map.error_map_run`);
    ``ekf``: Experiments B–D (:func:`experiments.scenarios.formation.ekf.ekf_study`).
    """
    ds, summary = STUDIES[cfg.study](cfg, progress)
    ds.attrs["title"] = cfg.title
    return ScenarioResult(dataset=ds, summary={"study": cfg.study, **summary})


def plot(dataset: xr.Dataset, fig_dir: Path, *, format: str = "png") -> list[Path]:
    """Figures of a stored ``coobs run`` of this kind (drawn from the dataset only), as ``format``
    (``"png"``, ``"pdf"`` or ``"svg"``)."""
    from experiments.scenarios.formation import figures

    drawers = {"ekf": figures.ekf_figures, "error_map": figures.error_map_run_figures}
    return drawers.get(dataset.attrs.get("study"), figures.closed_loop_figures)(dataset, fig_dir, format=format)


def plot_sweep(dataset: xr.Dataset, fig_dir: Path, *, format: str = "png") -> list[Path]:
    """Figures of a stored sweep of this kind (error maps with the CRLB map, convergence maps), as ``format``."""
    from experiments.scenarios.formation.figures import sweep_figures

    return sweep_figures(dataset, fig_dir, format=format)
