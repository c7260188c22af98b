"""Parameter sweeps on Dask: a grid over config keys × trials, streamed cell by cell to a zarr store."""

from experiments.sweep.cell import Metric, SweepCell
from experiments.sweep.runner import SweepReport, run_sweep
from experiments.sweep.seeds import cell_seed_sequences, child_seeds
from experiments.sweep.spec import GridRange, SweepSpec, parse_overrides
from experiments.sweep.store import STORE_NAME, open_sweep
from experiments.sweep.summary import redraw, sweep_summary

__all__ = [
    "Metric",
    "SweepCell",
    "SweepReport",
    "SweepSpec",
    "GridRange",
    "STORE_NAME",
    "run_sweep",
    "open_sweep",
    "parse_overrides",
    "sweep_summary",
    "cell_seed_sequences",
    "child_seeds",
    "redraw",
]
