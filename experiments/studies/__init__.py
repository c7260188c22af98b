"""Studies outside the scenario kinds: the filter validation, the tumble, the noise convention, the docs figures."""

from experiments.studies.filter_study import STUDIES, run_studies
from experiments.studies.noise_calibration import (
    ATTITUDE_NOISE_CELL,
    attitude_noise_cell,
    axis_sigma_rad,
    perturb_attitude,
)
from experiments.studies.tumble import TumbleHistory, tumble_history

__all__ = [
    "STUDIES",
    "run_studies",
    "ATTITUDE_NOISE_CELL",
    "attitude_noise_cell",
    "axis_sigma_rad",
    "perturb_attitude",
    "TumbleHistory",
    "tumble_history",
]
