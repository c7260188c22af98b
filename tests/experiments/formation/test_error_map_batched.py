"""Experiment A's trials batched through observation, triangulation and registration give what each trial gives alone."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from experiments.config import load_config

CONFIGS = Path(__file__).resolve().parents[3] / "experiments" / "configs"
METRICS = ("e_dtheta_deg", "step_rms_deg", "crlb_deg", "n_tracks", "n_matches", "n_inliers", "failed_steps")


@pytest.mark.parametrize("noise_model", ["calibrated", "fixed"])
def test_batched_trials_equal_the_per_trial_path(monkeypatch, noise_model):
    """One cell (2 views, 60 m, 10°, 5 trials × 4 steps) with the trials observed, triangulated and
    registered together and one at a time: every per-trial metric identical (each trial's draws come
    from its own stream; each point's Gauss–Newton stops on its own step, whatever the batch)."""
    import experiments.scenarios.formation.error_map as em
    from experiments.sweep import cell_seed_sequences

    _, cfg = load_config(CONFIGS / "003_fig5_fig6.toml", overrides={
        "error_map.filter_runs": 0, "error_map.steps": 4, "observation.noise_model": noise_model,
        "formation.n_views": 2, "formation.distance_m": 60.0})
    seeds = cell_seed_sequences(cfg.seed, {}, 5)
    batched = em.error_map_trials(cfg, seeds)
    monkeypatch.setattr(em, "_TRIALS_PER_BATCH", 1)
    alone = em.error_map_trials(cfg, seeds)
    for k in METRICS:
        np.testing.assert_array_equal(batched[k], alone[k], err_msg=k)
    assert np.isfinite(batched["n_tracks"]).all() and np.nanmax(batched["n_tracks"]) > 10
    assert list(batched["failure_reason"]) == list(alone["failure_reason"])


def test_calibrated_observe_trials_equals_observe_epochs_per_trial():
    """vision.geometric.observe_trials (calibrated, geometry of all trials in one batch) gives each
    trial exactly what observe_epochs gives it with the same generator."""
    from experiments.scenarios.formation.error_map import random_attitudes
    from experiments.scenarios.formation.parts import load_target, make_camera, symmetric_T_CW
    from vision.geometric import observe_epochs, observe_trials, surface_features

    _, cfg = load_config(CONFIGS / "003_fig5_fig6.toml", overrides={"formation.distance_m": 70.0})
    cam, target, T = make_camera(cfg), load_target(cfg), symmetric_T_CW(cfg)
    feats = surface_features(target, n_features=1500, surface="outer")
    R, E = 3, 4
    q = random_attitudes(np.random.default_rng(5), R * E).reshape(R, E, 4)
    sun = np.broadcast_to(np.array([0.8, -0.4, 0.45]), (R, E, 3))
    TT = np.broadcast_to(T, (R, E, *T.shape))
    many = observe_trials(cam, TT, target, q, sun, rngs=[np.random.default_rng(s) for s in range(R)],
                          features=feats, noise_model="calibrated", batch_size=8)
    for r in range(R):
        one = observe_epochs(cam, TT[r], target, q[r], sun[r], rng=np.random.default_rng(r), features=feats,
                             noise_model="calibrated")
        for a, b in zip(many[r], one, strict=True):
            np.testing.assert_array_equal(a.feature_id, b.feature_id)
            np.testing.assert_array_equal(a.uv_px, b.uv_px)
            np.testing.assert_array_equal(a.descriptors, b.descriptors)
            np.testing.assert_array_equal(a.track_sigma_px, b.track_sigma_px)
    assert sum(o.n_tracks for trial in many for o in trial) > 0
