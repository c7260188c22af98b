"""Orbit geometry of paper 001's simulation (001 Table 1).

Both spacecraft are on 6721.2 km orbits inclined ≈42.225°, RAAN 0.  The chaser has e = 1e-7,
argument of perigee 0 and passes the ascending node 0.013 s *after* the target, so the target
leads by ≈100 m along-track; the chaser's inclination is 5e-6° higher (±0.59 m cross-track).
001 gives times of node passage, not anomalies; here the time of node passage fixes the mean anomaly,
``M = n (t − t_node)``, with the argument of latitude 0 at node passage (for the chaser, perigee
is at the node).  Propagation is Keplerian two-body with μ = 398600.4418 km³/s².

Facts derived from Table 1 by Keplerian propagation and reproduced here: over 0–6000 s the
relative range stays within 98.8–101.5 m, the radial offset within ±0.67 m, the cross-track
offset within ±0.59 m; the period is 5483.8 s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from orbits._checks import check_times
from orbits.cw import mean_motion
from orbits.hill import hill_from_inertial
from orbits.two_body import MU_EARTH_M3_S2, state_from_elements, true_from_mean_anomaly

__all__ = ["Table1Orbit", "CHASER_001", "TARGET_001", "Scenario001Geometry", "scenario_001_geometry",
           "DURATION_001_S", "STEP_001_S"]

#: Simulation length and step of paper 001 (stated in 001).
DURATION_001_S = 6000.0
STEP_001_S = 5.0


@dataclass(frozen=True)
class Table1Orbit:
    """One column of 001 Table 1 (orbit part), SI units.

    Attributes
    ----------
    a_m, e, i_rad, raan_rad, argp_rad : float
        Classical elements (the target's "—" argument of perigee is 0: circular orbit, u measured
        from the node).
    t_node_s : float
        Time of ascending-node passage (s from the scenario epoch).
    """

    a_m: float
    e: float
    i_rad: float
    raan_rad: float
    argp_rad: float
    t_node_s: float

    def state_N(self, t_s: ArrayLike, *, mu_m3_s2: float = MU_EARTH_M3_S2) -> tuple[np.ndarray, np.ndarray]:
        """Inertial position (m) and velocity (m/s), shapes ``(T, 3)``, at epochs ``t_s`` (T,).

        ``M = n (t − t_node)`` then Kepler's equation for ν (argument of perigee at the node).
        """
        t = check_times(t_s)
        n = float(mean_motion(self.a_m, mu_m3_s2=mu_m3_s2))
        nu = true_from_mean_anomaly(n * (t - self.t_node_s), self.e)
        return state_from_elements(self.a_m, self.e, self.i_rad, self.raan_rad, self.argp_rad, nu,
                                   mu_m3_s2=mu_m3_s2)


#: 001 Table 1, chaser (主动航天器).
CHASER_001 = Table1Orbit(a_m=6721.2e3, e=1e-7, i_rad=float(np.radians(42.225005)), raan_rad=0.0,
                         argp_rad=0.0, t_node_s=0.013)
#: 001 Table 1, target (目标航天器).
TARGET_001 = Table1Orbit(a_m=6721.2e3, e=0.0, i_rad=float(np.radians(42.225)), raan_rad=0.0,
                         argp_rad=0.0, t_node_s=0.0)


@dataclass(frozen=True)
class Scenario001Geometry:
    """States of paper 001's chaser and target over time, and their relative motion.

    Attributes
    ----------
    t_s : ndarray, shape (T,)
        Epochs (s).
    r_chaser_N, v_chaser_N, r_target_N, v_target_N : ndarray, shape (T, 3)
        Inertial states (m, m/s).
    x_chaser_target_H : ndarray, shape (T, 6)
        Chaser relative to the target in the *target's* Hill frame H (coobs convention,
        ``docs/conventions.md``), ``[r, v]`` (m, m/s; rotating-frame velocity).
    x_target_chaser_Hc : ndarray, shape (T, 6)
        Target relative to the chaser in the *chaser's* Hill frame (x radial, y along-track,
        z normal): the frame in which 001 reports its position errors (flag P001-4 (docs/papers.md#p001-4), whose X is
        this frame's y).
    range_m : ndarray, shape (T,)
        Chaser–target distance (m).
    """

    t_s: np.ndarray
    r_chaser_N: np.ndarray
    v_chaser_N: np.ndarray
    r_target_N: np.ndarray
    v_target_N: np.ndarray
    x_chaser_target_H: np.ndarray
    x_target_chaser_Hc: np.ndarray
    range_m: np.ndarray


def scenario_001_geometry(t_s: ArrayLike | None = None, *,
                          mu_m3_s2: float = MU_EARTH_M3_S2) -> Scenario001Geometry:
    """Chaser and target states of 001 Table 1 and their relative trajectory.

    Parameters
    ----------
    t_s : array_like, shape (T,), optional
        Epochs (s); default the paper's 0–6000 s at 5 s (1201 epochs).
    mu_m3_s2 : float, keyword-only
        Gravitational parameter (m³/s²).

    Returns
    -------
    Scenario001Geometry
    """
    t = np.arange(0.0, DURATION_001_S + STEP_001_S / 2, STEP_001_S) if t_s is None else check_times(t_s)
    r_c, v_c = CHASER_001.state_N(t, mu_m3_s2=mu_m3_s2)
    r_t, v_t = TARGET_001.state_N(t, mu_m3_s2=mu_m3_s2)
    rho, rho_dot = hill_from_inertial(r_t, v_t, r_c, v_c)
    rho_c, rho_dot_c = hill_from_inertial(r_c, v_c, r_t, v_t)
    return Scenario001Geometry(
        t_s=t, r_chaser_N=r_c, v_chaser_N=v_c, r_target_N=r_t, v_target_N=v_t,
        x_chaser_target_H=np.concatenate([rho, rho_dot], axis=-1),
        x_target_chaser_Hc=np.concatenate([rho_c, rho_dot_c], axis=-1),
        range_m=np.linalg.norm(r_c - r_t, axis=-1),
    )
