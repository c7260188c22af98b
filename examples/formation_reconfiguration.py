"""Formation planning with reconfiguration: three of six observers move into a 3-view geometry.

Six spacecraft fly bounded Clohessy–Wiltshire orbits about the target; only one of them is inside
the observation window at the start.  The wanted geometry is the symmetric 3-view cone of paper 003
(60 m behind the target, 10° between optical axes).  ``formation.reconfiguration`` picks the three
cheapest movers (Hungarian assignment on the two-impulse Δv) and plans minimum-fuel multi-impulse
transfers with casadi/IPOPT, keeping out of a 20 m sphere about the target and 5 m from every other
spacecraft; the convex problem without those constraints gives a lower bound on the Δv.

Run it:  ``python examples/formation_reconfiguration.py`` (seconds) → ``docs/figures/gallery/formation_reconfiguration.png``
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from formation.reconfiguration import choose_movers, drift_free_slot_states, lower_bound, plan
from formation.scenarios import six_spacecraft_scenario
from orbits.cw import propagate

NAME = "formation_reconfiguration"
GALLERY = Path(__file__).resolve().parents[1] / "docs" / "figures" / "gallery"


def main(*, out_dir: Path = GALLERY, small: bool = True) -> dict[str, Any]:
    """Plan the reconfiguration and draw it; returns the key numbers, the plan and the figure's path.

    Parameters
    ----------
    out_dir : Path
        Folder for ``formation_reconfiguration.png``.
    small : bool
        4 impulses per spacecraft, constraints checked every 10 s (seconds); ``False``: 8 impulses,
        checked every second.
    """
    # 1. configure: the scenario, the slots, which spacecraft move where
    s = six_spacecraft_scenario()
    slots_H = drift_free_slot_states(s.slots.r_CT_H, s.n)
    tf_s = 0.6 * s.period_s
    movers, slot_of = choose_movers(s.x0_H, slots_H, tf_s, s.n)
    others = np.setdiff1d(np.arange(len(s.x0_H)), movers)
    n_impulses = 4 if small else 8

    # 2. run: minimum-fuel plan with keep-out and separation, and its convex lower bound
    p = plan(s.x0_H[movers], slots_H[slot_of], n=s.n, tf_s=tf_s, assign=False, n_impulses=n_impulses,
             dv_max_m_s=1.0, keep_out_radius_m=20.0, min_separation_m=5.0, others_x0_H=s.x0_H[others],
             check_step_s=10.0 if small else 1.0, coarse_points=100 if small else 400)
    lb = lower_bound(s.x0_H[movers], slots_H[slot_of], n=s.n, tf_s=tf_s, n_impulses=n_impulses)

    # 3. pull the outputs: trajectories, the coasting spacecraft, distances to the target
    r_move_H = p.trajectory_H[..., :3]  # (3, K, 3)
    r_coast_H = propagate(s.x0_H[others], p.t_grid_s, s.n)[..., :3]
    range_m = np.linalg.norm(r_move_H, axis=-1)

    # 4. plot: along-track vs radial, the arrival geometry seen along-track, range over time
    fig = Figure(figsize=(12.0, 4.0), layout="constrained")
    ax1, ax2, ax3 = fig.subplots(1, 3, width_ratios=[1.6, 0.9, 1.0])
    for r in r_coast_H:
        ax1.plot(r[:, 1], r[:, 0], color="0.8", lw=0.8)
    for i, r in enumerate(r_move_H):
        line, = ax1.plot(r[:, 1], r[:, 0], lw=1.6, label=f"spacecraft {movers[i]} → slot {slot_of[i]}")
        ax1.plot(r[0, 1], r[0, 0], "o", color=line.get_color())
        ax2.plot(r[-40:, 0], r[-40:, 2], lw=1.6, color=line.get_color())
        ax2.plot(r[-1, 0], r[-1, 2], "o", color=line.get_color())
        ax3.plot(p.t_grid_s / 60.0, range_m[i], color=line.get_color())
    ax1.plot(slots_H[:, 1], slots_H[:, 0], "k*", ms=10, label="slots")
    ax1.add_patch(_circle(20.0))
    lo, hi = r_move_H[..., 1].min() - 30.0, max(r_move_H[..., 1].max(), 20.0) + 30.0
    ax1.set(xlabel="along-track y_H [m]", ylabel="radial x_H [m]", xlim=(lo, hi), aspect="equal",
            title="transfers (coasting spacecraft grey)")
    ax1.legend(fontsize=8, loc="upper left")
    ax2.plot(slots_H[:, 0], slots_H[:, 2], "k*", ms=10)
    ax2.set(xlabel="radial x_H [m]", ylabel="cross-track z_H [m]", aspect="equal",
            title="arrival, seen along-track")
    ax3.axhline(20.0, color="tab:red", ls="--", lw=1, label="keep-out 20 m")
    ax3.set(xlabel="time [min]", ylabel="range to target [m]", yscale="log",
            title=f"Δv {p.dv_total_m_s:.3f} m/s (lower bound {lb:.3f})")
    ax3.legend(fontsize=8)
    fig.suptitle(f"Reconfiguration into the 003 3-view cone: {n_impulses} impulses each, IPOPT, "
                 f"{p.rounds} solves, ok={p.ok}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    figure = out_dir / f"{NAME}.png"
    fig.savefig(figure, dpi=110)
    return {"figure": figure, "ok": p.ok, "failure_reason": p.failure_reason, "dv_total_m_s": p.dv_total_m_s,
            "dv_lower_bound_m_s": lb, "min_range_m": float(range_m.min()), "solve_time_s": p.solve_time_s,
            "plan": p, "x0_H": s.x0_H[movers], "slots_H": slots_H[slot_of], "n_rad_s": s.n}


def _circle(radius_m: float):
    from matplotlib.patches import Circle

    return Circle((0.0, 0.0), radius_m, color="tab:red", alpha=0.25, label="keep-out")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out-dir", type=Path, default=GALLERY, help="folder for the figure")
    parser.add_argument("--full", action="store_true", help="8 impulses, checked every second")
    args = parser.parse_args()
    res = main(out_dir=args.out_dir, small=not args.full)
    print(f"ok={res['ok']} {res['failure_reason']}; Δv {res['dv_total_m_s']:.4f} m/s (lower bound "
          f"{res['dv_lower_bound_m_s']:.4f}); closest approach {res['min_range_m']:.1f} m; "
          f"solved in {res['solve_time_s']:.1f} s")
    print(f"figure: {res['figure']}")
