"""Heavy-tailed keypoint errors as a lognormal scale mixture of Gaussians.

Rendered keypoints err far from Gaussian: over the calibration's points the triangulation NEES has
a mean of 3 (the σ inflation makes it so) but a median well below a χ² variable's, a narrow core and
a tail of keypoints whose error is several times their σ.  A keypoint whose error is Gaussian with
variance ``w σ²``, ``w`` lognormal of mean 1 (``log w ~ N(−s²/2, s²)``), gives a NEES ``w · (m/k) χ²_k``
(``k`` degrees of freedom, mean ``m``) whose median falls with ``s`` while its mean stays ``m``:

- :func:`mixture_cdf`: ``P(w (m/k) χ²_k ≤ x)``, by Gauss–Hermite quadrature over ``log w``;
- :func:`spread_for_median`: the ``s`` whose mixture over a set of points (their degrees of freedom)
  has a given median: how the calibration turns measured NEES into the spread the calibrated
  geometric mode draws (:mod:`vision.geometric_calibrated`);
- :func:`location_information`: the Fisher information about a shift of one such error, over a
  Gaussian's of the same variance.  A heavy tail carries more information than a Gaussian of the same
  variance (the Gaussian is the least informative at a given variance), so the Cramér–Rao bound of
  the rendered errors lies below the Gaussian bound the product reports, by ``1/√I`` in σ for
  independent errors, and by up to ``e^{−s²/2}`` were every multiplier known (information ``e^{s²}``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import brentq
from scipy.stats import chi2

__all__ = ["location_information", "mixture_cdf", "spread_for_median"]

#: Gauss–Hermite nodes and weights of the standard normal (probabilists'), 61 points
_Z, _W = np.polynomial.hermite_e.hermegauss(61)
_W = _W / _W.sum()
#: largest spread searched (a factor e^4 in σ² at one standard deviation)
_MAX_SPREAD = 4.0


def mixture_cdf(x: ArrayLike, spread: float, dof: int, mean: float = 3.0) -> np.ndarray:
    """``P(w (mean/dof) χ²_dof ≤ x)`` with ``log w ~ N(−spread²/2, spread²)``."""
    x = np.asarray(x, dtype=float)
    w = np.exp(float(spread) * _Z - 0.5 * float(spread) ** 2)
    return np.sum(_W * chi2.cdf(x[..., None] * dof / (mean * w), dof), axis=-1)


def spread_for_median(median: float, dof_counts: dict[int, int], mean: float = 3.0) -> float:
    """The spread ``s`` whose mixture, over points with these degrees of freedom (``{dof: points}``), has
    this pooled median; 0 where the Gaussian's own median is no higher (no tail to explain)."""
    counts = {int(k): float(n) for k, n in dof_counts.items() if n > 0}
    if not counts or not np.isfinite(median) or median <= 0:
        raise ValueError(f"spread_for_median: need a positive median and points, got {median!r}, {dof_counts!r}")
    total = sum(counts.values())

    def excess(s: float) -> float:
        return sum(n * float(mixture_cdf(median, s, k, mean)) for k, n in counts.items()) / total - 0.5

    if excess(0.0) >= 0.0:                  # the observed median at or above the Gaussian's
        return 0.0
    if excess(_MAX_SPREAD) < 0.0:
        return _MAX_SPREAD
    return float(brentq(excess, 0.0, _MAX_SPREAD, xtol=1e-6))


def location_information(spread: float) -> float:
    """Fisher information about the location of one error ``√w · z`` (``z`` standard normal, ``w``
    lognormal of mean 1 and log spread ``spread``: unit variance), ``∫ p′² / p``; 1 for a Gaussian."""
    from scipy.integrate import quad

    s = float(spread)
    if s < 1e-6:
        return 1.0
    w = np.exp(s * _Z - 0.5 * s * s)

    def ratio(x: float) -> float:
        pdf = _W * np.exp(-0.5 * x * x / w) / np.sqrt(2.0 * np.pi * w)
        p = float(np.sum(pdf))
        return float(np.sum(pdf * x / w)) ** 2 / p if p > 0.0 else 0.0

    return 2.0 * float(quad(ratio, 0.0, 12.0 * float(np.exp(0.5 * s * s + 2.0 * s)), limit=400)[0])
