"""Flying a reconfiguration plan: CW states of the moving spacecraft at any time after its start."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from formation.reconfiguration import ReconfigurationPlan
from orbits.cw import propagate, stm

__all__ = ["states_along_plan"]


def states_along_plan(x0_H: ArrayLike, plan: ReconfigurationPlan, t_s: ArrayLike, *, n: float) -> np.ndarray:
    """States of the planned spacecraft at times ``t_s`` (s from the plan's start), coasting after arrival.

    The impulse of node ``j`` is applied at ``plan.impulse_times_s[j]`` (a state at exactly a node
    time is the one after its impulse, as in ``plan.trajectory_H``); after the last node the
    spacecraft coast on CW, so with :func:`formation.reconfiguration.drift_free_slot_states` slots
    they follow the slots' bounded orbits.

    Parameters
    ----------
    x0_H : (m, 6) array_like
        Initial states of the spacecraft the plan moves, in the plan's order (H, m and m/s).
    plan : ReconfigurationPlan
        From :func:`formation.reconfiguration.plan`.
    t_s : (T,) array_like
        Times >= 0, s from the start of the plan, any order.
    n : float
        Mean motion, rad/s.

    Returns
    -------
    (m, T, 6) ndarray
        States in H, m and m/s.
    """
    x0 = np.asarray(x0_H, dtype=float)
    dv = np.asarray(plan.impulses_H, dtype=float)
    if x0.ndim != 2 or x0.shape[1] != 6 or x0.shape[0] != dv.shape[0]:
        raise ValueError(f"x0_H: expected shape ({dv.shape[0]}, 6) like the plan's impulses, got {x0.shape}")
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    if t.ndim != 1 or not np.all(np.isfinite(t)) or np.any(t < 0):
        raise ValueError(f"t_s: expected finite times >= 0 (s from the plan's start), got min {np.min(t)!r}")
    nodes = np.asarray(plan.impulse_times_s, dtype=float)
    after = np.empty((x0.shape[0], nodes.size, 6))  # states just after each node's impulse
    x = x0.copy()
    prev = 0.0
    for j, tj in enumerate(nodes):
        x = propagate(x, [tj - prev], n)[:, 0] if tj > prev else x.copy()
        x[:, 3:] += dv[:, j]
        after[:, j] = x
        prev = tj
    seg = np.searchsorted(nodes, t, side="right") - 1  # last node at or before t (−1: before the first)
    start = np.where(seg[None, :, None] >= 0, after[:, np.maximum(seg, 0)], x0[:, None, :])
    dt = t - np.where(seg >= 0, nodes[np.maximum(seg, 0)], 0.0)
    return np.einsum("tab,mtb->mta", stm(dt, n), start)
