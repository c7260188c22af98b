"""Experiments: configs, scenarios, sweeps, result datasets, plots, the ``coobs`` CLI, benchmarks.

This is the only package that does I/O, plotting, Dask and printing; the science packages below it
are pure functions over numpy arrays (ARCHITECTURE §1).
"""
