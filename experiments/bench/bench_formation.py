"""Formation benchmarks: reconfiguration plan time and Δv optimality, selection throughput.

Rows:

* wall time of :func:`formation.reconfiguration.plan` on the six-spacecraft scenario of the
  formation issue (three movers into the trailing 3-view slots in 0.6 orbit, 6 impulses, keep-out
  20 m, separation 5 m, 1 s check grid; target < 2 s), and on a case where the keep-out and
  separation constraints bind (three spacecraft ahead of the target cross to trailing slots in 0.3
  orbit, 8 impulses, |Δv| <= 0.5 m/s: the path constraints of the sequential convex programme
  are active);
* total Δv of each plan against the convex lower bound (:func:`formation.reconfiguration.lower_bound`,
  same nodes, no keep-out or separation): ratio = bound / plan (target >= 0.952, within 5 %);
* observer-selection throughput (epochs × k-subsets scored and chosen per second, point-DOP score)
  against a per-epoch, per-subset Python loop giving the same choices;
* the Cramér–Rao score (:func:`formation.quality.crlb_score`) against one
  ``attitude_increment_crlb`` call per subset.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

from experiments.bench import BenchRow, best_time, throughput_row


def _scenario_plan_inputs():
    from formation.reconfiguration import choose_movers, drift_free_slot_states
    from formation.scenarios import six_spacecraft_scenario

    s = six_spacecraft_scenario()
    slots = drift_free_slot_states(s.slots.r_CT_H, s.n)
    tf = 0.6 * s.period_s
    movers, slot_of = choose_movers(s.x0_H, slots, tf, s.n)
    others = np.setdiff1d(np.arange(6), movers)
    return s, dict(x0_H=s.x0_H[movers], slots_H=slots[slot_of], n=s.n, tf_s=tf, n_impulses=6, dv_max_m_s=1.0,
                   keep_out_radius_m=20.0, min_separation_m=5.0, others_x0_H=s.x0_H[others], assign=False)


def _binding_plan_inputs(s):
    from formation.reconfiguration import drift_free_slot_states

    n = s.n
    x0 = np.array([[0.0, 90.0, 0.0, 0.0, 0.0, 0.0], [2.0, 120.0, -3.0, 0.0, -4.0 * n, 0.0],
                   [-1.0, 70.0, 2.0, 0.0, 2.0 * n, 0.0]])
    return dict(x0_H=x0, slots_H=drift_free_slot_states(s.slots.r_CT_H, n), n=n, tf_s=0.3 * s.period_s,
                n_impulses=8, dv_max_m_s=0.5, keep_out_radius_m=20.0, min_separation_m=5.0)


def _plan_rows(label: str, kw: dict, repeat: int) -> list[BenchRow]:
    from formation.reconfiguration import lower_bound, plan

    p = plan(**kw)
    wall = best_time(lambda: plan(**kw), repeat=repeat)
    lb = lower_bound(kw["x0_H"], np.asarray(kw["slots_H"])[p.assignment], n=kw["n"], tf_s=kw["tf_s"],
                     n_impulses=kw["n_impulses"], dv_max_m_s=kw["dv_max_m_s"])
    ok = "all constraints hold on the 1 s grid" if p.ok else f"FAILED ({p.failure_reason})"
    return [
        BenchRow(f"reconfiguration plan wall time, {label}", wall, "s", "", float("nan"), float("nan"),
                 f"target < 2 s; {p.rounds} convex solve(s); {ok}"),
        BenchRow(f"reconfiguration total Δv, {label}", p.dv_total_m_s, "m/s",
                 "convex lower bound (same nodes, no keep-out/separation)", lb, lb / p.dv_total_m_s,
                 "target ratio >= 0.952 (within 5 %)"),
    ]


def _selection_case(T: int, N: int, rng):
    """T epochs of N candidates about a cone at 60 m (adjacent axes 10°); the odd ones swing out to
    162 m, beyond the 150 m range window, twice per run; small random walks."""
    from formation.constraints import ObservationConstraints, evaluate
    from formation.geometry import symmetric_views

    base = symmetric_views(N, 60.0, 10.0, orientation=[0.5**0.5, 0.5**0.5, 0.0, 0.0]).r_CT_H
    swing = 1.0 + 1.7 * np.sin(np.linspace(0.0, 2 * np.pi, T)) ** 2
    r = base[None] * np.where(np.arange(N) % 2 == 1, swing[:, None], 1.0)[..., None]
    r = r + np.cumsum(rng.normal(scale=0.05, size=(T, N, 3)), axis=0)
    return evaluate(ObservationConstraints(), r), r


def _naive_selection(ev, r, k, hysteresis=0.1):
    """Per-epoch, per-subset loop: the same rule as formation.selection.select_observers."""
    from formation.selection import point_dop

    T, N, _ = r.shape
    single, pair = ev.single_ok, ev.pair_ok
    subsets = list(combinations(range(N), k))
    chosen = np.full((T, k), -1)
    current = None
    for t in range(T):
        scores = []
        for sub in subsets:
            ok = all(single[t, i] for i in sub) and all(pair[t, i, j] for i in sub for j in sub)
            scores.append(float(point_dop(r[t, list(sub)])) if ok else np.inf)
        best = int(np.argmin(scores))
        if not np.isfinite(scores[best]):
            current = None
            continue
        if current is None or not np.isfinite(scores[current]) or scores[current] > (1 + hysteresis) * scores[best]:
            current = best
        chosen[t] = subsets[current]
    return chosen


def run(*, quick: bool = False) -> list[BenchRow]:
    from attitude.quaternion import matrix_from_quat, quat_from_rotvec
    from formation.quality import DEFAULT_INCREMENT_ROTVEC_H, camera_poses_at_target, crlb_score
    from formation.selection import select_observers
    from reconstruction.accuracy import attitude_increment_crlb
    from vision.camera import PinholeCamera

    rng = np.random.default_rng(0)
    s, kw = _scenario_plan_inputs()
    rows = _plan_rows("six-spacecraft scenario (3 movers, 6 impulses, 0.6 orbit)", kw, 2 if quick else 5)
    if not quick:
        rows += _plan_rows("binding keep-out case (3 movers, 8 impulses, 0.3 orbit)", _binding_plan_inputs(s), 1)

    # --- selection throughput
    T, N, k = (200, 8, 3) if quick else (2000, 8, 3)
    ev, r = _selection_case(T, N, rng)
    S = len(list(combinations(range(N), k)))
    tl = select_observers(ev, r, k)
    ours = best_time(lambda: select_observers(ev, r, k), repeat=3)
    T_peer = max(T // 10, 50)
    ev_p, r_p = _selection_case(T_peer, N, np.random.default_rng(0))
    same = np.array_equal(_naive_selection(ev_p, r_p, k), select_observers(ev_p, r_p, k).subset)
    peer = best_time(lambda: _naive_selection(ev_p, r_p, k), repeat=1) * T / T_peer
    rows.append(throughput_row(
        f"observer selection, {T} epochs x {S} subsets (N={N}, k={k}, point DOP)", ours, peer, T * S,
        "epoch-subsets/s", "per-epoch, per-subset Python loop",
        note=f"same choices: {same}; {int((~tl.short).sum())} epochs with a feasible set, {tl.switches} switches"))

    # --- Cramér–Rao score
    cam = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)
    m = 60
    i = np.arange(m) + 0.5
    polar, az = np.arccos(1 - 2 * i / m), np.pi * (1 + 5**0.5) * i
    u = np.stack([np.cos(az) * np.sin(polar), np.sin(az) * np.sin(polar), np.cos(polar)], -1)
    X = 4.0 * u
    subsets = np.array(list(combinations(range(N), k)))
    Tc = 20 if quick else 100
    pos = r[:Tc][:, subsets]  # (Tc, S, k, 3)
    score = crlb_score(cam, X, pixel_sigma_px=0.5)
    got = score(pos)
    ours_c = best_time(lambda: score(pos), repeat=2)
    n_peer = 100
    flat = pos.reshape(-1, k, 3)[:n_peer]
    Kk = np.broadcast_to(cam.K, (k, 3, 3))
    R = matrix_from_quat(quat_from_rotvec(np.asarray(DEFAULT_INCREMENT_ROTVEC_H)))

    def peer_loop():
        return [float(attitude_increment_crlb(X, Kk, camera_poses_at_target(p), pixel_sigma_px=0.5, R_delta=R,
                                              image_size=cam.image_size).rms_angle_rad) for p in flat]

    ref = np.asarray(peer_loop())
    diff = float(np.nanmax(np.abs(ref - got.reshape(-1)[:n_peer]) / ref))
    peer_c = best_time(peer_loop, repeat=1) * pos.shape[0] * pos.shape[1] / n_peer
    rows.append(throughput_row(
        f"Cramér–Rao selection score, {Tc} epochs x {S} subsets, {m} points, k={k}", ours_c, peer_c,
        Tc * S, "epoch-subsets/s", "attitude_increment_crlb per subset (Python loop)",
        note=f"max rel. diff {diff:.1e}; point DOP is cheaper but ranks by a point at the centre"))
    return rows
