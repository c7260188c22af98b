"""Typed measurements the attitude filters accept: a registered increment and an absolute attitude.

Both hold one epoch of a batch of ``M`` filters: every field is either one value, shared by all
trials, or ``M`` rows.  ``None`` in place of the whole measurement means that no trial has one
this epoch.

What is judged where:

* **At construction** (``ValueError``, the whole measurement is refused): wrong shapes, per-trial
  fields of different lengths, an unknown ``cov_side``, and the Hill frames ``R_NH_prev``,
  ``R_NH_now`` unless they are finite proper rotations.  These are the caller's bookkeeping, the
  same for every trial.
* **Per row, by the filter** (one trial's row, not the batch): a row of the quaternion that is
  all NaN is a *missing* measurement (the filter only propagates that trial, or only re-clones
  it for an increment; nothing is counted).  A *bad* row, that is ±inf or only partly NaN
  components, a zero quaternion (norm ``<= 1e-6``), or a covariance that is not finite or not
  positive definite, is not used either, but is counted in ``FilterState.n_rejected`` (without
  counting towards ``reset_after_rejections``).  :class:`~filters.AttitudeEKF` and
  :class:`~filters.MEKF` treat these rows identically.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from attitude.matrix import check_rotation_matrix

__all__ = ["IncrementMeasurement", "AbsoluteAttitudeMeasurement"]


def _rows(value: object, tail: tuple[int, ...], name: str) -> np.ndarray:
    """``value`` as a float array of shape ``tail`` or ``(M, *tail)``; ValueError otherwise."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a float array of shape {tail} or (M, {', '.join(map(str, tail))}), "
                         f"got {value!r}") from None
    if a.shape != tail and (a.ndim != len(tail) + 1 or a.shape[1:] != tail):
        raise ValueError(f"{name}: expected shape {tail} or (M, {', '.join(map(str, tail))}), got {a.shape}")
    return a


def _common_trials(fields: dict[str, np.ndarray], tails: dict[str, int]) -> None:
    """Fields given per trial must agree on ``M``."""
    sizes = {name: a.shape[0] for name, a in fields.items() if a.ndim > tails[name]}
    if len(set(sizes.values())) > 1:
        raise ValueError(f"trial counts differ between fields: {sizes}")


@dataclass(frozen=True)
class IncrementMeasurement:
    """Registered attitude increment of the target, observed in the Hill frame H, between two epochs.

    Attributes
    ----------
    dq_H : ndarray, shape (4,) or (M, 4)
        Scalar-first increment with ``R(dq_H) = R_HT(now) R_HT(prev)ᵀ`` (003 eq (31) in H:
        ``ρ_H(now) = R(dq_H) ρ_H(prev)``).  All-NaN rows are missing measurements; other
        non-finite rows and zero quaternions are rejected by the filter (module notes).
    cov_rotvec_H : ndarray, shape (3, 3) or (M, 3, 3)
        Covariance (rad², H components) of the rotation-vector error ``v`` of the increment;
        a trial whose covariance is not finite or not positive definite is rejected.
    R_NH_prev : ndarray, shape (3, 3) or (M, 3, 3)
        H→N rotation (``v_N = R_NH v_H``) at the earlier epoch, the one of the filter's clone.
    R_NH_now : ndarray, shape (3, 3) or (M, 3, 3)
        H→N rotation at the later epoch.
    cov_side : {"left", "right"}
        Side of the error: ``ΔR_meas = exp([v×]) ΔR_true`` ("left": in the frame of the later
        cloud) or ``ΔR_true exp([v×])`` ("right").

    Raises
    ------
    ValueError
        On a wrong shape, a non-finite or non-rotation frame, an unknown ``cov_side``, or
        per-trial fields of different lengths.
    """

    dq_H: np.ndarray
    cov_rotvec_H: np.ndarray
    R_NH_prev: np.ndarray
    R_NH_now: np.ndarray
    cov_side: Literal["left", "right"] = "left"

    def __post_init__(self) -> None:
        fields = {
            "dq_H": _rows(self.dq_H, (4,), "dq_H"),
            "cov_rotvec_H": _rows(self.cov_rotvec_H, (3, 3), "cov_rotvec_H"),
            "R_NH_prev": _rows(self.R_NH_prev, (3, 3), "R_NH_prev"),
            "R_NH_now": _rows(self.R_NH_now, (3, 3), "R_NH_now"),
        }
        for name in ("R_NH_prev", "R_NH_now"):
            check_rotation_matrix(fields[name], name=name)
        _common_trials(fields, {"dq_H": 1, "cov_rotvec_H": 2, "R_NH_prev": 2, "R_NH_now": 2})
        if self.cov_side not in ("left", "right"):
            raise ValueError(f"cov_side: expected 'left' or 'right', got {self.cov_side!r}")
        for name, value in fields.items():
            object.__setattr__(self, name, value)


@dataclass(frozen=True)
class AbsoluteAttitudeMeasurement:
    """Measured attitude of the target, ``z = q_NT ⊗ exp(e/2)`` with a body-frame error ``e``.

    Attributes
    ----------
    q_NT : ndarray, shape (4,) or (M, 4)
        Scalar-first attitude (T to N); all-NaN rows are missing measurements; other non-finite
        rows and zero quaternions are rejected by the filter (module notes).
    cov_rotvec_T : ndarray, shape (3, 3) or (M, 3, 3)
        Covariance (rad², T components) of ``e``; a trial whose covariance is not finite or not
        positive definite is rejected.  For an attitude-angle error quoted as one number use
        :func:`filters.noise_mapping.rotvec_covariance_from_angle_error`.

    Raises
    ------
    ValueError
        On a wrong shape or per-trial fields of different lengths (bad rows are judged per
        trial by the filter, module notes).
    """

    q_NT: np.ndarray
    cov_rotvec_T: np.ndarray

    def __post_init__(self) -> None:
        fields = {"q_NT": _rows(self.q_NT, (4,), "q_NT"),
                  "cov_rotvec_T": _rows(self.cov_rotvec_T, (3, 3), "cov_rotvec_T")}
        _common_trials(fields, {"q_NT": 1, "cov_rotvec_T": 2})
        for name, value in fields.items():
            object.__setattr__(self, name, value)
