"""A formation config names its closed-loop parts; they come out of the closed_loop registries."""

from __future__ import annotations

from pathlib import Path

import pydantic
import pytest

from closed_loop import ESTIMATORS, OBSERVERS, REGISTRARS
from experiments.config import load_config
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


def test_formation_config_is_frozen():
    _, cfg = load_config(CONFIGS / "quickstart.toml")
    with pytest.raises(pydantic.ValidationError):
        cfg.formation.distance_m = 10.0
    moved = cfg.model_copy(update={"formation": cfg.formation.model_copy(update={"distance_m": 60.0})})
    assert moved.formation.distance_m == 60.0 and cfg.formation.distance_m == 40.0
