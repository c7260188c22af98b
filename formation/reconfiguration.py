"""Minimum-fuel multi-impulse reconfiguration of observers under CW dynamics (casadi + IPOPT).

When fewer than k candidates satisfy the observation constraints, chosen spacecraft are moved to
target slots (for instance a :func:`formation.geometry.symmetric_views` geometry) within a given
time.  The plan has two stages:

1. **Slot assignment**: the Hungarian algorithm (``scipy.optimize.linear_sum_assignment``) on the
   two-impulse CW transfer cost ``|Δv₀| + |Δv_f|`` (``orbits.cw.two_impulse_transfer``).
2. **Multi-impulse optimisation**: impulses ``Δv_ij`` at M fixed nodes ``t_j`` (the last at
   arrival) for every spacecraft i.  Because CW is linear, every position is an affine function of
   the impulses, ``r_i(τ) = Φ_rr r_i0 + Φ_rv v_i0 + Σ_{t_j < τ} Φ_rv(τ − t_j) Δv_ij``, so the
   problem is

       minimise   Σ_ij |Δv_ij|
       subject to x_i(t_f) = slot_i,  |Δv_ij| <= Δv_max,
                  |r_i(τ)| >= R_keep-out,  |r_i(τ) − r_l(τ)| >= d_sep   for τ on a grid,

   solved by IPOPT (``casadi.Opti``).  The path constraints are imposed on a coarse grid, checked
   on a fine one (1 s by default), and every violated instant is added to the grid before solving
   again, until the fine-grid check passes.

Without the non-convex keep-out and separation constraints the problem is convex (a second-order
cone program); its optimum, :func:`lower_bound`, bounds the total Δv of the full problem from below
for the same impulse nodes.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linear_sum_assignment

from orbits.cw import propagate, stm, two_impulse_transfer

__all__ = ["ReconfigurationPlan", "assign_slots", "choose_movers", "plan", "lower_bound", "drift_free_slot_states"]



@dataclass(frozen=True)
class ReconfigurationPlan:
    """A planned reconfiguration.

    Attributes
    ----------
    assignment : (m,) int ndarray
        Slot index of each moving spacecraft.
    impulse_times_s : (M,) ndarray
        Node times of the impulses, s from the start.
    impulses_H : (m, M, 3) ndarray
        Impulses, m/s in H.
    dv_per_spacecraft_m_s : (m,) ndarray
        Σ_j |Δv_ij|.
    dv_total_m_s : float
    t_grid_s : (K,) ndarray
        Fine check grid.
    trajectory_H : (m, K, 6) ndarray
        States on the check grid (after the impulse at a node).
    margins : dict[str, ndarray]
        ``"keep_out"`` (m, K) in m, ``"separation"`` (P, K) in m for every pair (moving–moving and
        moving–fixed), ``"dv_limit"`` (m, M) in m/s, ``"final_state"`` (m,) residual norm.
        Positive (or ~0 for the final state) means satisfied.
    ok : bool
        Solver success and every margin satisfied on the fine grid.
    failure_reason : str
        Empty when ``ok``, else why the plan is not usable (solver status or violated constraints).
    solver_status : str
        IPOPT's return status of the last solve.
    solve_time_s : float
        Wall time of the whole plan (all refinement rounds).
    rounds : int
        Number of solves (constraint-grid refinements + 1).
    """

    assignment: np.ndarray
    impulse_times_s: np.ndarray
    impulses_H: np.ndarray
    dv_per_spacecraft_m_s: np.ndarray
    dv_total_m_s: float
    t_grid_s: np.ndarray
    trajectory_H: np.ndarray
    margins: dict[str, np.ndarray]
    ok: bool
    failure_reason: str
    solver_status: str
    solve_time_s: float
    rounds: int


def drift_free_slot_states(r_slot_H: ArrayLike, n: float) -> np.ndarray:
    """Slot states with the drift-free velocity ``(0, −2 n x, 0)``: the spacecraft stays near the slot.

    From there the motion is a bounded 2:1 ellipse through the slot (``orbits.cw``), so the geometry
    changes slowly after arrival instead of drifting away.
    """
    r = np.asarray(r_slot_H, dtype=float)
    v = np.zeros_like(r)
    v[..., 1] = -2.0 * n * r[..., 0]
    return np.concatenate([r, v], -1)


def _two_impulse_costs(x0: np.ndarray, slots_H: ArrayLike, tf_s: float, n: float) -> np.ndarray:
    """(spacecraft, slot) matrix of two-impulse CW Δv; 1e9 where no unique transfer exists."""
    slots = np.asarray(slots_H, dtype=float)
    tr = two_impulse_transfer(x0[:, None, :], slots[None, :, :], tf_s, n)
    return np.where(tr.ok, tr.total_dv_m_s, 1e9)


def assign_slots(x0_H: ArrayLike, slots_H: ArrayLike, tf_s: float, n: float) -> tuple[np.ndarray, np.ndarray]:
    """Hungarian assignment of spacecraft to slots on the two-impulse Δv; returns (assignment, cost matrix)."""
    x0 = np.asarray(x0_H, dtype=float)
    cost = _two_impulse_costs(x0, slots_H, tf_s, n)
    rows, cols = linear_sum_assignment(cost)
    assignment = np.empty(x0.shape[0], dtype=int)
    assignment[rows] = cols
    return assignment, cost


def choose_movers(x0_H: ArrayLike, slots_H: ArrayLike, tf_s: float, n: float) -> tuple[np.ndarray, np.ndarray]:
    """Pick which of N >= k candidates fill the k slots: rectangular Hungarian on the two-impulse Δv.

    Returns ``(movers, slot_of_mover)``: candidate indices (sorted) and the slot assigned to each.
    """
    x0 = np.asarray(x0_H, dtype=float)
    slots = np.asarray(slots_H, dtype=float)
    if x0.shape[0] < slots.shape[0]:
        raise ValueError(f"x0_H: {x0.shape[0]} candidates cannot fill {slots.shape[0]} slots")
    rows, cols = linear_sum_assignment(_two_impulse_costs(x0, slots, tf_s, n))
    order = np.argsort(rows)
    return rows[order], cols[order]


def _affine_maps(x0: np.ndarray, nodes: np.ndarray, taus: np.ndarray, n: float):
    """Position at times ``taus`` as ``c (m, K, 3) + G (K, 3, M, 3) · Δv`` (impulse at t_j applies for τ >= t_j)."""
    c = propagate(x0, taus, n)[..., :3]  # (m, K, 3)
    dt = taus[:, None] - nodes[None, :]  # (K, M)
    Phi = stm(np.maximum(dt, 0.0), n)[..., :3, 3:]  # (K, M, 3, 3)
    Phi = np.where((dt >= 0)[..., None, None], Phi, 0.0)
    return c, Phi.transpose(0, 2, 1, 3)  # (K, 3, M, 3)


def _final_maps(x0: np.ndarray, nodes: np.ndarray, tf: float, n: float):
    c = (stm(tf, n) @ x0[..., None])[..., 0]  # (m, 6)
    Phi = stm(tf - nodes, n)[..., :, 3:]  # (M, 6, 3)
    return c, Phi.transpose(1, 0, 2)  # (6, M, 3)


def _solve(x0, slots, nodes, tf, n, dv_max, warm, lin=None):
    """One convex solve (IPOPT): min Σ|Δv| s.t. final states, |Δv| <= Δv_max and ``lin``.

    ``lin`` is a list of ``(A (R, m·3M), b (R,))`` linear inequalities ``A vec(Δv) >= b`` (the
    linearised keep-out and separation constraints).
    """
    m, M = x0.shape[0], nodes.size
    opti = ca.Opti()
    DV = opti.variable(3 * M, m)  # column i: impulses of spacecraft i, node-major
    S = opti.variable(M, m)  # epigraph of the impulse norms: S >= |Δv|
    sq = ca.vertcat(*[ca.sum1(DV[3 * j:3 * j + 3, :] ** 2) for j in range(M)])  # (M, m) squared norms
    opti.minimize(ca.sum1(ca.sum2(S)))
    opti.subject_to(ca.vec(S) >= 0)
    opti.subject_to(ca.vec(S) <= dv_max)
    opti.subject_to(ca.vec(S**2 - sq) >= 0)
    cf, Gf = _final_maps(x0, nodes, tf, n)
    opti.subject_to(ca.DM(cf.T) + ca.mtimes(ca.DM(Gf.reshape(6, 3 * M)), DV) == ca.DM(slots.T))
    for A, b in lin or []:
        opti.subject_to(ca.mtimes(ca.DM(A), ca.vec(DV)) >= ca.DM(b))
    opti.set_initial(DV, warm.reshape(m, 3 * M).T)
    opti.set_initial(S, np.linalg.norm(warm, axis=-1).T + 1e-3)
    opti.solver("ipopt", {"print_time": False, "expand": True}, {"print_level": 0, "sb": "yes", "tol": 1e-9,
                                                                 "acceptable_tol": 1e-7, "max_iter": 1000})
    try:
        sol = opti.solve()
        status = sol.stats()["return_status"]
        values = np.asarray(sol.value(DV)).reshape(3 * M, m)
    except RuntimeError:
        status = opti.stats()["return_status"]
        values = np.asarray(opti.debug.value(DV)).reshape(3 * M, m)
    return values.T.reshape(m, M, 3), status


def _linearised_path_constraints(x0, dv_ref, nodes, taus, n, keep_out, d_sep, others, *, screen=2.0):
    """Half-space (inner convex) approximations of keep-out and separation about ``dv_ref``.

    Outside a ball ``|r − a| >= ρ`` is replaced by ``eᵀ (r − a) >= ρ`` with ``e`` the unit vector from
    ``a`` to the reference position: every point of the half-space is outside the ball, so each
    convex iterate is feasible for the original constraints on ``taus`` (sequential convex
    programming, e.g. Morgan, Chung & Hadaegh, J. Guid. Control Dyn. 37 (2014) 1725).  Rows whose
    reference distance exceeds ``screen × ρ`` are left out (constraint screening); if a later iterate
    comes close there, the fine-grid check adds the instant back.
    """
    m, M = x0.shape[0], nodes.size
    K = taus.size
    c, G = _affine_maps(x0, nodes, taus, n)  # c (m, K, 3), G (K, 3, M, 3)
    G = G.reshape(K, 3, 3 * M)
    r_ref = c + np.einsum("kab,ib->ika", G, dv_ref.reshape(m, 3 * M))
    lin = []

    def rows(i, e):  # e (K, 3): coefficient rows of e·r_i for spacecraft i in vec(DV) ordering
        A = np.zeros((K, m * 3 * M))
        A[:, i * 3 * M:(i + 1) * 3 * M] = np.einsum("ka,kab->kb", e, G)
        return A

    def add(A, d, b, rho):
        near = np.linalg.norm(d, axis=-1) < screen * rho
        if np.any(near):
            lin.append((A[near], b[near]))

    def unit(v):
        nv = np.linalg.norm(v, axis=-1, keepdims=True)
        return v / np.where(nv > 0, nv, 1.0)

    r_oth = propagate(others, taus, n)[..., :3] if (others is not None and d_sep > 0) else None
    for i in range(m):
        if keep_out > 0:
            e = unit(r_ref[i])
            add(rows(i, e), r_ref[i], keep_out - np.sum(e * c[i], -1), keep_out)
        if d_sep > 0:
            for l in range(i + 1, m):
                d = r_ref[i] - r_ref[l]
                e = unit(d)
                add(rows(i, e) - rows(l, e), d, d_sep - np.sum(e * (c[i] - c[l]), -1), d_sep)
            if r_oth is not None:
                for o in range(r_oth.shape[0]):
                    d = r_ref[i] - r_oth[o]
                    e = unit(d)
                    add(rows(i, e), d, d_sep - np.sum(e * (c[i] - r_oth[o]), -1), d_sep)
    return lin


def _check_inputs(x0, slots, tf_s, n, n_impulses, dv_max, keep_out, d_sep):
    if x0.ndim != 2 or x0.shape[1] != 6:
        raise ValueError(f"x0_H: expected shape (m, 6), got {x0.shape}")
    if slots.ndim != 2 or slots.shape[1] != 6:
        raise ValueError(f"slots_H: expected shape (k, 6), got {slots.shape}")
    if slots.shape[0] < x0.shape[0]:
        raise ValueError(f"slots_H: {slots.shape[0]} slots for {x0.shape[0]} spacecraft")
    if not tf_s > 0:
        raise ValueError(f"tf_s: must be positive, got {tf_s!r}")
    if not n > 0:
        raise ValueError(f"n: mean motion must be positive, got {n!r}")
    if n_impulses < 2:
        raise ValueError(f"n_impulses: need at least 2 (departure and arrival), got {n_impulses!r}")
    if not dv_max > 0:
        raise ValueError(f"dv_max_m_s: must be positive, got {dv_max!r}")
    conflicts = []
    slot_r = np.linalg.norm(slots[:, :3], axis=-1)
    if keep_out > 0 and np.any(slot_r < keep_out):
        conflicts.append(f"slot at {slot_r.min():.3g} m inside the keep-out radius {keep_out:.3g} m")
    if keep_out > 0 and np.any(np.linalg.norm(x0[:, :3], axis=-1) < keep_out):
        conflicts.append(f"a spacecraft starts inside the keep-out radius {keep_out:.3g} m")
    if d_sep > 0 and slots.shape[0] > 1:
        sep = np.linalg.norm(slots[:, None, :3] - slots[None, :, :3], axis=-1)
        sep = sep[np.triu_indices(slots.shape[0], 1)].min()
        if sep < d_sep:
            conflicts.append(f"slots {sep:.3g} m apart, closer than the minimum separation {d_sep:.3g} m")
    if conflicts:
        raise ValueError("infeasible reconfiguration: " + "; ".join(conflicts))


def lower_bound(x0_H: ArrayLike, slots_H: ArrayLike, *, n: float, tf_s: float, n_impulses: int = 6,
                dv_max_m_s: float = 1.0) -> float:
    """Total Δv (m/s) of the convex problem without keep-out and separation (a lower bound)."""
    x0 = np.asarray(x0_H, dtype=float)
    slots = np.asarray(slots_H, dtype=float)
    nodes = np.linspace(0.0, tf_s, n_impulses)
    warm = _two_impulse_warm_start(x0, slots, nodes, tf_s, n)
    dv, _ = _solve(x0, slots, nodes, tf_s, n, dv_max_m_s, warm)
    return float(np.sum(np.linalg.norm(dv, axis=-1)))


def _two_impulse_warm_start(x0, slots, nodes, tf, n):
    tr = two_impulse_transfer(x0, slots, tf, n)
    warm = np.zeros((x0.shape[0], nodes.size, 3))
    warm[:, 0] = np.nan_to_num(tr.dv0_H)
    warm[:, -1] = np.nan_to_num(tr.dvf_H)
    return warm


def plan(
    x0_H: ArrayLike,
    slots_H: ArrayLike,
    *,
    n: float,
    tf_s: float,
    n_impulses: int = 6,
    dv_max_m_s: float = 1.0,
    keep_out_radius_m: float = 20.0,
    min_separation_m: float = 5.0,
    others_x0_H: ArrayLike | None = None,
    check_step_s: float = 1.0,
    coarse_points: int = 400,
    max_rounds: int = 15,
    assign: bool = True,
) -> ReconfigurationPlan:
    """Plan a minimum-fuel transfer of the spacecraft ``x0_H`` to the slots ``slots_H``.

    Parameters
    ----------
    x0_H : (m, 6) array_like
        Initial CW states of the spacecraft that move (H, m and m/s).
    slots_H : (k, 6) array_like, k >= m
        Wanted final states (e.g. :func:`drift_free_slot_states` of a symmetric geometry).
    n : float
        Mean motion, rad/s.
    tf_s : float
        Transfer time, s.
    n_impulses : int
        Impulse nodes M, evenly spaced from 0 to ``tf_s`` (the last one at arrival).
    dv_max_m_s : float
        Largest single impulse, m/s.
    keep_out_radius_m, min_separation_m : float
        Path constraints (0 disables): distance from the target and between spacecraft (moving
        ones, and against ``others_x0_H`` that coast).
    others_x0_H : (o, 6) array_like, optional
        Spacecraft that do not manoeuvre, for the separation constraint.
    check_step_s : float
        Step of the fine grid on which every path constraint is verified.
    assign : bool
        Hungarian slot assignment (otherwise spacecraft i goes to slot i).
    """
    t_start = time.perf_counter()
    x0 = np.asarray(x0_H, dtype=float)
    slots_all = np.asarray(slots_H, dtype=float)
    _check_inputs(x0, slots_all, tf_s, n, n_impulses, dv_max_m_s, keep_out_radius_m, min_separation_m)
    others = None if others_x0_H is None else np.asarray(others_x0_H, dtype=float).reshape(-1, 6)
    if assign:
        assignment, _ = assign_slots(x0, slots_all, tf_s, n)
    else:
        assignment = np.arange(x0.shape[0])
    slots = slots_all[assignment]
    nodes = np.linspace(0.0, tf_s, n_impulses)
    fine = np.arange(0.0, tf_s + 0.5 * check_step_s, check_step_s)
    fine = fine[fine <= tf_s]
    warm = _two_impulse_warm_start(x0, slots, nodes, tf_s, n)
    # Sequential convex programming: start from the convex problem without path constraints; while
    # the fine-grid check fails, linearise keep-out and separation about the current solution on the
    # coarse grid plus every violated instant, and solve the convex subproblem again.
    dv, status = _solve(x0, slots, nodes, tf_s, n, dv_max_m_s, warm)
    taus = np.zeros(0)
    rounds = 1
    prev_cost = np.inf
    while True:
        traj, margins = _evaluate(x0, dv, nodes, fine, tf_s, n, slots, dv_max_m_s, keep_out_radius_m,
                                  min_separation_m, others)
        bad_t = _violations(margins, fine)
        cost = float(np.sum(np.linalg.norm(dv, axis=-1)))
        converged = rounds == 1 or abs(cost - prev_cost) < 1e-4 * cost
        if (bad_t.size == 0 and converged) or rounds >= max_rounds:
            break
        if taus.size == 0:
            taus = np.linspace(0.0, tf_s, coarse_points)[1:-1]
        taus = np.unique(np.concatenate([taus, bad_t]))
        lin = _linearised_path_constraints(x0, dv, nodes, taus, n, keep_out_radius_m, min_separation_m, others)
        prev_cost = cost
        dv, status = _solve(x0, slots, nodes, tf_s, n, dv_max_m_s, dv, lin)
        rounds += 1
    solved = status in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
    n_bad = _violations(margins, fine).size
    arrived = bool(np.all(margins["final_state"] < 1e-6))
    ok = solved and n_bad == 0 and arrived
    if not solved:
        reason = f"IPOPT did not solve the problem ({status})"
    elif n_bad:
        reason = (f"keep-out or separation violated at {n_bad} instants of the {check_step_s} s "
                  f"check grid after {rounds} solves")
    elif not arrived:
        reason = "final state misses the slot state by more than 1e-6"
    else:
        reason = ""
    per = np.sum(np.linalg.norm(dv, axis=-1), axis=-1)
    return ReconfigurationPlan(
        assignment=assignment, impulse_times_s=nodes, impulses_H=dv, dv_per_spacecraft_m_s=per,
        dv_total_m_s=float(per.sum()), t_grid_s=fine, trajectory_H=traj, margins=margins, ok=bool(ok),
        failure_reason=reason, solver_status=status, solve_time_s=time.perf_counter() - t_start, rounds=rounds,
    )


def _evaluate(x0, dv, nodes, fine, tf, n, slots, dv_max, keep_out, d_sep, others):
    """States on the fine grid and every constraint margin."""
    m = x0.shape[0]
    c, G = _affine_maps(x0, nodes, fine, n)  # positions
    r = c + np.einsum("kamb,imb->ika", G, dv)
    # velocities on the grid from the full STM
    cv = propagate(x0, fine, n)[..., 3:]
    dt = fine[:, None] - nodes[None, :]
    Pvv = stm(np.maximum(dt, 0.0), n)[..., 3:, 3:]
    Pvv = np.where((dt >= 0)[..., None, None], Pvv, 0.0)
    v = cv + np.einsum("kmab,imb->ika", Pvv, dv)
    traj = np.concatenate([r, v], -1)
    cf, Gf = _final_maps(x0, nodes, tf, n)
    xf = cf + np.einsum("amb,imb->ia", Gf, dv)
    margins = {
        "keep_out": np.linalg.norm(r, axis=-1) - keep_out if keep_out > 0 else np.full(r.shape[:2], np.inf),
        "dv_limit": dv_max - np.linalg.norm(dv, axis=-1),
        "final_state": np.linalg.norm(xf - slots, axis=-1),
    }
    seps = []
    if d_sep > 0:
        for i in range(m):
            for l in range(i + 1, m):
                seps.append(np.linalg.norm(r[i] - r[l], axis=-1) - d_sep)
        if others is not None:
            r_oth = propagate(others, fine, n)[..., :3]
            for i in range(m):
                for o in range(r_oth.shape[0]):
                    seps.append(np.linalg.norm(r[i] - r_oth[o], axis=-1) - d_sep)
    margins["separation"] = np.array(seps).reshape(-1, fine.size)
    return traj, margins


def _violations(margins, fine, tol=-1e-6):
    bad = np.zeros(fine.size, dtype=bool)
    for key in ("keep_out", "separation"):
        mk = margins[key]
        if mk.size:
            bad |= np.any(mk < tol, axis=0)
    return fine[bad]
