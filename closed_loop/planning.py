"""Observer planning: which observers see the target at each epoch, with one reconfiguration if needed.

The candidates' CW states come in as arrays; :func:`plan_observers` selects a set at every epoch
(:func:`formation.selection.select_observers` on the 003 §1.2 constraints), and when no set
qualifies in sunlight it moves ``k`` candidates (:func:`formation.reconfiguration.choose_movers`)
into given slots with a minimum-fuel plan (:func:`formation.reconfiguration.plan`), follows them
along it (:func:`formation.execution.states_along_plan`) and selects again.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from formation.constraints import ObservationConstraints, evaluate
from formation.execution import states_along_plan
from formation.reconfiguration import choose_movers, drift_free_slot_states, plan
from formation.selection import select_observers

__all__ = ["ObserverPlan", "Reconfiguration", "select_active", "plan_observers"]

NO_SET = "no observer set satisfies the 003 §1.2 constraints"
SHADOW = "target in Earth shadow"
RECONFIGURING = "reconfiguring"


@dataclass(frozen=True)
class ObserverPlan:
    """Observers over the run.

    Attributes
    ----------
    names : list of str
        One per candidate.
    x_H : ndarray (S, T, 6)
        CW states (after any reconfiguration), H, m and m/s.
    active : ndarray (T, S) bool
        Selected observers.
    failure_reason : ndarray (T,) object
        Why no set was selected at an epoch (``""`` where one was).
    dv_m_s : ndarray (S,)
        Δv spent by each candidate in the reconfiguration, m/s.
    reconfiguration : dict
        Start time, duration, movers, Δv, solver status and success of the reconfiguration
        (empty when none was planned).
    """

    names: list[str]
    x_H: np.ndarray
    active: np.ndarray
    failure_reason: np.ndarray
    dv_m_s: np.ndarray
    reconfiguration: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> np.ndarray:
        """(T,) bool: epochs with a selected observer set."""
        return self.failure_reason == ""

    @classmethod
    def all_active(cls, names: Sequence[str], x_H: np.ndarray) -> ObserverPlan:
        """Every candidate active at every epoch (a fixed formation such as the symmetric cone)."""
        S, T = x_H.shape[:2]
        return cls(list(names), x_H, np.ones((T, S), bool), np.array([""] * T, dtype=object), np.zeros(S), {})


@dataclass(frozen=True)
class Reconfiguration:
    """Where and how to move observers when no set qualifies.

    Attributes
    ----------
    slots_r_H : ndarray (k, 3)
        Slot positions (e.g. :func:`formation.geometry.symmetric_views`), H, m; their states are
        the drift-free ones (:func:`formation.reconfiguration.drift_free_slot_states`).
    duration_s : float
        Transfer time.
    dv_max_m_s : float
        Largest single impulse.
    keep_out_radius_m : float
        Keep-out sphere about the target.
    """

    slots_r_H: np.ndarray
    duration_s: float
    dv_max_m_s: float
    keep_out_radius_m: float


def select_active(constraints: ObservationConstraints, x_H: np.ndarray, sun_H: np.ndarray,
                  illumination: np.ndarray, *, max_active: int,
                  min_active: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Observer sets over the run: ``max_active`` observers, else ``min_active`` where that qualifies.

    Parameters
    ----------
    constraints : formation.constraints.ObservationConstraints
    x_H : ndarray (S, T, 6)
        Candidates' CW states, H, m and m/s.
    sun_H : ndarray (T, 3)
        Direction to the Sun in H.
    illumination : ndarray (T,)
        Visible fraction of the Sun from the target (0: Earth's shadow).
    max_active, min_active : int
        Preferred and fallback set sizes.

    Returns
    -------
    active : ndarray (T, S) bool
    short : ndarray (T,) bool
        Epochs with no qualifying set.
    failure_reason : ndarray (T,) object
        Why (``""`` where a set qualifies).
    """
    r = np.swapaxes(x_H[..., :3], 0, 1)  # (T, S, 3)
    ev = evaluate(constraints, r, sun_H=sun_H, target_lit=illumination > 0)
    k = min(max_active, r.shape[1])
    tl = select_observers(ev, r, k)
    active = tl.active.copy()
    short = tl.short.copy()
    if min_active < k and short.any():
        tl2 = select_observers(ev, r, min_active)
        use = short & ~tl2.short
        active[use] = tl2.active[use]
        short &= tl2.short
    reason = np.where(short, np.where(illumination > 0, NO_SET, SHADOW), "")
    return active, short, reason.astype(object)


