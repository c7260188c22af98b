"""Flying a reconfiguration plan, and slot states that hold a trailing geometry after arrival.

:func:`states_along_plan` gives the moving spacecraft's CW states at any time after the plan's
start (impulses at the nodes, coasting after arrival).

Holding the geometry: :func:`formation.reconfiguration.drift_free_slot_states` gives each slot the
velocity ``(0, −2 n x, 0)``; then ``x(t) = x₀ cos nt`` and ``z(t) = z₀ cos nt`` both shrink together,
so a cone about the along-track axis collapses onto it a quarter orbit after arrival (every
pairwise optical-axis angle → 0, far below γ_min).  :func:`circulating_slot_states` instead makes
each slot's cross-track/radial offset turn at the orbit rate, ``(x, z)(t) = R(nt) (x₀, z₀)``
(velocity ``(n z, −2 n x, −n x)``, still drift-free), so the triangle of offsets keeps its size and
only the along-track positions oscillate by ``2|(x₀, z₀)|``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from formation.reconfiguration import ReconfigurationPlan
from orbits.cw import propagate, stm

__all__ = ["circulating_slot_states", "states_along_plan"]


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


def circulating_slot_states(r_slot_H: ArrayLike, n: float) -> np.ndarray:
    """Slot states whose radial/cross-track offset turns at the orbit rate (see module doc).

    Velocity ``(n z, −2 n x, −n x)`` at slot position ``(x, y, z)``: ``ẏ = −2 n x`` removes the
    along-track drift (CW), and ``(ẋ, ż) = n (z, −x)`` makes ``x(t) = x₀ cos nt + z₀ sin nt``,
    ``z(t) = z₀ cos nt − x₀ sin nt``: the offset ``(x, z)`` keeps its length.  Meant for geometries
    whose axis is along-track (observers trailing or leading the target).

    Parameters
    ----------
    r_slot_H : (..., 3) array_like
        Slot positions relative to the target, H, m.
    n : float
        Mean motion, rad/s.

    Returns
    -------
    (..., 6) ndarray
        Slot states, m and m/s.
    """
    r = np.asarray(r_slot_H, dtype=float)
    if r.shape[-1:] != (3,):
        raise ValueError(f"r_slot_H: expected shape (..., 3), got {r.shape}")
    if not n > 0:
        raise ValueError(f"n: mean motion must be positive, got {n!r}")
    v = np.stack([n * r[..., 2], -2.0 * n * r[..., 0], -n * r[..., 0]], -1)
    return np.concatenate([r, v], -1)
