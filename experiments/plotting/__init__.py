"""Plot primitives and the generic sweep overview, drawn with matplotlib (Agg) from stored results."""

from experiments.plotting.primitives import (
    axes_or_new,
    plot_band,
    plot_cloud,
    plot_histogram,
    plot_image_tracks,
    plot_map,
    plot_time_series,
    plot_timeline,
    save,
)
from experiments.plotting.sweep_overview import sweep_overview_figures

__all__ = [
    "axes_or_new",
    "plot_map",
    "plot_band",
    "plot_time_series",
    "plot_timeline",
    "plot_image_tracks",
    "plot_cloud",
    "plot_histogram",
    "save",
    "sweep_overview_figures",
]