def plan_observers(names: Sequence[str], x_H: np.ndarray, t_s: np.ndarray, constraints: ObservationConstraints,
                   sun_H: np.ndarray, illumination: np.ndarray, *, n_rad_s: float, max_active: int,
                   min_active: int, reconfiguration: Reconfiguration | None = None) -> ObserverPlan:
    """Selection over the whole run, with one minimum-fuel reconfiguration when no set qualifies.

    The observers are selected at every epoch (:func:`select_active`); at the first sunlit epoch
    where no set qualifies, and when ``reconfiguration`` is given, the candidates with the cheapest
    two-impulse transfers into its slots (:func:`formation.reconfiguration.choose_movers`) are moved
    there by :func:`formation.reconfiguration.plan` within its duration, and the selection is
    repeated on the new trajectories (epochs during the transfer without a set read
    ``"reconfiguring"``).

    Parameters
    ----------
    names : sequence of str
        Candidates.
    x_H : ndarray (S, T, 6)
        Their CW states without manoeuvres, H, m and m/s.
    t_s : ndarray (T,)
        Epochs, s.
    constraints : formation.constraints.ObservationConstraints
    sun_H : ndarray (T, 3)
        Direction to the Sun in H.
    illumination : ndarray (T,)
        Visible fraction of the Sun from the target.
    n_rad_s : float
        Mean motion of the target's orbit.
    max_active, min_active : int
        Preferred and fallback set sizes.
    reconfiguration : Reconfiguration, optional
        Slots and limits of the reconfiguration (none is planned when omitted).

    Returns
    -------
    ObserverPlan
    """
    S = len(names)
    dv = np.zeros(S)
    active, short, reason = select_active(constraints, x_H, sun_H, illumination, max_active=max_active,
                                          min_active=min_active)
    info: dict[str, Any] = {}
    gap = np.flatnonzero(short & (illumination > 0))
    if reconfiguration is not None and gap.size:
        rc = reconfiguration
        k0 = int(gap[0])
        slots = drift_free_slot_states(rc.slots_r_H, n_rad_s)
        x0 = x_H[:, k0]
        movers, _ = choose_movers(x0, slots, rc.duration_s, n_rad_s)
        others = np.setdiff1d(np.arange(S), movers)
        p = plan(x0[movers], slots, n=n_rad_s, tf_s=rc.duration_s, dv_max_m_s=rc.dv_max_m_s,
                 keep_out_radius_m=rc.keep_out_radius_m, others_x0_H=x0[others] if others.size else None)
        info = {"start_s": float(t_s[k0]), "duration_s": rc.duration_s, "movers": [names[i] for i in movers],
                "dv_total_m_s": p.dv_total_m_s, "solver_status": p.solver_status, "success": bool(p.ok)}
        if p.ok:
            x_H = x_H.copy()
            x_H[movers, k0:] = states_along_plan(x0[movers], p, t_s[k0:] - t_s[k0], n=n_rad_s)
            dv[movers] = p.dv_per_spacecraft_m_s
            active, short, reason = select_active(constraints, x_H, sun_H, illumination, max_active=max_active,
                                                  min_active=min_active)
            during = (t_s >= t_s[k0]) & (t_s < t_s[k0] + rc.duration_s)
            reason = np.where(short & during, RECONFIGURING, reason).astype(object)
    return ObserverPlan(list(names), x_H, active, reason, dv, info)
