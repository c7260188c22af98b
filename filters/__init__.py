"""Attitude and spin estimation of a tumbling target (ARCHITECTURE §1; paper 003 §2).

* :class:`AttitudeEKF` — the paper's 7-state additive-quaternion EKF (003 eq 14–32).
* :class:`MEKF` — multiplicative (error-state) EKF, optionally estimating two inertia ratios.
* Both take absolute attitudes (:meth:`update_absolute`) and registration increments measured in
  the rotating Hill frame (:meth:`update_increment`, stochastic cloning), gate outliers, skip
  missing epochs, and flag trials whose covariance stops being positive definite.
* :func:`run_monte_carlo` — M filters at once, one random stream per trial.
* :mod:`filters.metrics` — 003 eq (36)–(37), rotation-angle error, convergence, NEES, SPEED score.
* :mod:`filters.noise_mapping` — rotation-vector covariance to quaternion covariance (UT).

Every estimate is batched: states hold ``(M, ...)`` arrays and a single filter is a batch of one.
"""

from .attitude_ekf import AttitudeEKF
from .dynamics import inertia_from_ratios, inertia_ratios_from_inertia, propagate_rk4
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
    "AttitudeEKF",
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
