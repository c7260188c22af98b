"""Reference formation scenarios used by tests, configs and docs."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from attitude.quaternion import quat_from_axis_angle
from formation.constraints import ObservationConstraints
from formation.geometry import ViewGeometry, symmetric_views
from orbits.cw import bounded_orbit_state, mean_motion

__all__ = ["SixSpacecraftScenario", "six_spacecraft_scenario"]


@dataclass(frozen=True)
class SixSpacecraftScenario:
    """Six observers on bounded CW orbits about a target on a 6721.2 km circular orbit.

    Attributes
    ----------
    n : float
        Mean motion, rad/s.
    period_s : float
    x0_H : (6, 6) ndarray
        Initial relative states (H, m and m/s).
    constraints : ObservationConstraints
    slots : ViewGeometry
        The wanted 3-view geometry: 60 m behind the target along-track, 10° between optical axes.
    """

    n: float
    period_s: float
    x0_H: np.ndarray
    constraints: ObservationConstraints
    slots: ViewGeometry


def six_spacecraft_scenario() -> SixSpacecraftScenario:
    """The reconfiguration scenario of the formation issue: only spacecraft 0 can observe at t = 0.

    Spacecraft 0 circles the target on a 35 m × 70 m natural-motion ellipse centred 55 m behind it;
    the others fly larger bounded orbits whose centres are 180–900 m away along-track, out of the
    150 m range window.
    """
    a_m = 6721.2e3
    n = float(mean_motion(a_m))
    x0 = bounded_orbit_state(
        n=n,
        radial_amplitude_m=np.array([10.0, 40.0, 60.0, 30.0, 50.0, 80.0]),
        phase_rad=np.array([0.3, 1.0, 2.0, 3.0, 4.0, 5.0]),
        cross_track_amplitude_m=np.array([8.0, 30.0, 40.0, 20.0, 60.0, 50.0]),
        cross_track_phase_rad=np.full(6, -np.pi / 2),
        along_track_offset_m=np.array([-55.0, -180.0, 300.0, -320.0, 500.0, -900.0]),
    )
    # cone axis along −y_H: the observers trail the target (q_HG turns z_G onto −y_H)
    slots = symmetric_views(3, 60.0, 10.0, orientation=quat_from_axis_angle([1.0, 0.0, 0.0], np.pi / 2))
    return SixSpacecraftScenario(n=n, period_s=2 * np.pi / n, x0_H=x0,
                                 constraints=ObservationConstraints(), slots=slots)
