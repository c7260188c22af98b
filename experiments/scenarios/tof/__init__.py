"""Scenario kind ``tof_000``: paper 000's TOF-camera pose of a cooperative marker target."""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader as lazy

from experiments.scenarios.tof.config import MATCHERS, MATCHING_CASES, Config

if TYPE_CHECKING:
    from experiments.scenarios.tof.experiment import TABLE1_000, run, table1_stats
    from experiments.scenarios.tof.figures import plot

__all__ = ["Config", "run", "plot", "sweep_cell", "plot_sweep", "MATCHING_CASES", "MATCHERS", "TABLE1_000", "table1_stats"]

# run and plot (and the science behind them) load on first use
__getattr__, _, _ = lazy.attach(
    __name__, submod_attrs={"experiment": ["run", "TABLE1_000", "table1_stats"], "figures": ["plot"]}
)


def sweep_cell(cfg: Config):
    """The ``coobs sweep`` cell named by ``sweep.cell`` (only ``"envelope"``); ``ValueError`` otherwise."""
    from experiments.sweep import SweepSpec

    name = cfg.sweep.cell if isinstance(cfg.sweep, SweepSpec) else ""
    if name != "envelope":
        raise ValueError(f"unknown cell {name!r}; known: envelope")
    from experiments.scenarios.tof.envelope import envelope_sweep_cell

    return envelope_sweep_cell(cfg)


def plot_sweep(dataset, fig_dir, *, format: str = "png"):
    """Envelope maps of a stored ``coobs sweep`` of this kind (error, availability, error/bound, failures)."""
    from experiments.scenarios.tof.envelope import envelope_figures

    return envelope_figures(dataset, fig_dir, format=format)
