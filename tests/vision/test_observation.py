"""Tests of the Observation contract common to the rendered and geometric modes."""

import numpy as np
import pytest

from vision.observation import Observation


def _cams(n):
    K = np.tile(np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]]), (n, 1, 1))
    T = np.tile(np.eye(4), (n, 1, 1))
    return K, T


def test_observation_counts_tracks_and_views_and_presence_mask():
    K, T = _cams(3)
    uv = np.full((4, 3, 2), np.nan)
    uv[0, :2] = [[1.0, 2.0], [3.0, 4.0]]
    uv[1:, 1:] = 5.0
    obs = Observation(uv, np.zeros((4, 8), np.float32), K, T, (640, 480), 0.5,
                      np.array([3, 1, -1, 2]), np.zeros((4, 3)))
    assert (obs.n_tracks, obs.n_views) == (4, 3)
    assert obs.ok
    np.testing.assert_array_equal(obs.seen.sum(axis=1), [2, 2, 2, 2])
    assert obs.descriptors.dtype == np.float32
    assert obs.image_size == (640, 480)


def test_empty_observation_carries_reason_and_zero_tracks():
    K, T = _cams(2)
    obs = Observation.empty(K, T, (640, 480), 0.3, "target in Earth shadow")
    assert obs.n_tracks == 0 and obs.n_views == 2 and not obs.ok
    assert obs.uv_px.shape == (0, 2, 2) and obs.descriptors.shape == (0, 128)
    assert obs.failure_reason == "target in Earth shadow"


@pytest.mark.parametrize("field,value", [
    ("uv_px", np.zeros((4, 2, 2))),
    ("feature_id", np.zeros(3, int)),
    ("X_T_true", np.zeros((4, 2))),
    ("pixel_sigma_px", -1.0),
    ("T_CW", np.zeros((2, 4, 4))),
])
def test_observation_rejects_inconsistent_shapes_naming_the_field(field, value):
    K, T = _cams(3)
    kw = dict(uv_px=np.zeros((4, 3, 2)), descriptors=np.zeros((4, 8), np.float32), K=K, T_CW=T,
              image_size=(640, 480), pixel_sigma_px=0.5, feature_id=np.zeros(4, int),
              X_T_true=np.zeros((4, 3)))
    kw[field] = value
    with pytest.raises(ValueError, match=field):
        Observation(**kw)
