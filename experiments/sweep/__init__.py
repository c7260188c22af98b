"""Parameter sweeps on Dask: a grid over config keys × trials, streamed cell by cell to a zarr store.

A sweep evaluates one cell function (:class:`SweepCell`) at every point of a grid, ``trials`` times
per point, with reproducible per-trial streams (:func:`cell_seed_sequences`); each finished cell is
written at once, so a sweep can be resumed; failures become rows with a ``failure_reason``.
"""

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
