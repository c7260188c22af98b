"""Synthetic marker-matching problems with known labels, for the Monte Carlo of paper 000's matcher."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from vision.tof import MarkerPlate

__all__ = ["MatchingTrials", "random_matching_trials"]


@dataclass(frozen=True)
class MatchingTrials:
    """A batch of synthetic matching problems with their true labels.

    Attributes
    ----------
    points_S : (T, n, 3) ndarray
        Observed points (m), in random order.
    truth : (T, n) int ndarray
        Model index of every observed point, −1 for a spurious point.
    """

    points_S: np.ndarray
    truth: np.ndarray


def random_matching_trials(plate: MarkerPlate, n_trials: int, *, n_missing: int = 0, n_spurious: int = 0,
                           spurious: str = "volume", noise_m: float = 0.002, range_m: float = 0.7,
                           spurious_sigma_m: float = 0.150,
                           rng: np.random.Generator | int | None = None) -> MatchingTrials:
    """Random observations of the plate's markers: the Monte Carlo of 000 §3 (``docs/tof.md``).

    Each trial draws a uniformly random rotation (distances do not depend on it), places the plate
    origin at ``[0, 0, range_m]``, adds isotropic Gaussian noise ``noise_m`` to every point, removes
    ``n_missing`` random markers and adds ``n_spurious`` spurious points, then shuffles.

    Parameters
    ----------
    spurious : {"volume", "plate"}
        ``"volume"``: spurious point at the centroid of the observed points plus isotropic Gaussian
        ``spurious_sigma_m`` (A.5).  ``"plate"``: a dark blob on the plate, uniform over the plate
        at least two marker diameters from every marker (a blob closer than that would merge with
        the marker in the image), moved with the plate and noised like the markers.
    """
    if int(n_trials) != n_trials or n_trials < 1:
        raise ValueError(f"n_trials: must be an integer >= 1, got {n_trials!r}")
    q = plate.n_markers
    if not 0 <= n_missing <= q - 3:
        raise ValueError(f"n_missing: must lie in [0, {q - 3}], got {n_missing!r}")
    if n_spurious < 0:
        raise ValueError(f"n_spurious: must be >= 0, got {n_spurious!r}")
    if spurious not in ("volume", "plate"):
        raise ValueError(f"spurious: must be 'volume' or 'plate', got {spurious!r}")
    if not np.isfinite(noise_m) or noise_m < 0:
        raise ValueError(f"noise_m: must be finite and >= 0, got {noise_m!r}")

    rng = np.random.default_rng(rng)
    T = int(n_trials)
    R = Rotation.random(T, random_state=rng).as_matrix()
    model = plate.markers_C
    r = np.array([0.0, 0.0, range_m])
    obs_idx = np.argsort(rng.random((T, q)), axis=1)[:, : q - n_missing]            # kept markers
    pts = np.einsum("tij,tmj->tmi", R, model[obs_idx]) + r
    truth = obs_idx.copy()
    if n_spurious:
        if spurious == "volume":
            extra = pts.mean(axis=1, keepdims=True) + spurious_sigma_m * rng.standard_normal((T, n_spurious, 3))
        else:
            xy = _random_plate_points(plate, T * n_spurious, rng).reshape(T, n_spurious, 2)
            extra = np.einsum("tij,tmj->tmi", R, np.concatenate([xy, np.zeros((T, n_spurious, 1))], -1)) + r
        pts = np.concatenate([pts, extra], axis=1)
        truth = np.concatenate([truth, np.full((T, n_spurious), -1)], axis=1)
    pts = pts + noise_m * rng.standard_normal(pts.shape)
    perm = np.argsort(rng.random(truth.shape), axis=1)
    return MatchingTrials(np.take_along_axis(pts, perm[..., None], axis=1), np.take_along_axis(truth, perm, axis=1))


def _random_plate_points(plate: MarkerPlate, count: int, rng: np.random.Generator) -> np.ndarray:
    half = np.array([plate.width_m, plate.height_m]) / 2 - plate.marker_radius_m
    markers = np.asarray(plate.markers_xy_m)
    out = np.empty((0, 2))
    while len(out) < count:
        xy = rng.uniform(-half, half, size=(2 * count + 16, 2))
        far = np.linalg.norm(xy[:, None] - markers[None], axis=-1).min(axis=1) >= 4 * plate.marker_radius_m
        out = np.concatenate([out, xy[far]])
    return out[:count]
