"""Scenario kind ``cylindrical_004``: paper 004's orthogonal linear-CCD cameras, calibrated, measuring points and attitudes."""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader as lazy

from experiments.scenarios.cylindrical.config import (
    PAPER_MAX_ERR_DEG,
    TABLE1_MM,
    TABLE2_DEG,
    TABLE2_ERR_DEG,
    Config,
)

if TYPE_CHECKING:
    from experiments.scenarios.cylindrical.envelope_figures import plot_sweep
    from experiments.scenarios.cylindrical.experiment import run
    from experiments.scenarios.cylindrical.figures import plot
    from experiments.scenarios.cylindrical.kind import sweep_cell

__all__ = ["Config", "run", "plot", "sweep_cell", "plot_sweep", "TABLE1_MM", "TABLE2_DEG", "TABLE2_ERR_DEG",
           "PAPER_MAX_ERR_DEG"]

# run, plot, the sweep cell and its figures (and the science behind them) load on first use
__getattr__, _, _ = lazy.attach(__name__, submod_attrs={"experiment": ["run"], "figures": ["plot"],
                                                        "kind": ["sweep_cell"], "envelope_figures": ["plot_sweep"]})
