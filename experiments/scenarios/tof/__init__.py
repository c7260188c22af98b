"""Scenario kind ``tof_000``: paper 000's TOF-camera pose of a cooperative marker target."""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader as lazy

from experiments.scenarios.tof.config import MATCHERS, MATCHING_CASES, Config

if TYPE_CHECKING:
    from experiments.scenarios.tof.experiment import TABLE1_000, run, table1_stats
    from experiments.scenarios.tof.figures import plot

__all__ = ["Config", "run", "plot", "MATCHING_CASES", "MATCHERS", "TABLE1_000", "table1_stats"]

# run and plot (and the science behind them) load on first use
__getattr__, _, _ = lazy.attach(
    __name__, submod_attrs={"experiment": ["run", "TABLE1_000", "table1_stats"], "figures": ["plot"]}
)
