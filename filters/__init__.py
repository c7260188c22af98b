"""Batched attitude and spin estimation of a tumbling target: EKF, MEKF, Monte Carlo, metrics."""

from ._base import AttitudeFilter
from .attitude_ekf import AttitudeEKF
from .dynamics import inertia_from_ratios, inertia_ratios_from_inertia, propagate_rk4
from .measurements import AbsoluteAttitudeMeasurement, IncrementMeasurement
from .mekf import MEKF
from .metrics import (
    ConvergenceCriterion,
    attitude_error_angle,
    convergence_time,
    euler_angle_error,
    nees,
    nees_band,
    rate_error,
    speed_score,
)
from .monte_carlo import (
    MeasurementModel,
    MeasurementSeries,
    MonteCarloResult,
    draw_initial_estimates,
    hill_frame_rotation,
    run_monte_carlo,
    simulate_measurements,
)
from .noise_mapping import quat_noise_covariance, rotvec_covariance_from_angle_error
from .state import FilterState, ProcessNoise

__all__ = [
    "AttitudeFilter",
    "AttitudeEKF",
    "IncrementMeasurement",
    "AbsoluteAttitudeMeasurement",
    "MEKF",
    "FilterState",
    "ProcessNoise",
    "propagate_rk4",
    "inertia_from_ratios",
    "inertia_ratios_from_inertia",
    "ConvergenceCriterion",
    "attitude_error_angle",
    "euler_angle_error",
    "rate_error",
    "convergence_time",
    "nees",
    "nees_band",
    "speed_score",
    "MeasurementModel",
    "MeasurementSeries",
    "MonteCarloResult",
    "draw_initial_estimates",
    "simulate_measurements",
    "hill_frame_rotation",
    "run_monte_carlo",
    "quat_noise_covariance",
    "rotvec_covariance_from_angle_error",
]
