"""Cross-view survival factors of a keypoint's Sun phase, surface material, relative brightness and view angle.

The calibration measures, for every cross-view pair, the keypoints of the first view the second
camera sees (*matchable*) and those matched correctly (*correct*), per Sun phase bin of the pair, per
surface material and per relative-brightness bin of the keypoint (:mod:`vision.face_brightness`),
and jointly over those and the keypoint's view-angle bin (the angle between its surface normal and
the direction to the camera, :data:`vision.calibration.COS_VIEW_EDGES`).
The geometric mode multiplies the survival of the pair's range and angle, ``S(z/f, angle)``, by one
factor per class of each kind.

- **Marginal factors** (files with the per-kind counts only): the correct matches of a class over
  those its matchable keypoints would have at ``S``, pooled over ranges and angles.  Multiplying
  three of them counts an effect twice where the kinds are correlated (the brightest keypoints lie
  mostly on one material and at one phase, so a material's factor also carries part of the
  brightness effect, and the other way round).
- **Joint factors** (files with the counts per (phase, material, brightness, view) class,
  ``cross_view.joint_expected`` and ``joint_correct``): the main-effects Poisson model
  ``correct ~ Poisson(expected · f_phase · f_material · f_brightness · f_view)`` fitted by iterative
  proportional fitting, its maximum-likelihood solution: the product of the four factors
  reproduces every kind's measured correct matches at once (the shipped counts converge in under
  50 sweeps, 5 ms).  Keypoints seen at grazing view (mostly
  on silhouettes and the edges of faces, where the surface point under a keypoint changes with the
  viewpoint) survive far less than those seen face-on: only the joint counts have the view factor.

A class expected to have fewer than :data:`MIN_EXPECTED_CORRECT` correct matches gets no factor of
its own: a phase bin takes the nearest bin's, a material, brightness or view class 1.
"""

from __future__ import annotations

import numpy as np

from vision.calibration.tables import fill_nearest, table

__all__ = ["MIN_EXPECTED_CORRECT", "fit_main_effects", "survival_factors"]

#: correct matches a Sun phase bin, material, brightness or view class must be expected to have (under
#: no such effect) to get its own survival factor
MIN_EXPECTED_CORRECT = 20.0
#: the kinds of class, in the order of the joint counts' axes
KINDS = ("phase", "material", "brightness", "view")


def fit_main_effects(expected: np.ndarray, observed: np.ndarray, *, iterations: int = 500,
                     tol: float = 1e-10, fixed: list[np.ndarray] | None = None) -> list[np.ndarray]:
    """Factors ``f_k`` (one per axis) of the Poisson model ``observed ~ expected · Π_k f_k[i_k]`` by
    iterative proportional fitting: at convergence every axis's margin of the model equals the
    observed margin.  Classes with no expected count keep factor 1, and so do the classes marked in
    ``fixed`` (one bool array per axis; their margins are then not matched).  The scale is shared:
    each factor but the last has mean 1 weighted by its margin of ``expected``."""
    e = np.asarray(expected, dtype=float)
    o = np.asarray(observed, dtype=float)
    if e.shape != o.shape:
        raise ValueError(f"expected and observed must have one shape, got {e.shape} and {o.shape}")
    f = [np.ones(n) for n in e.shape]
    axes = range(e.ndim)
    for _ in range(int(iterations)):
        step = 0.0
        for k in axes:
            model = e * _outer(f, e.ndim)
            other = tuple(a for a in axes if a != k)
            m, obs_k = model.sum(axis=other), o.sum(axis=other)
            with np.errstate(invalid="ignore", divide="ignore"):
                r = np.where(m > 0, obs_k / m, 1.0)
            if fixed is not None:
                r = np.where(fixed[k], 1.0, r)
            f[k] = f[k] * r
            step = max(step, float(np.max(np.abs(np.log(np.where(r > 0, r, 1.0))))))
        if step < tol:
            break
    for k in range(e.ndim - 1):                                        # move the scale into the last factor
        w = e.sum(axis=tuple(a for a in axes if a != k))
        s = float(np.sum(w * f[k]) / np.sum(w)) if np.sum(w) > 0 else 1.0
        f[k], f[-1] = f[k] / s, f[-1] * s
    return f


def _outer(f: list[np.ndarray], ndim: int) -> np.ndarray:
    out = np.ones([1] * ndim)
    for k, v in enumerate(f):
        out = out * v.reshape([-1 if a == k else 1 for a in range(ndim)])
    return out


def _marginal(cv: dict, by: str) -> np.ndarray | None:
    """A kind's marginal factor (module docstring); NaN where too few correct matches are expected."""
    if f"{by}_correct" not in cv:
        return None
    correct = np.asarray(cv[f"{by}_correct"], dtype=float)          # (R, A, classes)
    matchable = np.asarray(cv[f"{by}_matchable"], dtype=float)
    expected = np.sum(matchable * table(cv["survival"])[:, :, None], axis=(0, 1))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(expected >= MIN_EXPECTED_CORRECT, correct.sum(axis=(0, 1)) / expected, np.nan)


def _joint(cv: dict) -> dict[str, np.ndarray]:
    """The kinds' joint factors (module docstring); NaN where too few correct matches are expected."""
    expected = np.asarray(cv["joint_expected"], dtype=float)        # (phase, material, brightness, view)
    f = fit_main_effects(expected, np.asarray(cv["joint_correct"], dtype=float))
    out = {}
    for k, by in enumerate(KINDS):
        e_k = expected.sum(axis=tuple(a for a in range(len(KINDS)) if a != k))
        out[by] = np.where(e_k >= MIN_EXPECTED_CORRECT, f[k], np.nan)
    return out


def survival_factors(cv: dict) -> dict[str, np.ndarray | None]:
    """``{"phase", "material", "brightness", "view"}`` → factor per class (None where the file has no counts of
    that kind) from a target's ``cross_view`` section: joint where it has the joint counts, else
    marginal; gaps filled (module docstring)."""
    raw = _joint(cv) if "joint_correct" in cv else {by: _marginal(cv, by) for by in KINDS[:3]} | {"view": None}
    out: dict[str, np.ndarray | None] = {}
    for by, g in raw.items():
        if g is None:
            out[by] = None
        elif by == "phase":
            out[by] = fill_nearest(list(g))
        else:
            out[by] = np.where(np.isfinite(g), g, 1.0)
    return out
