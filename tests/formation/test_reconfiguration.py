"""Minimum-fuel reconfiguration (casadi/IPOPT): the six-spacecraft scenario of the formation issue."""

import numpy as np
import pytest

from formation.constraints import evaluate
from formation.reconfiguration import choose_movers, drift_free_slot_states, lower_bound, plan
from formation.scenarios import six_spacecraft_scenario
from orbits.cw import propagate


@pytest.fixture(scope="module")
def scenario():
    return six_spacecraft_scenario()


def test_only_one_spacecraft_satisfies_the_constraints_at_t0(scenario):
    ev = evaluate(scenario.constraints, scenario.x0_H[None, :, :3])
    assert list(ev.single_ok[0]) == [True, False, False, False, False, False]


def test_plan_brings_three_into_a_valid_3_view_geometry_within_one_orbit(scenario):
    s = scenario
    slots = drift_free_slot_states(s.slots.r_CT_H, s.n)
    tf = 0.6 * s.period_s
    movers, slot_of = choose_movers(s.x0_H, slots, tf, s.n)
    others = np.setdiff1d(np.arange(6), movers)
    p = plan(s.x0_H[movers], slots[slot_of], n=s.n, tf_s=tf, assign=False, n_impulses=6,
             dv_max_m_s=1.0, keep_out_radius_m=20.0, min_separation_m=5.0, others_x0_H=s.x0_H[others])
    assert p.ok, p.failure_reason
    # every path constraint on the 1 s grid, the Δv limit at every impulse, the final states
    assert np.diff(p.t_grid_s).max() <= 1.0 + 1e-9 and p.t_grid_s[-1] == pytest.approx(tf, abs=1.0)
    assert p.margins["keep_out"].min() >= -1e-6
    assert p.margins["separation"].min() >= -1e-6
    assert p.margins["dv_limit"].min() >= -1e-9
    assert p.margins["final_state"].max() < 1e-6
    # independent propagation of the impulses reproduces the planned trajectory
    x = s.x0_H[movers].copy()
    t_prev = 0.0
    for j, tj in enumerate(p.impulse_times_s):
        x = propagate(x, [tj - t_prev], s.n)[:, 0]
        x[:, 3:] += p.impulses_H[:, j]
        t_prev = tj
    np.testing.assert_allclose(x, slots[slot_of], atol=1e-6)
    # the arrival geometry satisfies every observation constraint
    ev = evaluate(s.constraints, x[None, :, :3])
    assert ev.set_ok([0, 1, 2])[0]
    # within 5 % of the convex lower bound (no keep-out, no separation) for the same nodes
    lb = lower_bound(s.x0_H[movers], slots[slot_of], n=s.n, tf_s=tf, n_impulses=6)
    assert lb * (1 - 1e-9) <= p.dv_total_m_s <= 1.05 * lb


def test_binding_keep_out_is_respected_on_the_fine_grid(scenario):
    """Spacecraft ahead of the target must pass it to reach trailing slots: keep-out and separation bind."""
    s = scenario
    n = s.n
    x0 = np.array([[0.0, 90.0, 0.0, 0.0, 0.0, 0.0], [2.0, 120.0, -3.0, 0.0, -4.0 * n, 0.0],
                   [-1.0, 70.0, 2.0, 0.0, 2.0 * n, 0.0]])
    slots = drift_free_slot_states(s.slots.r_CT_H, n)
    tf = 0.3 * s.period_s
    p = plan(x0, slots, n=n, tf_s=tf, n_impulses=8, dv_max_m_s=0.5, keep_out_radius_m=20.0, min_separation_m=5.0)
    assert p.ok, p.failure_reason
    assert p.margins["keep_out"].min() >= -1e-6 and p.margins["separation"].min() >= -1e-6
    lb = lower_bound(x0, slots[p.assignment], n=n, tf_s=tf, n_impulses=8, dv_max_m_s=0.5)
    assert lb * (1 - 1e-9) <= p.dv_total_m_s <= 1.05 * lb


def test_infeasible_request_names_the_conflicting_constraints(scenario):
    s = scenario
    slots = drift_free_slot_states(s.slots.r_CT_H, s.n)
    with pytest.raises(ValueError, match="inside the keep-out radius 100 m"):
        plan(s.x0_H[[1, 2, 3]], slots, n=s.n, tf_s=3000.0, keep_out_radius_m=100.0)
    with pytest.raises(ValueError, match="closer than the minimum separation 20 m"):
        plan(s.x0_H[[1, 2, 3]], slots, n=s.n, tf_s=3000.0, min_separation_m=20.0)
