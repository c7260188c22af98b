"""Attitude measurement noise: the error-angle ↔ per-axis σ convention of the 003 EKF study.

003 §3.3 gives the measurement noise of Experiments B–D as an "attitude-angle error" e (0.2°, 0.6°,
or a range read off Figs 5–6).  coobs fixes the convention (docs/filters.md): e is the 2-norm of the
three-axis error, so each axis gets ``σ_axis = e/√3`` and a noisy attitude is
``q̃ = q ⊗ exp(½ δθ)``, ``δθ ~ N(0, σ_axis² I₃)``.  Then the error angle ``|δθ|`` follows a Maxwell
distribution with RMS exactly e and mean ``σ_axis √(8/π)``.

:func:`attitude_noise_cell` is a sweep cell (``experiments.sweep``) that checks this convention by
Monte Carlo over a grid of e: its metrics have those closed forms, which makes it the reference
cell for the sweep engine's own tests.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from attitude.quaternion import quat_angle_between, quat_from_rotvec, quat_multiply, quat_normalize
from experiments.sweep import Metric, SweepCell, child_seeds

__all__ = ["axis_sigma_rad", "perturb_attitude", "attitude_noise_cell", "ATTITUDE_NOISE_CELL"]


def axis_sigma_rad(angle_error_rad: float) -> float:
    """Per-axis standard deviation ``e/√3`` of an attitude-angle error ``e`` (the 2-norm over three axes), rad."""
    e = float(angle_error_rad)
    if not np.isfinite(e) or e < 0:
        raise ValueError(f"angle_error_rad: must be finite and >= 0, got {e!r}")
    return e / np.sqrt(3.0)


def perturb_attitude(q: np.ndarray, angle_error_rad: float, *, rng: np.random.Generator | int | None = None) -> np.ndarray:
    """Noisy attitudes ``q ⊗ exp(½ δθ)`` with ``δθ ~ N(0, (e/√3)² I₃)`` in body axes.

    Parameters
    ----------
    q : ndarray, shape (..., 4)
        True unit quaternions (scalar first, Hamilton).
    angle_error_rad : float
        Attitude-angle error e (RMS of the error angle), rad.
    rng : Generator, int or None
        Random source.

    Returns
    -------
    ndarray, shape (..., 4)
        The perturbed unit quaternions.
    """
    sigma = axis_sigma_rad(angle_error_rad)
    q = np.asarray(q, dtype=float)
    rng = np.random.default_rng(rng)
    dtheta = rng.normal(0.0, sigma, size=(*q.shape[:-1], 3))
    return quat_normalize(quat_multiply(q, quat_from_rotvec(dtheta)))


def attitude_noise_cell(params: Mapping[str, Any], seeds: Sequence[np.random.SeedSequence]) -> dict[str, np.ndarray]:
    """Sweep cell: RMS and mean error angle of :func:`perturb_attitude` for one e.

    Parameters
    ----------
    params : mapping
        ``angle_error_deg`` (e, degrees, >= 0) and ``samples`` (attitudes per trial, >= 1).
    seeds : sequence of SeedSequence
        One per trial.

    Returns
    -------
    dict
        ``rms_angle_deg`` and ``mean_angle_deg``, shape ``(trials,)``; ``expected_rms_deg`` and
        ``expected_mean_deg`` (closed forms ``e`` and ``(e/√3)√(8/π)``), per cell.
    """
    e_deg = float(params["angle_error_deg"])
    samples = int(params["samples"])
    if not np.isfinite(e_deg) or e_deg < 0:
        raise ValueError(f"angle_error_deg: must be finite and >= 0, got {e_deg!r}")
    if samples < 1:
        raise ValueError(f"samples: must be >= 1, got {samples}")
    e = np.deg2rad(e_deg)
    sigma = axis_sigma_rad(e)
    rms = np.empty(len(seeds))
    mean = np.empty(len(seeds))
    for t, ss in enumerate(seeds):
        rng_truth, rng_noise = (np.random.default_rng(s) for s in child_seeds(ss, 2))
        q = quat_normalize(rng_truth.normal(size=(samples, 4)))
        ang = quat_angle_between(q, perturb_attitude(q, e, rng=rng_noise))
        rms[t] = np.rad2deg(np.sqrt(np.mean(ang**2)))
        mean[t] = np.rad2deg(np.mean(ang))
    return {
        "rms_angle_deg": rms,
        "mean_angle_deg": mean,
        "expected_rms_deg": np.asarray(e_deg),
        "expected_mean_deg": np.asarray(np.rad2deg(sigma * np.sqrt(8.0 / np.pi))),
    }


ATTITUDE_NOISE_CELL = SweepCell(
    fn=attitude_noise_cell,
    metrics={
        "rms_angle_deg": Metric("deg", long_name="RMS error angle of the perturbed attitudes"),
        "mean_angle_deg": Metric("deg", long_name="mean error angle of the perturbed attitudes"),
        "expected_rms_deg": Metric("deg", per_trial=False, long_name="closed-form RMS error angle, e"),
        "expected_mean_deg": Metric("deg", per_trial=False,
                                    long_name="closed-form mean error angle, (e/sqrt 3) sqrt(8/pi)"),
    },
    name="attitude_noise",
)
