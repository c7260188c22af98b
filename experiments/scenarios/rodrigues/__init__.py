"""Scenario kind ``rodrigues_001``: paper 001's monocular relative pose over 6000 s, against OpenCV and pycolmap."""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader as lazy

from experiments.scenarios.rodrigues.config import Config
from experiments.scenarios.rodrigues.truth import (
    R_HO,
    crossing_times_s,
    cube_vertices,
    truth_001,
    visible_vertices,
)

if TYPE_CHECKING:
    from experiments.scenarios.rodrigues.envelope import sweep_cell
    from experiments.scenarios.rodrigues.envelope_figures import plot_sweep
    from experiments.scenarios.rodrigues.experiment import SOLVERS, run
    from experiments.scenarios.rodrigues.figures import plot

__all__ = ["Config", "run", "plot", "sweep_cell", "plot_sweep", "SOLVERS", "R_HO", "truth_001", "crossing_times_s", "cube_vertices",
           "visible_vertices"]

# run, plot and the sweep (OpenCV and pycolmap behind them) load on first use
__getattr__, _, _ = lazy.attach(__name__, submod_attrs={"experiment": ["run", "SOLVERS"], "figures": ["plot"],
                                                           "envelope": ["sweep_cell"],
                                                           "envelope_figures": ["plot_sweep"]})
