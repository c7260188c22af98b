"""The lognormal scale mixture of Gaussian errors (vision.calibration.scale_mixture)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2

from vision.calibration.scale_mixture import location_information, mixture_cdf, spread_for_median


def test_without_spread_the_mixture_is_the_scaled_chi2():
    x = np.linspace(0.1, 12.0, 25)
    for dof in (1, 2, 3):
        np.testing.assert_allclose(mixture_cdf(x, 0.0, dof), chi2.cdf(x * dof / 3.0, dof), atol=1e-12)


@pytest.mark.parametrize("spread", [0.3, 0.8, 1.2])
def test_the_mixture_matches_monte_carlo_and_the_spread_is_recovered_from_its_median(spread):
    """Points of 2 and 3 degrees of freedom (as two- and three-view tracks) with lognormal σ² multipliers:
    the quadrature CDF matches the sample's at its quartiles, and the spread fitted to the pooled
    median is the one drawn, within the sample's own error."""
    rng = np.random.default_rng(7)
    n2, n3 = 60_000, 40_000
    w = np.exp(spread * rng.normal(size=n2 + n3) - 0.5 * spread**2)
    nees = w * np.r_[1.5 * rng.chisquare(2, n2), rng.chisquare(3, n3)]
    for q in (0.25, 0.5, 0.75):
        x = np.quantile(nees, q)
        pooled = (n2 * mixture_cdf(x, spread, 2) + n3 * mixture_cdf(x, spread, 3)) / (n2 + n3)
        assert abs(pooled - q) < 0.005
    assert spread_for_median(float(np.median(nees)), {2: n2, 3: n3}) == pytest.approx(spread, abs=0.03)
    assert np.mean(nees) == pytest.approx(3.0, rel=0.03)          # the mean stays 3: only the shape changes


def test_a_median_at_or_above_the_gaussian_gives_no_spread_and_bad_input_one_line():
    assert spread_for_median(float(chi2.median(3)), {3: 10}) == 0.0
    assert spread_for_median(5.0, {2: 3, 3: 4}) == 0.0
    with pytest.raises(ValueError, match="spread_for_median: need a positive median"):
        spread_for_median(float("nan"), {3: 10})


@settings(max_examples=25, deadline=None)
@given(st.floats(0.0, 1.5), st.floats(0.01, 0.3))
def test_a_heavy_tail_carries_more_location_information_than_a_gaussian_and_less_than_known_multipliers(s, ds):
    """At unit variance the Gaussian is the least informative about a shift (information 1); knowing
    each error's multiplier would give E[1/w] = e^{s²}; the mixture lies between and grows with s."""
    info = location_information(s)
    assert 1.0 - 1e-6 <= info <= np.exp(s * s) + 1e-6
    assert location_information(s + ds) >= info - 1e-6


def test_location_information_is_the_variance_of_the_score():
    """Monte Carlo: the mean square of the score p'/p of errors drawn from the mixture (s = 1)."""
    rng = np.random.default_rng(11)
    s, n = 1.0, 400_000
    x = np.sqrt(np.exp(s * rng.normal(size=n) - 0.5 * s * s)) * rng.normal(size=n)
    z, w = np.polynomial.hermite_e.hermegauss(81)
    w = w / w.sum()
    var = np.exp(s * z - 0.5 * s * s)
    pdf = w * np.exp(-0.5 * x[:, None] ** 2 / var) / np.sqrt(2 * np.pi * var)
    score = np.sum(pdf * x[:, None] / var, axis=1) / np.sum(pdf, axis=1)
    assert location_information(s) == pytest.approx(np.mean(score**2), rel=0.02)
