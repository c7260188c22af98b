"""Relative pose in paper 001's parameters (Gibbs vector of one of four sets, and translation), and the solver's result.

Model and conventions
---------------------
* Point map (001 eq 6, flag P001-2, docs/papers.md#p001-2): ``X_C = R_CT X_T + r_TC_C``.  ``R_CT``
  maps target-body components to camera components (it is the paper's ``R``) and ``r_TC_C`` (the
  paper's ``t``) is the position of the target origin relative to the camera, in camera components.
* Attitude (001 eq 8′, flag P001-3, docs/papers.md#p001-3): inside the solver, Shuster's convention,
  as in the paper: ``R_CT = A(g^(i)) R^(i)`` with ``A`` Shuster's attitude matrix
  (:func:`attitude.gibbs.shuster_matrix_from_gibbs_set`).  At the boundary, the project's Hamilton
  quaternion ``q_CT`` (``matrix_from_quat(q_CT) = R_CT``); ``(g, i)`` is the parameter set of the
  Hamilton ``q_TC`` (:attr:`GibbsPose.q_CT`, :meth:`GibbsPose.from_quat`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from attitude.gibbs import (
    best_gibbs_set,
    gibbs_set_from_quat,
    quat_from_gibbs_set,
    shuster_matrix_from_gibbs_set,
)
from attitude.quaternion import check_quat, quat_conjugate

__all__ = ["FAILURE_REASONS", "GibbsPose", "RodriguesPoseResult"]


#: Values of :attr:`RodriguesPoseResult.failure_reason` ("" means success).
FAILURE_REASONS = (
    "too_few_points",  # fewer than 3 visible points (001 eq 27 needs n >= 3)
    "rank_deficient",  # rank A < 6 (001 eq 27: "extract more features")
    "behind_camera",  # a visible point predicted at Z_C <= 0: the linearisation is meaningless
    "gibbs_singular",  # non-switching variant: an update carried the fixed set through 180°
    "diverged",  # non-finite iterate
    "not_converged",  # eps_attitude / eps_translation_m not reached within max_iterations
)


@dataclass(frozen=True)
class GibbsPose:
    """Relative pose in 001's parameters: Gibbs vector of a parameter set, and translation.

    Attributes
    ----------
    g : (..., 3) ndarray
        Gibbs vector of parameter set ``gibbs_set`` (001 eq 4, Shuster convention) such that
        ``R_CT = A(g) R^(i)`` (001 eq 8′).  NaN where a solve failed.
    gibbs_set : (...,) int ndarray
        Parameter-set index ``i`` in {0, 1, 2, 3} (reference frame ``r^(i)`` = ``r^(0)`` turned by π
        about its own i-th axis).
    r_TC_C : (..., 3) ndarray
        Target origin relative to the camera, camera components, m (001's ``t``).
    """

    g: np.ndarray
    gibbs_set: np.ndarray
    r_TC_C: np.ndarray

    @classmethod
    def from_quat(cls, q_CT: ArrayLike, r_TC_C: ArrayLike, *, gibbs_set: ArrayLike | None = None) -> GibbsPose:
        """Pose from the project's Hamilton ``q_CT`` (``R_CT = matrix_from_quat(q_CT)``) and ``r_TC_C``.

        ``gibbs_set=None`` picks the set whose denominator is the largest quaternion component
        (every ``|g_j| <= 1``, :func:`attitude.gibbs.best_gibbs_set`); an explicit set (e.g. 0 for the
        non-switching variant) is used as given and may be singular (``inf`` components).
        """
        q_CT = check_quat(q_CT, name="q_CT", unit=False)
        r = np.asarray(r_TC_C, dtype=float)
        if r.ndim == 0 or r.shape[-1] != 3 or not np.all(np.isfinite(r)):
            raise ValueError(f"r_TC_C: expected finite array of shape (..., 3), got shape {r.shape}")
        q_TC = quat_conjugate(q_CT)  # Shuster's A(q_TC) = R_TCᵀ = R_CT (flag P001-3)
        if gibbs_set is None:
            g, i = best_gibbs_set(q_TC)
        else:
            i = np.asarray(gibbs_set)
            if not np.issubdtype(i.dtype, np.integer) or np.any((i < 0) | (i > 3)):
                raise ValueError(f"gibbs_set: must be integers in 0..3, got {gibbs_set!r}")
            with np.errstate(over="ignore"):  # a set within ~1e-308 of its singularity: inf
                g = gibbs_set_from_quat(q_TC, i)
            i = np.broadcast_to(i, g.shape[:-1])
        shape = np.broadcast_shapes(g.shape, r.shape)
        return cls(np.broadcast_to(g, shape).copy(), np.broadcast_to(i, shape[:-1]).astype(int),
                   np.broadcast_to(r, shape).copy())

    @property
    def shape(self) -> tuple[int, ...]:
        """Batch shape."""
        return self.g.shape[:-1]

    @property
    def valid(self) -> np.ndarray:
        """``(...,)`` bool: the pose holds finite numbers."""
        return np.all(np.isfinite(self.g), -1) & np.all(np.isfinite(self.r_TC_C), -1)

    @property
    def R_CT(self) -> np.ndarray:
        """``(..., 3, 3)`` target→camera matrix ``A(g^(i)) R^(i)`` (001 eq 8′); NaN where invalid."""
        out = np.full(self.shape + (3, 3), np.nan)
        ok = self.valid
        out[ok] = shuster_matrix_from_gibbs_set(self.g[ok], self.gibbs_set[ok])
        return out

    @property
    def q_CT(self) -> np.ndarray:
        """``(..., 4)`` Hamilton ``q_CT`` (scalar first, ``w >= 0``); NaN where invalid."""
        out = np.full(self.shape + (4,), np.nan)
        ok = self.valid
        out[ok] = quat_conjugate(quat_from_gibbs_set(self.g[ok], self.gibbs_set[ok]))
        return out

    def where(self, mask: ArrayLike, other: GibbsPose) -> GibbsPose:
        """Element-wise choice: ``self`` where ``mask`` is true, ``other`` elsewhere."""
        m = np.asarray(mask, dtype=bool)
        return GibbsPose(np.where(m[..., None], self.g, other.g), np.where(m, self.gibbs_set, other.gibbs_set),
                         np.where(m[..., None], self.r_TC_C, other.r_TC_C))


@dataclass(frozen=True)
class RodriguesPoseResult:
    """Result of :func:`solve_pose_rodrigues` (batch shape ``...``) or :func:`track_pose_rodrigues`.

    Attributes
    ----------
    pose : GibbsPose
        The estimate; NaN where the solve failed.
    ok : (...,) bool ndarray
    failure_reason : (...,) str ndarray
        ``""`` on success, else one of :data:`FAILURE_REASONS`.
    iterations : (...,) int ndarray
        Gauss–Newton updates applied.
    switches : (...,) int ndarray
        Parameter-set switches (001 eq 5) made during the solve.
    n_points : (...,) int ndarray
        Visible points used.
    residual_rms_m : (...,) ndarray
        RMS focal-plane reprojection residual at the returned pose (per coordinate, unweighted), m;
        evaluated to first order in the last update, whose size is below ε₁, ε₂.
    """

    pose: GibbsPose
    ok: np.ndarray
    failure_reason: np.ndarray
    iterations: np.ndarray
    switches: np.ndarray
    n_points: np.ndarray
    residual_rms_m: np.ndarray

    @property
    def q_CT(self) -> np.ndarray:
        """Hamilton ``q_CT`` ``(..., 4)``; NaN where failed."""
        return self.pose.q_CT

    @property
    def R_CT(self) -> np.ndarray:
        """``R_CT`` ``(..., 3, 3)``; NaN where failed."""
        return self.pose.R_CT

    @property
    def r_TC_C(self) -> np.ndarray:
        """Target position relative to the camera, camera components ``(..., 3)``, m; NaN where failed."""
        return self.pose.r_TC_C
