"""Observer planning with the formation functions gives the numbers of the steps written out by hand."""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

from closed_loop import ObserverPlan, Reconfiguration, plan_observers, select_active
from formation.constraints import ObservationConstraints
from formation.geometry import look_at, symmetric_views
from formation.quality import camera_poses_at_target
from formation.reconfiguration import choose_movers, drift_free_slot_states, plan
from orbits.cw import apply_impulse, mean_motion, propagate, two_impulse_transfer
from orbits.two_body import R_EARTH_M

N_RAD_S = float(mean_motion(R_EARTH_M + 870e3))
CON = ObservationConstraints(fov_rad=float(np.deg2rad(20.0)), target_radius_m=5.3, d_max_m=150.0, d_min_form="tan",
                             d_min_lambda=1.1, pointing_max_rad=float(np.deg2rad(5.0)),
                             axis_angle_min_rad=float(np.deg2rad(5.0)), axis_angle_max_rad=float(np.deg2rad(30.0)),
                             comm_range_m=1000.0, sun_exclusion_rad=float(np.deg2rad(30.0)), keep_out_radius_m=20.0)


def _far_candidates(t: np.ndarray) -> tuple[list[str], np.ndarray]:
    x0 = np.array([[0.0, -200.0 - 10 * i, 5.0 * i, 0.0, 0.0, 0.0] for i in range(3)])
    return [f"s{i}" for i in range(3)], propagate(x0, t, N_RAD_S)


def _impulse_by_impulse(x0, times, dv, t_rel, n):
    """States after impulses ``dv (m, M, 3)`` applied at ``times (M,)``, propagated node to node."""
    states = [apply_impulse(x0, dv[:, 0])]
    for j in range(1, len(times)):
        prev = propagate(states[-1], np.array([times[j] - times[j - 1]]), n)[:, 0]
        states.append(apply_impulse(prev, dv[:, j]))
    out = np.empty((x0.shape[0], t_rel.size, 6))
    seg = np.searchsorted(times, t_rel, side="right") - 1
    for j in np.unique(seg):
        sel = seg == j
        out[:, sel] = propagate(states[j], t_rel[sel] - times[j], n)
    return out


def test_reconfiguration_plan_matches_hungarian_movers_and_node_by_node_propagation():
    t = np.arange(0.0, 1200.0, 30.0)
    names, x = _far_candidates(t)
    sun_H = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (t.size, 3))
    lit = np.ones(t.size)
    slots_r = symmetric_views(3, 50.0, 10.0).r_CT_H
    rc = Reconfiguration(slots_r_H=slots_r, duration_s=600.0, dv_max_m_s=1.0, keep_out_radius_m=20.0)
    p = plan_observers(names, x, t, CON, sun_H, lit, n_rad_s=N_RAD_S, max_active=3, min_active=2, reconfiguration=rc)

    # the same steps by hand: Hungarian on the two-impulse Δv, the plan, impulses applied node by node
    slots = drift_free_slot_states(slots_r, N_RAD_S)
    tr = two_impulse_transfer(x[:, 0][:, None, :], slots[None], 600.0, N_RAD_S)
    rows, _ = linear_sum_assignment(np.where(tr.ok, tr.total_dv_m_s, 1e9))
    movers = np.sort(rows)
    np.testing.assert_array_equal(choose_movers(x[:, 0], slots, 600.0, N_RAD_S)[0], movers)
    ref = plan(x[movers, 0], slots, n=N_RAD_S, tf_s=600.0, dv_max_m_s=1.0, keep_out_radius_m=20.0)
    assert ref.ok and p.reconfiguration["success"]
    expected = _impulse_by_impulse(x[movers, 0], ref.impulse_times_s, ref.impulses_H, t, N_RAD_S)
    np.testing.assert_allclose(p.x_H[movers], expected, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(p.dv_m_s[movers], ref.dv_per_spacecraft_m_s)
    active, _, _ = select_active(CON, expected, sun_H, lit, max_active=3, min_active=2)
    np.testing.assert_array_equal(p.active, active)
    during = (t < 600.0) & ~p.active.any(axis=1)
    assert set(p.failure_reason[during]) == {"reconfiguring"}
    np.testing.assert_array_equal(p.ok, p.failure_reason == "")


def test_camera_poses_look_at_the_target_with_z_up_except_near_the_pole():
    rng = np.random.default_rng(4)
    r = rng.normal(size=(50, 3)) * 40.0
    r[:5] = [[0.0, 0.5, 60.0], [0.3, 0.0, -45.0], [0.0, 0.0, 30.0], [0.1, -0.1, -20.0], [5.0, 0.0, 40.0]]
    up = np.where(np.abs(r[:, 2:3]) > 0.99 * np.linalg.norm(r, axis=1, keepdims=True),
                  np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(camera_poses_at_target(r), look_at(r, np.zeros(3), up), rtol=0, atol=1e-12)


def test_all_active_plan_of_a_fixed_formation():
    x = np.zeros((3, 4, 6))
    p = ObserverPlan.all_active(["a", "b", "c"], x)
    assert p.active.shape == (4, 3) and p.active.all() and p.ok.all()
    assert p.reconfiguration == {} and np.all(p.dv_m_s == 0)
