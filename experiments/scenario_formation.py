"""Scenario kind ``"formation"``: paper 003, cooperative multi-view observation of a tumbling target.

``coobs run CONFIG --out DIR`` runs the config's ``study`` (see :mod:`experiments.formation_config`):

- ``closed_loop`` — one scenario end to end (:func:`experiments.formation_closed_loop.closed_loop`);
- ``error_map`` — one cell of Experiment A at the configured distance and axis angle, ``trials``
  initial attitudes (:func:`experiments.formation_pipeline.error_map_trials`);
- ``ekf`` — Experiments B–D (:func:`experiments.formation_ekf.ekf_study`).

``coobs sweep CONFIG --out DIR`` runs its ``[sweep]`` table with one of the cells of
:data:`SWEEP_CELLS` (``error_map``, ``closed_loop``, ``ekf``).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import xarray as xr

from experiments.formation_config import Config
from experiments.scenarios import ScenarioResult
from experiments.sweep import SweepCell, cell_seed_sequences

__all__ = ["Config", "run", "plot", "sweep_cell", "plot_sweep", "SWEEP_CELLS"]


def _error_map_cell(cfg: Config) -> SweepCell:
    from experiments.formation_pipeline import error_map_sweep_cell

    return error_map_sweep_cell(cfg)


def _closed_loop_cell(cfg: Config) -> SweepCell:
    from experiments.formation_closed_loop import closed_loop_sweep_cell

    return closed_loop_sweep_cell(cfg)


def _ekf_cell(cfg: Config) -> SweepCell:
    from experiments.formation_ekf import ekf_sweep_cell

    return ekf_sweep_cell(cfg)


#: sweep cell name → factory ``(base config) -> SweepCell``
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


def run(cfg: Config, *, progress: Callable[[int, int], None]) -> ScenarioResult:
    """Run the config's study once (see the module docstring)."""
    if cfg.study == "ekf":
        from experiments.formation_ekf import ekf_study

        ds, summary = ekf_study(cfg, progress=progress)
    elif cfg.study == "error_map":
        ds, summary = _error_map_run(cfg, progress)
    else:
        from experiments.formation_closed_loop import closed_loop

        seed_seq = cell_seed_sequences(cfg.seed, {}, 1)[0]
        ds, summary = closed_loop(cfg, seed_seq, progress=progress)
    ds.attrs["title"] = cfg.title
    summary = {"study": cfg.study, **summary}
    return ScenarioResult(dataset=ds, summary=summary)


def _error_map_run(cfg: Config, progress: Callable[[int, int], None]) -> tuple[xr.Dataset, dict]:
    from experiments.formation_pipeline import error_map_sweep_cell

    cell = error_map_sweep_cell(cfg)
    seeds = cell_seed_sequences(cfg.seed, {}, cfg.trials)
    progress(0, 1)
    out = cell.fn(cfg, seeds)
    progress(1, 1)
    data = {}
    for name, m in cell.metrics.items():
        dims = ("trial",) if m.per_trial else ()
        data[name] = (dims, np.asarray(out[name], dtype=float), {"units": m.units, "long_name": m.long_name})
    data["failure_reason"] = ("trial", np.asarray(out["failure_reason"]).astype(str))
    f = cfg.formation
    ds = xr.Dataset(data, coords={"trial": np.arange(cfg.trials)},
                    attrs={"study": "error_map", "distance_m": f.distance_m, "axis_angle_deg": f.axis_angle_deg,
                           "n_views": f.n_views, "registration": cfg.estimator.registration,
                           "observation_mode": cfg.observation.mode})
    e = ds.e_dtheta_deg.values
    summary = {
        "distance_m": f.distance_m, "axis_angle_deg": f.axis_angle_deg, "n_views": f.n_views,
        "median_e_dtheta_deg": float(np.nanmedian(e)) if np.isfinite(e).any() else float("nan"),
        "median_step_rms_deg": float(np.nanmedian(ds.step_rms_deg.values)),
        "median_crlb_deg": float(np.nanmedian(ds.crlb_deg.values)),
        "failed_trials": int((ds.failure_reason.values != "").sum()),
    }
    return ds, summary


def plot(dataset: xr.Dataset, fig_dir: Path) -> list[Path]:
    """Figures of a stored ``coobs run`` of this kind (drawn from the dataset only)."""
    from experiments import plots as pf

    study = dataset.attrs.get("study")
    if study == "ekf":
        return pf.ekf_figures(dataset, fig_dir)
    if study == "error_map":
        return pf.error_map_run_figures(dataset, fig_dir)
    return pf.closed_loop_figures(dataset, fig_dir)


def plot_sweep(dataset: xr.Dataset, fig_dir: Path) -> list[Path]:
    """Figures of a stored sweep of this kind (error maps with the CRLB map, convergence maps)."""
    from experiments import plots as pf

    return pf.sweep_figures(dataset, fig_dir)
