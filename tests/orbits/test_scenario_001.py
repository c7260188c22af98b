"""Tests of orbits.scenario_001: paper 001 Table 1 geometry and the facts derived from it."""

from __future__ import annotations

import numpy as np

from orbits import cw
from orbits.scenario_001 import CHASER_001, TARGET_001, scenario_001_geometry
from orbits.two_body import elements_from_state, propagate_kepler


def test_relative_range_98_8_to_101_5_m_over_6000_s():
    """Derived from 001 Table 1 (Keplerian): relative range 98.8–101.5 m over 0–6000 s (5 s steps), radial
    offset within ±0.67 m, cross-track within ±0.59 m, target ≈100 m ahead along-track."""
    g = scenario_001_geometry()
    assert g.t_s.shape == (1201,) and g.t_s[-1] == 6000.0
    assert round(g.range_m.min(), 1) == 98.8 and round(g.range_m.max(), 1) == 101.5
    x = g.x_target_chaser_Hc
    assert round(np.abs(x[:, 0]).max(), 2) == 0.67
    assert round(np.abs(x[:, 2]).max(), 2) == 0.59
    assert np.all((x[:, 1] > 98.7) & (x[:, 1] < 101.5))  # target ahead along-track
    # In the target's frame the chaser trails.
    assert np.all(g.x_chaser_target_H[:, 1] < -98.7)


def test_table1_states_have_table1_elements():
    for orbit in (CHASER_001, TARGET_001):
        r, v = orbit.state_N(np.array([1000.0]))
        el = elements_from_state(r[0], v[0])
        assert abs(el.a_m - 6721.2e3) < 1e-4
        assert abs(el.i_rad - orbit.i_rad) < 1e-13
        assert abs(el.e - orbit.e) < 1e-12
    # Node passage: the chaser is on the equator, ascending, at t = 0.013 s; the target at 0.
    r, v = CHASER_001.state_N(np.array([0.013]))
    assert abs(r[0, 2]) < 1e-6 and v[0, 2] > 0
    r, v = TARGET_001.state_N(np.array([0.0]))
    assert abs(r[0, 2]) < 1e-9 and v[0, 2] > 0


def test_scenario_states_are_keplerian():
    """The element-built trajectory equals Kepler propagation of its initial state."""
    g = scenario_001_geometry(np.linspace(0, 6000, 13))
    r, _ = propagate_kepler(g.r_chaser_N[0], g.v_chaser_N[0], g.t_s)
    np.testing.assert_allclose(r, g.r_chaser_N, atol=1e-6)


def test_cw_tracks_001_relative_motion_to_3cm():
    """The target's orbit is circular, so CW from the initial relative state reproduces the
    two-body relative trajectory up to the ρ²/a curvature term: ≤ 3 cm over 6000 s at 100 m."""
    g = scenario_001_geometry()
    x_cw = cw.propagate(g.x_chaser_target_H[0], g.t_s, cw.mean_motion(6721.2e3))
    err = np.linalg.norm(x_cw[:, :3] - g.x_chaser_target_H[:, :3], axis=-1)
    assert err.max() < 0.03
