"""coobs: a formation of spacecraft observing a tumbling, non-cooperative target, from Python.

The calls a notebook needs, over the scenario kinds of :mod:`experiments`:

- :func:`configs` — the bundled configs, by name, one line each;
- :func:`run` — one scenario (a bundled name, a TOML file, a table or a config, plus dotted-key
  overrides) → :class:`RunResult` with ``.dataset`` (xarray), ``.summary`` and ``.plot()``;
- :func:`sweep` — a config's ``[sweep]`` table on Dask → the sweep's xarray dataset;
- :func:`plot` — the figures of a run's, a sweep's or a filter study's dataset, or of an output folder.

The science packages (``attitude``, ``orbits``, ``vision``, ``filters``, ``reconstruction``,
``formation``, ``chaser``, ``closed_loop``) stay importable on their own: the closed loop can be
built from its parts without any config (docs/architecture.md).  The ``coobs`` command line
(:mod:`coobs.cli`, also ``python -m coobs``) is a thin layer over these calls.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _dist_version

from coobs.api import Configs, RunResult, configs, plot, run, sweep
from experiments.config import ConfigError

try:
    __version__: str = _dist_version("coobs")
except PackageNotFoundError:  # a source tree that was never installed
    __version__ = "0+unknown"

__all__ = ["__version__", "ConfigError", "Configs", "RunResult", "configs", "plot", "run", "sweep"]
