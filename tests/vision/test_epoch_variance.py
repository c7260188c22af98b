"""vision.epoch_variance: the epoch's variance factor from epipolar residuals, against analytic truth."""

import numpy as np
import pytest
from scipy.stats import chi2

from formation.geometry import symmetric_views
from vision.camera import PinholeCamera
from vision.epoch_variance import epipolar_chi2, epoch_variance_factor

CAM = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)
GATE = chi2.isf(0.001, 1)


def _tracks(n_tracks: int, sigma_true: np.ndarray, rng: np.random.Generator, n_views: int = 3):
    """Tracks of random points of a 4 m body 40 m away, seen by 3 cameras 10° apart, with noise σ_true."""
    T = symmetric_views(n_views, 40.0, 10.0).T_CW
    X = rng.uniform(-2.0, 2.0, (n_tracks, 3))
    uv = np.stack([CAM.project_world(X, T[v])[0] for v in range(n_views)], axis=1)
    uv = uv + sigma_true[..., None] * rng.standard_normal(uv.shape)
    K = np.stack([CAM.K] * n_views)
    return uv, K, T


def _truncated_mean(c: float) -> float:
    """E[cX | cX < GATE] for X ~ χ²(1): E[X 1(X < t)] = P(χ²(3) < t), t = GATE / c."""
    t = GATE / c
    return c * chi2.cdf(t, 3) / chi2.cdf(t, 1)


@pytest.mark.parametrize("ratio", [1.0, 2.0, 0.5])
def test_factor_is_the_squared_ratio_of_the_true_to_the_given_sigma(ratio):
    """Keypoints drawn with σ_true = ratio · σ (σ varying per keypoint, 0.1-0.4 px) give the factor
    ratio², less what the χ²(1) gate truncates (analytic), within 4 % (3 × 3000 pairs)."""
    rng = np.random.default_rng(7)
    sigma = rng.uniform(0.1, 0.4, (3000, 3))
    uv, K, T = _tracks(3000, ratio * sigma, rng)
    c2 = epipolar_chi2(uv, K, T, sigma)
    assert c2.shape == (9000,)
    expected = _truncated_mean(ratio ** 2)
    got = epoch_variance_factor(uv, K, T, sigma, prior_pairs=1e-9)
    assert got == pytest.approx(expected, rel=0.04)
    if ratio == 1.0:
        assert np.mean(c2) == pytest.approx(1.0, rel=0.05)      # untruncated: χ²(1) has mean 1


def test_few_pairs_shrink_towards_one_and_none_give_one():
    rng = np.random.default_rng(1)
    sigma = np.full((4, 2), 0.2)
    uv, K, T = _tracks(4, 3.0 * sigma, rng, n_views=2)           # 4 pairs, true factor ~9 (gated)
    c2 = epipolar_chi2(uv, K, T, sigma)
    kept = c2[c2 < GATE]
    assert epoch_variance_factor(uv, K, T, sigma, prior_pairs=10.0) == pytest.approx((kept.sum() + 10.0) / (kept.size + 10.0))
    uv[:, 1] = np.nan                                          # no track seen in both views
    assert epoch_variance_factor(uv, K, T, sigma) == 1.0


@pytest.mark.parametrize(("kw", "value"), [("gate_probability", 1.0), ("gate_probability", 0.0), ("prior_pairs", 0.0)])
def test_bad_options_are_refused_by_name(kw, value):
    rng = np.random.default_rng(2)
    sigma = np.full((5, 2), 0.2)
    uv, K, T = _tracks(5, sigma, rng, n_views=2)
    with pytest.raises(ValueError, match=kw):
        epoch_variance_factor(uv, K, T, sigma, **{kw: value})
