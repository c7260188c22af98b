"""observation.earth_background / earth_albedo / glints: validation and their way to the rendered observer."""

from __future__ import annotations

import numpy as np
import pytest

from experiments.config import ConfigError, load_config
from experiments.scenarios.formation.parts import make_observer
from orbits.two_body import R_EARTH_M


def _cfg(**overrides):
    return load_config({"kind": "formation", "seed": 11}, overrides)[1]


@pytest.mark.parametrize(("overrides", "message"), [
    ({"observation.earth_albedo": 1.5}, "observation.earth_albedo: Input should be less than or equal to 1 (got 1.5)"),
    ({"observation.earth_albedo": -0.1}, "observation.earth_albedo: Input should be greater than or equal to 0"),
    ({"observation.glints": "yes"}, "observation.glints: Input should be a valid boolean (got 'yes')"),
    ({"observation.earth_background": True}, "observation.earth_background: true needs mode = 'rendered'"),
    ({"observation.glints": True}, "observation.glints: true needs mode = 'rendered'"),
])
def test_bad_values_give_one_line_naming_the_key(overrides, message):
    with pytest.raises(ConfigError) as err:
        _cfg(**overrides)
    text = str(err.value)
    assert "\n" not in text and text.startswith(message), text


def test_defaults_are_off_and_the_options_reach_the_rendered_observer():
    off = _cfg(**{"observation.mode": "rendered"})
    assert (off.observation.earth_background, off.observation.glints, off.observation.earth_albedo) == (False, False, 0.3)
    on = _cfg(**{"observation.mode": "rendered", "observation.earth_background": True, "observation.glints": True,
                 "observation.earth_albedo": 0.25, "formation.orbit_altitude_km": 500.0})
    obs = make_observer(on)
    assert obs.earth_background and obs.glints and obs.earth_albedo == 0.25 and obs.earth_seed == 11
    assert obs.orbit_radius_m == pytest.approx(R_EARTH_M + 500e3)
    assert not make_observer(off).earth_background


def test_the_rendered_observer_sees_the_earth_only_when_asked():
    from vision.camera import look_at

    base = {"observation.mode": "rendered", "camera.width_px": 256, "camera.height_px": 256}
    eye = 40.0 * np.array([0.8, 0.36, 0.48])
    T = np.stack([look_at(eye, np.zeros(3), np.array([0.0, 0.0, 1.0]))] * 2)
    T[1] = look_at(eye + np.array([0.0, 3.0, 0.0]), np.zeros(3), np.array([0.0, 0.0, 1.0]))
    q, sun = np.array([0.9, 0.1, 0.3, 0.2]) / np.linalg.norm([0.9, 0.1, 0.3, 0.2]), np.array([0.7, 0.5, 0.4])
    plain = make_observer(_cfg(**base)).observe(T, q, sun, rng=np.random.default_rng(1))
    again = make_observer(_cfg(**base)).observe(T, q, sun, rng=np.random.default_rng(1))
    earth = make_observer(_cfg(**base, **{"observation.earth_background": True})).observe(
        T, q, sun, rng=np.random.default_rng(1))
    np.testing.assert_array_equal(plain.uv_px, again.uv_px)
    assert plain.n_tracks > 0 and earth.n_tracks > 0
    assert plain.n_tracks != earth.n_tracks or not np.array_equal(plain.uv_px, earth.uv_px)
