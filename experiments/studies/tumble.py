"""The truth motion of a torque-free tumbling target: attitude, rate and the drift of its invariants."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from attitude.euler import euler_from_matrix
from attitude.quaternion import matrix_from_quat
from attitude.rigid_body import (
    angular_momentum_N,
    check_inertia,
    kinetic_energy,
    propagate_torque_free,
)

__all__ = ["TumbleHistory", "tumble_history"]


@dataclass(frozen=True)
class TumbleHistory:
    """A torque-free tumble sampled at fixed steps, from ``q_NT = [1, 0, 0, 0]``.

    Attributes
    ----------
    t_s : ndarray, shape (T,)
        Sample times, s.
    ypr_rad : ndarray, shape (T, 3)
        3-2-1 Euler angles (yaw, pitch, roll) of ``R_NT``, rad.
    omega_TN_T_rad_s : ndarray, shape (T, 3)
        Body rate in target axes, rad/s.
    momentum_drift : float
        ``max |L_N(t) − L_N(0)| / |L_N(0)|`` (relative; exactly conserved, so a check of the propagator).
    energy_drift : float
        ``max |E(t) − E(0)| / E(0)`` (relative).
    """

    t_s: np.ndarray
    ypr_rad: np.ndarray
    omega_TN_T_rad_s: np.ndarray
    momentum_drift: float
    energy_drift: float


def tumble_history(J_kg_m2: np.ndarray, omega0_TN_T_rad_s: np.ndarray, *, duration_s: float,
                   step_s: float, inertia_name: str = "J_kg_m2") -> TumbleHistory:
    """Propagate a torque-free rigid body exactly and sample it every ``step_s`` up to ``duration_s``.

    Parameters
    ----------
    J_kg_m2 : ndarray, shape (3, 3)
        Inertia in target axes, kg·m² (checked: symmetric, positive, triangle inequality).
    omega0_TN_T_rad_s : ndarray, shape (3,)
        Initial body rate, rad/s.
    duration_s, step_s : float
        Duration and output step, s (both > 0).
    inertia_name : str
        Name of the inertia in error messages.

    Returns
    -------
    TumbleHistory

    Raises
    ------
    ValueError
        Bad inertia (naming ``inertia_name``), or a non-positive duration or step.
    """
    check_inertia(J_kg_m2, name=inertia_name)
    if duration_s <= 0:
        raise ValueError(f"duration_s: must be positive, got {duration_s}")
    if step_s <= 0:
        raise ValueError(f"step_s: must be positive, got {step_s}")
    t = np.arange(0.0, duration_s + 0.5 * step_s, step_s)
    q, w = propagate_torque_free(np.array([1.0, 0, 0, 0]), np.asarray(omega0_TN_T_rad_s, dtype=float), J_kg_m2, t)
    ypr, _ = euler_from_matrix(matrix_from_quat(q), "321")
    L = angular_momentum_N(q, w, J_kg_m2)
    E = kinetic_energy(w, J_kg_m2)
    return TumbleHistory(t_s=t, ypr_rad=ypr, omega_TN_T_rad_s=w,
                         momentum_drift=float(np.abs(L - L[0]).max() / np.linalg.norm(L[0])),
                         energy_drift=float(np.abs(E - E[0]).max() / E[0]))
