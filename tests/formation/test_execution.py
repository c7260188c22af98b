"""Flying a plan (formation.execution) on the six-spacecraft scenario."""

import numpy as np
import pytest

from formation.execution import states_along_plan
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
    assert p.success, p.status
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
