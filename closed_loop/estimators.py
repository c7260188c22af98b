"""Estimators: the attitude filters the loop can run, by the names the configs use."""

from __future__ import annotations

import numpy as np

from closed_loop.registry import Registry
from filters import MEKF, AttitudeEKF, AttitudeFilter, FilterState

__all__ = ["ESTIMATORS", "initial_estimate"]

#: filter name (config ``estimator.filter``) → class; each is built as ``cls(J_kg_m2=J)``
ESTIMATORS: Registry[type[AttitudeFilter]] = Registry("estimator", {"ekf": AttitudeEKF, "mekf": MEKF})


def initial_estimate(estimator: AttitudeFilter, q_NT0: np.ndarray, omega_TN_T0_rad_s: np.ndarray, *,
                     sigma_q: float, sigma_omega_rad_s: float, rng: np.random.Generator, t_s: float = 0.0,
                     attitude_known: bool = True) -> FilterState:
    """The filter's starting state: the truth perturbed as in 003 eq (35).

    Parameters
    ----------
    estimator : filters.AttitudeFilter
    q_NT0 : ndarray (4,)
        True initial attitude, scalar-first.
    omega_TN_T0_rad_s : ndarray (3,)
        True initial body rate, rad/s.
    sigma_q : float
        Initial quaternion σ per component (also the covariance's).
    sigma_omega_rad_s : float
        Initial rate σ, rad/s.
    rng : numpy.random.Generator
        The initial-estimate stream: 4 quaternion draws (only when the attitude is not known), then
        3 rate draws.
    t_s : float
        Epoch of the state, s.
    attitude_known : bool
        The first frame defines the body frame (flag P003-14a, docs/papers.md#p003-14a): start at
        ``q_NT0`` exactly (with ``sigma_q`` as its uncertainty); else add ``N(0, sigma_q²)`` per
        component (003 eq 35).

    Returns
    -------
    filters.FilterState
        A batch of one, without a clone (the loop clones it).
    """
    q0 = np.array(q_NT0, dtype=float) if attitude_known else q_NT0 + rng.normal(size=4) * sigma_q
    w0 = omega_TN_T0_rad_s + rng.normal(size=3) * sigma_omega_rad_s
    P0 = estimator.initial_covariance(sigma_q=sigma_q, sigma_omega_rad_s=sigma_omega_rad_s)
    return estimator.initial_state(q0, w0, P0, t_s=t_s)
