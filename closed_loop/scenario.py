"""The truth the loop observes: a torque-free tumbling target on a circular orbit, as plain arrays.

The target tumbles torque-free (:func:`attitude.rigid_body.propagate_torque_free`) with attitude
``q_NT``; the Hill frame H turns at the orbit rate n about N's z axis, ``R_NH(t) = R_z(n t)``
(:func:`filters.hill_frame_rotation`), so the target's attitude in the observation frame is
``q_HT = q_NH⁻¹ ⊗ q_NT``.  The Sun is fixed in N (its H direction turns with the orbit), and the
target is in Earth's shadow when :func:`orbits.environment.illumination_fraction` says so.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from attitude.quaternion import quat_conjugate, quat_from_matrix, quat_multiply
from attitude.rigid_body import propagate_torque_free
from filters import hill_frame_rotation
from orbits.cw import mean_motion
from orbits.environment import AU_M, illumination_fraction

__all__ = ["TumblingTarget", "tumbling_target"]


@dataclass(frozen=True)
class TumblingTarget:
    """Truth of a run over ``T`` epochs.

    Attributes
    ----------
    t_s : ndarray (T,)
        Epochs, s.
    q_NT : ndarray (T, 4)
        Attitude of the target in the inertial frame N, scalar-first.
    omega_TN_T_rad_s : ndarray (T, 3)
        Body rate, rad/s.
    n_rad_s : float
        Mean motion of the orbit.
    R_NH : ndarray (T, 3, 3)
        Hill frame in N.
    q_HT : ndarray (T, 4)
        Attitude of the target in H (what the cameras see).
    sun_H : ndarray (T, 3)
        Unit direction to the Sun in H.
    illumination : ndarray (T,)
        Visible fraction of the solar disc from the target (0 in Earth's shadow).
    """

    t_s: np.ndarray
    q_NT: np.ndarray
    omega_TN_T_rad_s: np.ndarray
    n_rad_s: float
    R_NH: np.ndarray
    q_HT: np.ndarray
    sun_H: np.ndarray
    illumination: np.ndarray


def tumbling_target(t_s: np.ndarray, q_NT0: np.ndarray, omega_TN_T0_rad_s: np.ndarray, J_kg_m2: np.ndarray, *,
                    orbit_radius_m: float, sun_N: np.ndarray) -> TumblingTarget:
    """Propagate the target and its orbit over the epochs ``t_s``.

    Parameters
    ----------
    t_s : ndarray (T,)
        Epochs, s.
    q_NT0 : ndarray (4,)
        Initial attitude (003 eq 34), scalar-first.
    omega_TN_T0_rad_s : ndarray (3,)
        Initial body rate, rad/s.
    J_kg_m2 : ndarray (3, 3)
        Inertia tensor.
    orbit_radius_m : float
        Radius of the target's circular orbit.
    sun_N : ndarray (3,)
        Direction to the Sun in N (any length).

    Returns
    -------
    TumblingTarget
    """
    t = np.asarray(t_s, dtype=float)
    q_NT, w_T = propagate_torque_free(np.asarray(q_NT0), omega_TN_T0_rad_s, J_kg_m2, t)
    n = float(mean_motion(orbit_radius_m))
    R_NH = hill_frame_rotation(t, n)
    q_HT = quat_multiply(quat_conjugate(quat_from_matrix(R_NH)), q_NT)
    sun = np.asarray(sun_N, dtype=float)
    sun = sun / np.linalg.norm(sun)
    lit = illumination_fraction(R_NH @ np.array([orbit_radius_m, 0.0, 0.0]), sun * AU_M)
    sun_H = np.einsum("tji,j->ti", R_NH, sun)
    return TumblingTarget(t_s=t, q_NT=q_NT, omega_TN_T_rad_s=w_T, n_rad_s=n, R_NH=R_NH, q_HT=q_HT, sun_H=sun_H,
                          illumination=lit)
