"""Experiment A's Cramér–Rao bound (``crlb_deg``): the points tracked at both epochs, each epoch with its
own view sets (issue 16 item 5)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from experiments.config import load_config

CONFIGS = Path(__file__).resolve().parents[3] / "experiments" / "configs"


def _two_epochs(distance_m: float, seed: int):
    from attitude.quaternion import quat_from_rotvec, quat_multiply
    from closed_loop import reconstruct_many
    from experiments.scenarios.formation.error_map import random_attitudes
    from experiments.scenarios.formation.parts import make_observer, symmetric_T_CW

    _, cfg = load_config(CONFIGS / "003_fig5_fig6.toml", overrides={"formation.distance_m": distance_m})
    observer, T_CW = make_observer(cfg), symmetric_T_CW(cfg)
    rng = np.random.default_rng(seed)
    q0 = random_attitudes(rng)
    dq = quat_from_rotvec(np.deg2rad([0.5, 0.5, 0.5]))
    # a larger turn than one step, so that view sets change between the two epochs
    dq_big = quat_from_rotvec(np.deg2rad([12.0, -8.0, 10.0]))
    q1 = quat_multiply(dq_big, q0)
    sun = np.asarray(cfg.observation.sun_H)
    frames = reconstruct_many([observer.observe(T_CW, q, sun, rng=rng) for q in (q0, q1)])
    return frames, q0, dq_big, dq, T_CW


def test_tracks_of_two_epochs_pair_by_surface_feature_in_the_geometric_mode():
    """The pairing by true body point (what the rendered mode needs) gives exactly the pairs of equal
    surface-feature ids of the geometric mode (an independent key)."""
    from experiments.scenarios.formation.error_map import _same_surface_points

    frames, *_ = _two_epochs(40.0, 1)
    a, b = frames[0].obs, frames[1].obs
    ip, ic = _same_surface_points(a, b)
    ids_a = {int(f): i for i, f in enumerate(a.feature_id) if f >= 0}
    ids_b = {int(f): i for i, f in enumerate(b.feature_id) if f >= 0}
    expected = sorted((ids_a[f], ids_b[f]) for f in ids_a.keys() & ids_b.keys())
    assert len(expected) > 30
    assert sorted(zip(ip.tolist(), ic.tolist(), strict=True)) == expected


def test_crlb_deg_uses_each_epochs_own_views():
    """``_crlb_deg`` equals the bound of the paired points with visible / visible_next taken from each
    epoch's tracks; where view sets change it differs from the bound with epoch t's views at both."""
    from attitude.quaternion import matrix_from_quat
    from experiments.scenarios.formation.error_map import _crlb_deg, _same_surface_points
    from reconstruction.accuracy import attitude_increment_crlb

    frames, q0, dq_big, _, T_CW = _two_epochs(40.0, 5)
    a, b = frames[0].obs, frames[1].obs
    ip, ic = _same_surface_points(a, b)
    assert np.any(a.seen[ip] != b.seen[ic])  # the view sets do change
    got = _crlb_deg(frames[0], frames[1], q0, dq_big, T_CW)
    X_W = a.X_T_true[ip] @ matrix_from_quat(q0).T
    kw = dict(pixel_sigma_px=a.pixel_sigma_px, R_delta=matrix_from_quat(dq_big))
    per_epoch = attitude_increment_crlb(X_W, a.K, T_CW, visible=a.seen[ip], visible_next=b.seen[ic], **kw)
    one_mask = attitude_increment_crlb(X_W, a.K, T_CW, visible=a.seen[ip], visible_next=a.seen[ip], **kw)
    assert got == np.degrees(per_epoch.rms_angle_rad)
    assert abs(np.degrees(one_mask.rms_angle_rad) / got - 1) > 0.01
