"""Flying a plan (formation.execution) on the six-spacecraft scenario."""

import numpy as np
import pytest

from formation.constraints import evaluate
from formation.execution import circulating_slot_states, states_along_plan
from formation.reconfiguration import choose_movers, drift_free_slot_states, plan
from formation.scenarios import six_spacecraft_scenario
from orbits.cw import propagate


@pytest.fixture(scope="module")
def planned():
    s = six_spacecraft_scenario()
    slots = drift_free_slot_states(s.slots.r_CT_H, s.n)
    tf = 0.6 * s.period_s
    movers, slot_of = choose_movers(s.x0_H, slots, tf, s.n)
    others = np.setdiff1d(np.arange(6), movers)
    p = plan(s.x0_H[movers], slots[slot_of], n=s.n, tf_s=tf, assign=False, others_x0_H=s.x0_H[others])
    assert p.ok, p.failure_reason
    return s, s.x0_H[movers], slots[slot_of], p


def test_states_reproduce_the_planned_trajectory_on_its_check_grid(planned):
    s, x0, _, p = planned
    x = states_along_plan(x0, p, p.t_grid_s, n=s.n)
    np.testing.assert_allclose(x[..., :3], p.trajectory_H[..., :3], atol=1e-7)
    np.testing.assert_allclose(x[..., 3:], p.trajectory_H[..., 3:], atol=1e-10)


def test_after_arrival_the_spacecraft_coast_on_their_slot_orbits(planned):
    s, x0, slots, p = planned
    tf = p.impulse_times_s[-1]
    t = tf + np.array([0.0, 100.0, 0.4 * s.period_s, s.period_s])
    x = states_along_plan(x0, p, t, n=s.n)
    np.testing.assert_allclose(x, propagate(slots, t - tf, s.n), atol=1e-7)
    # drift-free: one orbit later every spacecraft is back in its slot
    np.testing.assert_allclose(x[:, -1, :3], slots[:, :3], atol=1e-6)


def test_negative_times_and_mismatched_states_are_rejected(planned):
    s, x0, _, p = planned
    with pytest.raises(ValueError, match="t_s"):
        states_along_plan(x0, p, [-1.0, 3.0], n=s.n)
    with pytest.raises(ValueError, match="x0_H"):
        states_along_plan(x0[:2], p, [1.0], n=s.n)


def test_drift_free_slots_collapse_at_quarter_orbit_and_circulating_slots_hold_the_cone():
    """Analytic: with (0, −2nx, 0) the offsets x, z scale by cos nt, so at nt = 90° the three
    trailing cameras line up along-track (pairwise axis angles 0); circulating offsets keep their
    length, and the set passes every constraint over a whole orbit."""
    s = six_spacecraft_scenario()
    r = s.slots.r_CT_H
    quarter = np.array([0.25 * s.period_s])
    x_df = propagate(drift_free_slot_states(r, s.n), quarter, s.n)[:, 0]
    np.testing.assert_allclose(x_df[:, [0, 2]], 0.0, atol=1e-9)
    t = np.arange(0.0, s.period_s, 10.0)
    x_c = propagate(circulating_slot_states(r, s.n), t, s.n)
    rho = np.linalg.norm(x_c[..., [0, 2]], axis=-1)
    np.testing.assert_allclose(rho / np.linalg.norm(r[:, [0, 2]], axis=-1)[:, None], 1.0, rtol=1e-9)
    np.testing.assert_allclose(x_c[..., 4], -2 * s.n * x_c[..., 0], atol=1e-12)  # drift-free all along
    ev = evaluate(s.constraints, np.swapaxes(x_c[..., :3], 0, 1))
    assert ev.set_ok([0, 1, 2]).all()
    ev_df = evaluate(s.constraints, np.swapaxes(propagate(drift_free_slot_states(r, s.n), t, s.n)[..., :3], 0, 1))
    assert not ev_df.set_ok([0, 1, 2]).all()
