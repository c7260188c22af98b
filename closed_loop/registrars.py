"""Registrars: the attitude increment of the target between two epochs' clouds (003 eq 11–13, 30–32).

A :class:`Registrar` associates the tracks of two :class:`closed_loop.frames.Frame` objects
(:func:`reconstruction.association.associate_from_observations`) and fits the rigid motion of the
matched points; the rotation is the target's attitude increment in the observation frame H
(003 eq 31–32: ``ρ_H(now) = ΔR ρ_H(prev)``).  :data:`REGISTRARS` lists the alternatives by the
names the configs use (``estimator.registration``).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from attitude.quaternion import quat_from_matrix
from closed_loop.evidence import Evidence, check_evidence, spread_information
from closed_loop.frames import Frame
from closed_loop.registry import Registry
from filters import IncrementMeasurement
from reconstruction.association import (
    Association,
    associate,
    associate_from_observations,
    associate_observation_pairs,
)
from reconstruction.registration import RigidRegistration, fit_rigid, fit_rigid_ml, fit_rigid_robust

__all__ = [
    "MatchedClouds",
    "RegistrationIncrement",
    "Registrar",
    "KabschRegistrar",
    "RobustKabschRegistrar",
    "MLRegistrar",
    "REGISTRARS",
    "residual_rotation_covariance",
]


@dataclass(frozen=True)
class MatchedClouds:
    """The associated points of two epochs, row ``i`` of each array the same surface point.

    Attributes
    ----------
    P_H, Q_H : ndarray (k, 3)
        Points at the earlier and at the later epoch, H, m.
    cov_P_H, cov_Q_H : ndarray (k, 3, 3)
        Their triangulation covariances, m².
    weight_P, weight_Q : ndarray (k,)
        Scalar triangulation weights (:attr:`reconstruction.triangulation.Triangulation.weight`).
    """

    P_H: np.ndarray
    Q_H: np.ndarray
    cov_P_H: np.ndarray
    cov_Q_H: np.ndarray
    weight_P: np.ndarray
    weight_Q: np.ndarray


@dataclass(frozen=True)
class RegistrationIncrement:
    """The registered attitude increment between two frames.

    Attributes
    ----------
    R_H : ndarray (3, 3)
        Estimated increment ΔR in H, ``ρ_H(now) = ΔR ρ_H(prev)`` (NaN when not ok).
    cov_rotvec_H : ndarray (3, 3)
        Covariance of the left rotation-vector error, rad² (from the fit, else from its residuals);
        NaN when unavailable.
    n_matches : int
        Associated point pairs.
    n_inliers : int
        Pairs used in the final fit.
    ok : bool
    failure_reason : str
        ``""`` when ok.
    inliers_prev, inliers_curr : ndarray (n_inliers,) of int
        The tracks of the earlier and of the later frame that the final fit used (empty when not ok).
    """

    R_H: np.ndarray
    cov_rotvec_H: np.ndarray
    n_matches: int
    n_inliers: int
    ok: bool
    failure_reason: str
    inliers_prev: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    inliers_curr: np.ndarray = field(default_factory=lambda: np.zeros(0, int))

    @classmethod
    def failed(cls, failure_reason: str, n_matches: int = 0) -> RegistrationIncrement:
        """A failed increment (NaN rotation and covariance)."""
        return cls(np.full((3, 3), np.nan), np.full((3, 3), np.nan), n_matches, 0, False, failure_reason)

    @property
    def usable(self) -> bool:
        """Ok and with a finite covariance: the filter can take it."""
        return bool(self.ok and np.all(np.isfinite(self.cov_rotvec_H)))

    def measurement(self, R_NH_prev: np.ndarray, R_NH_now: np.ndarray) -> IncrementMeasurement | None:
        """The filter measurement of this increment (:class:`filters.IncrementMeasurement`), or ``None``.

        Parameters
        ----------
        R_NH_prev, R_NH_now : ndarray (3, 3)
            Hill frame at the earlier epoch and now (``v_N = R_NH v_H``).

        Returns
        -------
        filters.IncrementMeasurement or None
            ``None`` when the increment is not :attr:`usable` (the filter then only re-clones).
        """
        if not self.usable:
            return None
        return IncrementMeasurement(dq_H=quat_from_matrix(self.R_H)[None], cov_rotvec_H=self.cov_rotvec_H[None],
                                    R_NH_prev=R_NH_prev, R_NH_now=R_NH_now, cov_side="left")


@dataclass(frozen=True)
class Registrar(ABC):
    """Associates two frames' tracks and fits the rigid motion of the matched points.

    Subclasses implement :meth:`fit`; :meth:`register` does the association, the checks of
    :attr:`evidence` (:mod:`closed_loop.evidence`) and the bookkeeping.
    """

    evidence: Evidence = Evidence()

    @abstractmethod
    def fit(self, pairs: MatchedClouds, *, rng: np.random.Generator,
            R0: np.ndarray | None = None) -> RigidRegistration:
        """Fit ``Q ≈ R P + t`` to the matched points.

        Parameters
        ----------
        pairs : MatchedClouds
            Associated points of the two epochs, with their covariances and weights.
        rng : numpy.random.Generator
            The registration stream (RANSAC draws); deterministic fits ignore it.
        R0 : ndarray (3, 3), optional
            A predicted rotation; an iterative fit may start from it instead of a random search
            (and falls back to the search when the start fails).

        Returns
        -------
        reconstruction.registration.RigidRegistration
            ``R`` is the attitude increment in H; ``cov[:3, :3]`` its left rotation-vector
            covariance (NaN when the method gives none).
        """

    def register(self, prev: Frame, curr: Frame, *, rng: np.random.Generator,
                 with_covariance: bool = True, view_agnostic: bool = False,
                 R0: np.ndarray | None = None) -> RegistrationIncrement:
        """The attitude increment from ``prev`` to ``curr``.

        Parameters
        ----------
        prev, curr : closed_loop.frames.Frame
            Earlier and later epoch, seen by the same cameras.
        rng : numpy.random.Generator
            Registration stream.
        with_covariance : bool
            When the fit gives no covariance (Kabsch, RANSAC), estimate it from the fit's residuals
            (:func:`residual_rotation_covariance`; the filter needs it, the error maps do not).
        view_agnostic : bool
            Associate the tracks by descriptor whatever cameras saw them (two epochs seen by
            different observers or different numbers of them: a keyframe of the target model);
            default: view by view (003 §1.5, the same cameras at both epochs).
        R0 : ndarray (3, 3), optional
            The predicted increment, passed to :meth:`fit`.

        Returns
        -------
        RegistrationIncrement
            Never raises for bad data: a failed frame, association or fit is reported in
            ``ok`` / ``failure_reason``.
        """
        why = _frames_failure(prev, curr)
        if why:
            return RegistrationIncrement.failed(why)
        if view_agnostic:
            seen_p = (prev.tri.views_used & prev.tri.valid[:, None]).any(axis=1)[:, None]
            seen_c = (curr.tri.views_used & curr.tri.valid[:, None]).any(axis=1)[:, None]
            assoc = associate(seen_p, prev.obs.descriptors, seen_c, curr.obs.descriptors, X_prev=prev.tri.X_W,
                              X_next=curr.tri.X_W, residual_prev=prev.tri.rms_reprojection_px,
                              residual_next=curr.tri.rms_reprojection_px)
        else:
            assoc = associate_from_observations(prev.obs, curr.obs, prev.tri, curr.tri)
        return self._fit_associated(prev, curr, assoc, rng=rng, with_covariance=with_covariance, R0=R0)

    def register_pairs(self, frames: Sequence[Frame], pairs: Sequence[tuple[int, int]], *,
                       rngs: Sequence[np.random.Generator], with_covariance: bool = True) -> list[RegistrationIncrement]:
        """:meth:`register` for several pairs of frames, the associations of all of them in one pass
        (:func:`reconstruction.association.associate_observation_pairs`; view by view).

        Parameters
        ----------
        frames : sequence of closed_loop.frames.Frame
            The epochs (e.g. every epoch of every trial of a cell).
        pairs : sequence of (int, int)
            ``(a, b)``: the increment from ``frames[a]`` to ``frames[b]``.
        rngs : sequence of numpy.random.Generator
            The registration stream of each pair; the fits run in the order of ``pairs``, so pairs
            sharing a generator draw from it as consecutive :meth:`register` calls would.
        with_covariance : bool
            As in :meth:`register`.

        Returns
        -------
        list of RegistrationIncrement
            Result ``p`` equals ``register(frames[a], frames[b], rng=rngs[p], with_covariance=...)``.
        """
        why = [_frames_failure(frames[a], frames[b]) for a, b in pairs]
        todo = [p for p, w in enumerate(why) if not w]
        used = sorted({e for p in todo for e in pairs[p]})
        at = {e: i for i, e in enumerate(used)}
        assoc = associate_observation_pairs([frames[e].obs for e in used], [frames[e].tri for e in used],
                                            [(at[pairs[p][0]], at[pairs[p][1]]) for p in todo])
        assoc_of = dict(zip(todo, assoc, strict=True))
        return [self._fit_associated(frames[a], frames[b], assoc_of[p], rng=rngs[p], with_covariance=with_covariance)
                if p in assoc_of else RegistrationIncrement.failed(why[p]) for p, (a, b) in enumerate(pairs)]

    def _fit_associated(self, prev: Frame, curr: Frame, assoc: Association, *, rng: np.random.Generator,
                        with_covariance: bool, R0: np.ndarray | None = None) -> RegistrationIncrement:
        """The fit, the evidence checks and the bookkeeping of :meth:`register` after the association."""
        k = int(assoc.idx_prev.size)
        if not assoc.ok:
            return RegistrationIncrement.failed(f"association: {assoc.failure_reason}", k)
        ip, iq = assoc.idx_prev, assoc.idx_next
        pairs = MatchedClouds(P_H=prev.tri.X_W[ip], Q_H=curr.tri.X_W[iq], cov_P_H=prev.tri.cov_W[ip],
                              cov_Q_H=curr.tri.cov_W[iq], weight_P=prev.tri.weight[ip], weight_Q=curr.tri.weight[iq])
        reg = self.fit(pairs, rng=rng, R0=R0)
        if not bool(reg.ok):
            return RegistrationIncrement.failed(f"registration: {reg.failure_reason}", k)
        why = check_evidence(pairs.P_H, pairs.Q_H, pairs.cov_P_H, pairs.cov_Q_H, reg.R, reg.t, reg.inliers,
                             self.evidence)
        if why:
            return RegistrationIncrement.failed(why, k)
        cov = reg.cov[:3, :3]
        if with_covariance and not np.all(np.isfinite(cov)):
            cov = residual_rotation_covariance(pairs.P_H, pairs.Q_H, reg)
        inl = np.asarray(reg.inliers, dtype=bool)
        return RegistrationIncrement(R_H=reg.R, cov_rotvec_H=cov, n_matches=k, n_inliers=int(reg.n_inliers),
                                     ok=True, failure_reason="", inliers_prev=ip[inl], inliers_curr=iq[inl])


def _frames_failure(prev: Frame, curr: Frame) -> str:
    """Why two frames cannot be registered (a failed epoch), ``""`` when both are ok."""
    if not prev.ok:
        return f"previous epoch: {prev.failure_reason}"
    if not curr.ok:
        return f"this epoch: {curr.failure_reason}"
    return ""


@dataclass(frozen=True)
class KabschRegistrar(Registrar):
    """The paper's weighted rigid registration, 003 eq (11)–(13).

    Weights ``1 / (w_P⁻¹ + w_Q⁻¹)`` of the two points' triangulation weights (the paper's
    ``1/(W_ρ + ε₀)``, flag P003-4, docs/papers.md#p003-4).
    """

    def fit(self, pairs: MatchedClouds, *, rng: np.random.Generator,
            R0: np.ndarray | None = None) -> RigidRegistration:
        """Weighted Kabsch fit (:func:`reconstruction.registration.fit_rigid`); ``rng`` and ``R0`` are unused."""
        w = 1.0 / (pairs.weight_P ** -1 + pairs.weight_Q ** -1)
        return fit_rigid(pairs.P_H, pairs.Q_H, weights=w)


@dataclass(frozen=True)
class RobustKabschRegistrar(Registrar):
    """Kabsch after a 3-point RANSAC with the covariance chi-square gate (flag P003-6's check,
    docs/papers.md#p003-6; :func:`reconstruction.registration.fit_rigid_robust`)."""

    def fit(self, pairs: MatchedClouds, *, rng: np.random.Generator,
            R0: np.ndarray | None = None) -> RigidRegistration:
        """RANSAC on the covariance-gated residuals, then a Kabsch fit of the inliers (``R0`` unused)."""
        return fit_rigid_robust(pairs.P_H, pairs.Q_H, cov_P=pairs.cov_P_H, cov_Q=pairs.cov_Q_H, rng=rng)


@dataclass(frozen=True)
class MLRegistrar(Registrar):
    """Covariance-aware maximum-likelihood registration (:func:`reconstruction.registration.fit_rigid_ml`).

    It attains the Cramér–Rao bound of :func:`reconstruction.accuracy.attitude_increment_crlb`
    and gives the increment's covariance itself.  ``kernel="cauchy"`` weights the residuals with a
    Cauchy kernel of scale ``kernel_scale`` (Mahalanobis units) for heavy-tailed keypoint errors
    (config ``estimator.ml_kernel``; :func:`reconstruction.registration.fit_rigid_ml`).
    """

    kernel: str | None = None
    kernel_scale: float = 2.5

    def fit(self, pairs: MatchedClouds, *, rng: np.random.Generator,
            R0: np.ndarray | None = None) -> RigidRegistration:
        """Maximum-likelihood fit with the points' full covariances: from ``R0`` (the translation the median of
        the pairs' ``Q − R0 P``) when given and successful, else from a robust start drawn from ``rng``."""
        if R0 is not None:
            d = pairs.Q_H - pairs.P_H @ R0.T
            t0 = np.median(d[np.all(np.isfinite(d), axis=1)], axis=0)  # the pairs' translations, robustly
            reg = fit_rigid_ml(pairs.P_H, pairs.Q_H, pairs.cov_P_H, pairs.cov_Q_H, R0=R0, t0=t0, rng=rng,
                               kernel=self.kernel, kernel_scale=self.kernel_scale)
            if bool(reg.ok):
                return reg
        return fit_rigid_ml(pairs.P_H, pairs.Q_H, pairs.cov_P_H, pairs.cov_Q_H, rng=rng, kernel=self.kernel,
                            kernel_scale=self.kernel_scale)


def residual_rotation_covariance(P: np.ndarray, Q: np.ndarray, reg: RigidRegistration) -> np.ndarray:
    """Rotation covariance of a least-squares rigid fit from its own residuals (Kabsch, RANSAC).

    With isotropic residuals of variance ``σ² = Σ‖rᵢ‖² / (3N − 6)`` per axis, the left rotation
    error of the fit has covariance ``σ² (Σᵢ [Q̃ᵢ×]ᵀ [Q̃ᵢ×])⁻¹`` (``Q̃`` the inlier points about their
    centroid).  Unlike the Cramér–Rao bound this describes the estimator actually used: the spread of
    its residuals includes the depth-elongated triangulation errors it does not weight.

    Parameters
    ----------
    P, Q : ndarray (k, 3)
        The fitted point pairs, m.
    reg : reconstruction.registration.RigidRegistration
        The fit (``R``, ``t``, ``inliers``).

    Returns
    -------
    ndarray (3, 3)
        Covariance, rad² (NaN with fewer than 3 finite inliers).
    """
    inl = np.asarray(reg.inliers, dtype=bool) & np.all(np.isfinite(P), -1) & np.all(np.isfinite(Q), -1)
    n = int(inl.sum())
    if n < 3:
        return np.full((3, 3), np.nan)
    p, q = P[inl], Q[inl]
    r = q - p @ reg.R.T - reg.t
    sigma2 = float(np.sum(r * r) / max(3 * n - 6, 1))
    return sigma2 * np.linalg.inv(spread_information(q))


#: registration method (config ``estimator.registration``) → registrar class
REGISTRARS: Registry[type[Registrar]] = Registry("registrar", {"kabsch": KabschRegistrar,
                                                               "ransac": RobustKabschRegistrar,
                                                               "ml": MLRegistrar})
