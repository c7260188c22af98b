"""A formation config names its closed-loop parts; they come out of the closed_loop registries."""

from __future__ import annotations

from pathlib import Path

import pydantic
import pytest

from closed_loop import ESTIMATORS, OBSERVERS, REGISTRARS
from experiments.config import ConfigError, load_config
from experiments.scenarios.formation.parts import make_loop

CONFIGS = Path(__file__).resolve().parents[3] / "experiments" / "configs"


@pytest.mark.parametrize("mode", ["rendered", "geometric"])
@pytest.mark.parametrize("registration", ["kabsch", "ransac", "ml"])
@pytest.mark.parametrize("filt", ["ekf", "mekf"])
def test_config_names_pick_the_registered_parts_with_their_options(mode, registration, filt):
    _, cfg = load_config(CONFIGS / "quickstart.toml", overrides={
        "observation.mode": mode, "observation.pixel_sigma_px": 0.7, "estimator.registration": registration,
        "estimator.filter": filt})
    loop = make_loop(cfg)
    assert type(loop.observer) is OBSERVERS[mode]
    assert type(loop.registrar) is REGISTRARS[registration]
    assert type(loop.estimator) is ESTIMATORS[filt]
    assert loop.observer.pixel_sigma_px == 0.7
    assert loop.observer.camera.image_size == (1024, 1024)


@pytest.mark.parametrize("registration", ["ml", "map"])
def test_ml_kernel_of_the_config_reaches_the_ml_registrar(registration):
    over = {"estimator.registration": registration, "estimator.filter": "smoother" if registration == "map" else "ekf"}
    _, plain = load_config(CONFIGS / "quickstart.toml", overrides={**over, "estimator.ml_kernel": "none"})
    _, cauchy = load_config(CONFIGS / "quickstart.toml", overrides={**over, "estimator.ml_kernel": "cauchy"})
    assert make_loop(plain).registrar.kernel is None
    assert make_loop(cauchy).registrar.kernel == "cauchy"
    with pytest.raises(ConfigError, match="estimator.ml_kernel: Input should be 'none' or 'cauchy'"):
        load_config(CONFIGS / "quickstart.toml", overrides={"estimator.ml_kernel": "huber"})


def test_formation_config_is_frozen():
    _, cfg = load_config(CONFIGS / "quickstart.toml")
    with pytest.raises(pydantic.ValidationError):
        cfg.formation.distance_m = 10.0
    moved = cfg.model_copy(update={"formation": cfg.formation.model_copy(update={"distance_m": 60.0})})
    assert moved.formation.distance_m == 60.0 and cfg.formation.distance_m == 40.0


@pytest.mark.parametrize("registration, model", [("map", True), ("ml", False)])
@pytest.mark.parametrize("estimate", [True, False])
def test_smoother_config_builds_the_smoothing_loop(registration, model, estimate):
    """``filter = "smoother"`` gives the smoothing loop; ``map`` gives it a target model with the
    configured window; the smoother starts from the prior shape or the true tensor, with the configured
    process noise."""
    import numpy as np

    from closed_loop.smoothing_loop import SmoothingLoop

    _, cfg = load_config(CONFIGS / "003_smoother_300s.toml", overrides={
        "estimator.registration": registration, "estimator.estimate_inertia": estimate,
        "estimator.viewpoint_window_deg": 25.0, "estimator.min_inliers": 12,
        "estimator.process_sigma_attitude_rad": 2e-6, "estimator.process_sigma_rate_rad_s": 3e-8})
    loop = make_loop(cfg)
    assert type(loop) is SmoothingLoop
    assert (loop.model is not None) == model
    if model:
        assert loop.model.viewpoint_window_deg == 25.0
    assert loop.registrar.evidence.min_inliers == 12
    assert loop.settings.estimate_inertia == estimate
    assert (loop.settings.process_sigma_attitude_rad, loop.settings.process_sigma_rate_rad_s) == (2e-6, 3e-8)
    expected = np.diag([1.0, 0.9, 0.8]) if estimate else cfg.inertia()
    assert np.array_equal(loop.J_prior_kg_m2, expected)
    assert not np.allclose(cfg.inertia(), np.diag(np.diag(cfg.inertia())))  # the truth is not diagonal


@pytest.mark.parametrize("override, message", [
    ({"estimator.registration": "map", "estimator.filter": "ekf"}, "'map' needs estimator.filter = 'smoother'"),
    ({"target.inertia_tensor_kg_m2": [[1.0, 2.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]}, "must be symmetric"),
    ({"target.inertia_tensor_kg_m2": [[1.0, 0.0], [0.0, 1.0]]}, "expected a 3x3 matrix"),
    ({"target.inertia_tensor_kg_m2": [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]}, "positive definite"),
    ({"target.inertia_tensor_kg_m2": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 3.0]]}, "triangle inequality"),
])
def test_bad_smoother_settings_are_one_line_errors(override, message):
    from experiments.config import ConfigError

    with pytest.raises(ConfigError, match=message) as e:
        load_config(CONFIGS / "quickstart.toml", overrides=override)
    assert "\n" not in str(e.value).strip()
