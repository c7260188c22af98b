"""Orbital motion of the formation: Hill frame, Clohessy–Wiltshire relative motion, two-body truth, Sun and eclipse."""

from orbits.cw import (
    TwoImpulseTransfer,
    apply_impulse,
    bounded_orbit_state,
    mean_motion,
    natural_motion_circumnavigation,
    passive_safety_ellipse,
    propagate,
    stm,
    two_impulse_transfer,
)
from orbits.environment import (
    illumination_fraction,
    shadow_region,
    sun_direction_H,
    sun_direction_N,
)
from orbits.hill import hill_angular_velocity, hill_frame, hill_from_inertial, inertial_from_hill
from orbits.scenario_001 import scenario_001_geometry
from orbits.two_body import (
    MU_EARTH_M3_S2,
    R_EARTH_M,
    OrbitalElements,
    elements_from_state,
    orbital_period_s,
    propagate_kepler,
    relative_trajectory,
    state_from_elements,
)

__all__ = [
    "hill_frame",
    "hill_angular_velocity",
    "hill_from_inertial",
    "inertial_from_hill",
    "MU_EARTH_M3_S2",
    "R_EARTH_M",
    "OrbitalElements",
    "state_from_elements",
    "elements_from_state",
    "orbital_period_s",
    "propagate_kepler",
    "relative_trajectory",
    "mean_motion",
    "stm",
    "propagate",
    "apply_impulse",
    "TwoImpulseTransfer",
    "two_impulse_transfer",
    "bounded_orbit_state",
    "natural_motion_circumnavigation",
    "passive_safety_ellipse",
    "sun_direction_N",
    "sun_direction_H",
    "illumination_fraction",
    "shadow_region",
    "scenario_001_geometry",
]
