"""Scenario kind ``formation`` (paper 003): the closed loop, Experiment A and Experiments B–D from one config."""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader as lazy

from experiments.scenarios.formation.config import Config

if TYPE_CHECKING:
    from experiments.scenarios.formation.kind import (
        STUDIES,
        SWEEP_CELLS,
        plot,
        plot_sweep,
        run,
        sweep_cell,
    )

__all__ = ["Config", "run", "plot", "sweep_cell", "plot_sweep", "SWEEP_CELLS", "STUDIES"]

# the kind protocol (and the science behind it) loads on first use
__getattr__, _, _ = lazy.attach(__name__, submod_attrs={"kind": [name for name in __all__ if name != "Config"]})
