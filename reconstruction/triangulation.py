"""Multi-view triangulation with per-point covariance (003 §1.4, eq (4)–(8)).

The paper's weighted algebraic least squares (003 eq 4–6) is set up as the standard DLT on
normalised image coordinates (flag P003-3 (d), docs/papers.md#p003-3), solved linearly with the
homogeneous coordinate fixed at 1 (a 3×3 closed form), then refined by Gauss–Newton on the
reprojection error in pixels, which is the maximum-likelihood estimate under Gaussian pixel
noise.  The inverse Gauss–Newton information is the point's 3×3 covariance (first order; it equals
the Cramér–Rao bound of :func:`reconstruction.accuracy.point_covariance` at the estimate).

The paper's point "confidence" W_ρ (003 eq 7) is an algebraic residual; following flag P003-3 it
is reported here as the RMS reprojection error in pixels (``rms_reprojection_px``), and the
rejection test of 003 eq (8) becomes a chi-square gate on the normalised reprojection residual
(plus an optional pixel threshold ε_ρ).  Flag P003-4 (docs/papers.md#p003-4): W_ρ is a
residual, so a registration weight
must decrease with it (``1 / (W_ρ + ε₀)``); better, use the covariance.

Everything is vectorised over leading batch axes (trials, epochs) and over points: a batch of
``(..., M, n)`` observations is solved in one pass.  Failure is reported per point in ``valid`` /
``failure_code`` and per cloud in ``ok`` / ``failure_reason``; it never raises inside a sweep.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.stats import chi2 as _chi2

from reconstruction._geometry import (
    as_float,
    check_intrinsics,
    check_poses,
    check_positive,
    check_probability,
    chi2_quantile,
    project,
    scalar_or_array,
    sym3_inv,
)

if TYPE_CHECKING:
    from vision.observation import Observation

__all__ = [
    "POINT_OK",
    "FAILURE_TOO_FEW_VIEWS",
    "FAILURE_DEGENERATE",
    "FAILURE_BEHIND_CAMERA",
    "FAILURE_REPROJECTION",
    "FAILURE_REASONS",
    "Triangulation",
    "triangulate",
    "triangulate_from_observation",
]

#: Per-point failure codes (``Triangulation.failure_code``); 0 is an accepted point.
POINT_OK = 0
FAILURE_TOO_FEW_VIEWS = 1
FAILURE_DEGENERATE = 2
FAILURE_BEHIND_CAMERA = 3
FAILURE_REPROJECTION = 4
_DROP_VIEW_CHI2 = float(_chi2.isf(1e-6, 2))
#: Failure reason of each per-point failure code (index = code; ``""`` for an accepted point).
FAILURE_REASONS = (
    "",
    "seen in fewer than 2 views",
    "degenerate ray geometry (parallel rays or point at infinity)",
    "behind a camera",
    "reprojection residual above the gate",
)


@dataclass(frozen=True)
class Triangulation:
    """Triangulated point cloud(s) with per-point covariance.

    Batch axes ``...`` are those of the input observations; ``M`` points, ``n`` views.

    Attributes
    ----------
    X_W : ndarray (..., M, 3)
        Points in the world frame W (= Hill frame H), m.  NaN where ``valid`` is False.
    cov_W : ndarray (..., M, 3, 3)
        First-order covariance of each point in W, m².  NaN where ``valid`` is False.
    valid : ndarray (..., M) bool
        Point accepted (``failure_code == POINT_OK``): the per-point ``ok``.
    failure_code : ndarray (..., M) int8
        Per-point failure code, the reason is ``FAILURE_REASONS[code]``.
    views_used : ndarray (..., M, n) bool
        Views that entered the final estimate (a view can be dropped as an outlier).
    n_views : ndarray (..., M) int
        Number of views used.
    rms_reprojection_px : ndarray (..., M)
        Weighted RMS over the used views of the 2-D reprojection residual, px: the point
        residual W_ρ of 003 eq (7) in the form of flag P003-3.  Small means confident.
    chi2 : ndarray (..., M)
        Sum of squared normalised reprojection residuals (``dof = 2 n_views − 3``).
    n_valid : ndarray (...,) int
        Number of valid points per cloud.
    ok : bool or ndarray (...,) bool
        At least one point was triangulated.
    failure_reason : str or ndarray (...,) str
        ``""`` when ok, else why no point survived.
    """

    X_W: np.ndarray
    cov_W: np.ndarray
    valid: np.ndarray
    failure_code: np.ndarray
    views_used: np.ndarray
    n_views: np.ndarray
    rms_reprojection_px: np.ndarray
    chi2: np.ndarray
    n_valid: np.ndarray
    ok: bool | np.ndarray
    failure_reason: str | np.ndarray

    @property
    def weight(self) -> np.ndarray:
        """Scalar point weight ``1 / (W_ρ + 0.1 px)`` of flag P003-4 (docs/papers.md#p003-4; 0 for invalid points)."""
        return np.where(self.valid, 1.0 / (np.nan_to_num(self.rms_reprojection_px) + 0.1), 0.0)


def _solve(uv: np.ndarray, w: np.ndarray, K: np.ndarray, T: np.ndarray, Kinv: np.ndarray,
           iterations: int) -> tuple[np.ndarray, ...]:
    """Normalised DLT (linear, homogeneous coordinate fixed) + Gauss–Newton for points ``(..., n, 2)``
    with information weights ``w``.

    ``K, T, Kinv`` broadcast against ``uv[..., :, None, None]`` (shape ``(..., n, 3|4, 3|4)``).
    ``w`` is ``(..., n)``: camera weight / σ², 0 for absent views.  Returns the point, its
    information matrix, its inverse and determinant, the residuals ``(..., n, 2)`` and the depths ``(..., n)``.
    """
    # --- DLT on normalised coordinates (003 eq 4–6, flag P003-3 (d)): rows x·P3 − P1, y·P3 − P2
    hom = np.concatenate([uv, np.ones(uv.shape[:-1] + (1,))], -1)
    xn = (Kinv @ hom[..., None])[..., 0]
    x = xn[..., 0] / xn[..., 2]
    y = xn[..., 1] / xn[..., 2]
    P = T[..., :3, :]
    sw = np.sqrt(w * (K[..., 0, 0] * K[..., 1, 1]))[..., None]  # pixel-equivalent row scaling
    A = np.concatenate([(x[..., None] * P[..., 2, :] - P[..., 0, :]) * sw,
                        (y[..., None] * P[..., 2, :] - P[..., 1, :]) * sw], -2)
    col = np.sqrt(np.sum(A * A, axis=-2)) + 1e-300  # column equilibration
    A = A / col[..., None, :]
    AtA = np.swapaxes(A, -1, -2) @ A
    # the DLT rows solved with the (equilibrated) homogeneous coordinate fixed at 1: the 3×3 normal
    # equations S y = −b of AᵀA = [[S, b], [bᵀ, c]] in closed form, a start as good as the smallest
    # eigenvector's for points at finite range (Gauss–Newton converges from either to the same
    # point, to its tolerance) at a fraction of a batched eigh; parallel rays give a singular S
    # (NaN or a far point, flagged degenerate below)
    S_inv, _ = sym3_inv(AtA[..., :3, :3])
    with np.errstate(divide="ignore", invalid="ignore"):
        X = -(S_inv @ AtA[..., :3, 3:4])[..., 0] * (col[..., 3:4] / col[..., :3])
    # --- Gauss–Newton on the reprojection error (pixels), each point until its own step is below
    # 1e-9 (1 + |X|): only the points still moving are iterated (a point's result does not depend
    # on the other points of the batch)
    batch = X.shape[:-1]
    X = np.array(np.broadcast_to(X, batch + (3,)))
    P_px = K @ T[..., :3, :]                                    # camera matrices K [R | t], (..., n, 3, 4)
    shared = P_px.size == 12 * P_px.shape[-3]                   # one camera set for every point
    Pb = P_px.reshape(P_px.shape[-3:]) if shared else np.broadcast_to(P_px, batch + P_px.shape[-3:])
    uvb, wb = np.broadcast_to(uv, batch + uv.shape[-2:]), np.broadcast_to(w, batch + w.shape[-1:])
    act = np.nonzero(np.ones(batch, bool))
    for _ in range(iterations):
        if act[0].size == 0:
            break
        Xa = X[act]
        _, H, g, _ = _reprojection_terms(Xa, Pb if shared else Pb[act], uvb[act], wb[act])
        Hinv, _ = sym3_inv(H)
        dX = (Hinv @ g[..., None])[..., 0]
        Xa = Xa + dX
        X[act] = Xa
        moving = np.any(np.abs(dX) > 1e-9 * (1.0 + np.abs(Xa)), axis=-1)
        act = tuple(a[moving] for a in act)
    r, H, _, depth = _reprojection_terms(X, P_px, uv, w)
    Hinv, det = sym3_inv(H)
    return X, H, Hinv, det, r, depth


def _reprojection_terms(X_W: np.ndarray, P_px: np.ndarray, uv: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, ...]:
    """Gauss–Newton terms of points ``X_W (..., 3)`` seen through camera matrices ``P_px = K [R | t]
    (..., n, 3, 4)`` (K's last row ``[0, 0, 1]``): the residuals ``uv − π(X) (..., n, 2)`` (0 where
    ``w`` is 0), the information ``Σ w Jᵀ J (..., 3, 3)``, the gradient ``Σ w Jᵀ r (..., 3)`` and the
    depths ``(..., n)``, m.  The same quantities as :func:`reconstruction._geometry.project`, in
    elementwise arithmetic (batched 3×3 products are slow on many tiny matrices)."""
    X0, X1, X2 = (X_W[..., None, None, i] for i in range(3))
    p = P_px[..., 0] * X0 + P_px[..., 1] * X1 + P_px[..., 2] * X2 + P_px[..., 3]   # (..., n, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_z = 1.0 / p[..., 2]
    uvp = p[..., :2] * inv_z[..., None]
    # ∂uv/∂X_W = (K[:2] − uv ⊗ K[2]) R / z = (P[:2, :3] − uv ⊗ P[2, :3]) / z
    J = (P_px[..., :2, :3] - uvp[..., :, None] * P_px[..., 2:3, :3]) * inv_z[..., None, None]   # (..., n, 2, 3)
    r = np.where(w[..., None] > 0, uv - uvp, 0.0)
    Jw = J * w[..., None, None]
    rows = J.shape[:-3] + (2 * J.shape[-3], 3)                  # the 2n rows of every view together
    H = np.swapaxes(Jw.reshape(rows), -1, -2) @ J.reshape(rows)
    g = np.einsum("...vka,...vk->...a", Jw, r)
    return r, H, g, p[..., 2]


def _cloud_reason(code: np.ndarray) -> np.ndarray:
    """Per-cloud failure reason from the per-point failure codes ``(..., M)``."""
    batch = code.shape[:-1]
    out = np.full(batch, "", dtype=object)
    flat = code.reshape((int(np.prod(batch, dtype=int)), code.shape[-1]))
    reasons = out.reshape(-1)
    for i, s in enumerate(flat):
        if s.size == 0:
            reasons[i] = "no tracks to triangulate"
        elif not np.any(s == POINT_OK):
            codes, counts = np.unique(s, return_counts=True)
            c = int(codes[np.argmax(counts)])
            reasons[i] = ("all points " + FAILURE_REASONS[c] if counts.max() == s.size
                          else "no point triangulated; mostly " + FAILURE_REASONS[c])
    return out.astype(str)


def triangulate(uv_px: ArrayLike, K: ArrayLike, T_CW: ArrayLike, *, pixel_sigma_px: ArrayLike,
                camera_weights: ArrayLike | None = None,
                gate_probability: float = 0.999, max_rms_reprojection_px: float | None = None,
                drop_worst_view: bool = True, iterations: int = 8) -> Triangulation:
    """Triangulate tracks seen in 2..n calibrated views, with covariance and outlier rejection.

    For each track the normalised DLT (003 eq 4–6 per flag P003-3, docs/papers.md#p003-3) gives a start point that
    Gauss–Newton refines to the minimum of the weighted reprojection error

    .. math:: J(\\rho) = \\sum_k \\frac{W_k}{\\sigma^2} \\lVert \\pi(K_k M_k \\rho) - p_k \\rVert^2 ,

    the maximum-likelihood point under Gaussian pixel noise.  Its covariance is the inverse
    Gauss–Newton information ``(Σ_k W_k J_kᵀ J_k / σ²)⁻¹``.  A point is rejected when a used view
    sees it behind the camera (cheirality), when the rays are degenerate, or when its chi-square
    ``J(ρ̂)`` exceeds the ``gate_probability`` quantile of χ²(2 n_views − 3) (the statistically
    calibrated form of 003 eq 8).  With 3 or more views, a rejected point is retried once without
    its worst view, and kept if it then passes and the dropped view is a clear outlier against the
    others (innovation beyond the 1 − 10⁻⁶ χ²₂ quantile): a mismatch in one view is caught by the
    others, while good points rejected by chance stay rejected (no selection bias in the NEES).

    Parameters
    ----------
    uv_px : array_like (..., M, n, 2)
        Pixel coordinates (OpenCV convention) of M tracks in n views; NaN where a track is
        absent from a view.  Leading axes are batch axes (trials, epochs).
    K : array_like (..., n, 3, 3)
        Intrinsics, px; broadcast against the batch axes of ``uv_px``.
    T_CW : array_like (..., n, 4, 4)
        Camera-from-world poses (world W = Hill frame H), m.
    pixel_sigma_px : float or array_like broadcastable to (..., M, n)
        Standard deviation of each pixel coordinate, px.
    camera_weights : array_like (..., n), optional
        Camera confidence weights W_k of 003 eq (6)/(9).  Only ratios matter: they are
        normalised to mean 1, so view k's effective σ is ``pixel_sigma_px / sqrt(W_k)``.
        Default: all equal (maximum likelihood).
    gate_probability : float
        Chi-square gate on the reprojection residual; ``0.999`` rejects 0.1 % of good points.
    max_rms_reprojection_px : float, optional
        The paper's threshold ε_ρ on W_ρ (003 eq 8; flag P003-3 suggests 2 px), applied in
        addition to the chi-square gate.
    drop_worst_view : bool
        Retry rejected points seen in ≥ 3 views without their largest-residual view.
    iterations : int
        Maximum Gauss–Newton iterations (it stops earlier on convergence).

    Returns
    -------
    Triangulation
    """
    uv = as_float(uv_px, "uv_px")
    if uv.ndim < 3 or uv.shape[-1] != 2:
        raise ValueError(f"uv_px: expected shape (..., n_points, n_views, 2), got {uv.shape}")
    if np.any(np.isinf(uv)):
        raise ValueError("uv_px: contains infinite values (use NaN for absent observations)")
    K = check_intrinsics(K)
    T = check_poses(T_CW)
    batch, (M, n) = uv.shape[:-3], uv.shape[-3:-1]
    if K.shape[-3] != n or T.shape[-3] != n:
        raise ValueError(f"K, T_CW: expected {n} views to match uv_px {uv.shape}, got "
                         f"K {K.shape} and T_CW {T.shape}")
    try:
        batch = np.broadcast_shapes(batch, K.shape[:-3], T.shape[:-3])
    except ValueError:
        raise ValueError(f"K, T_CW: batch shapes {K.shape[:-3]}, {T.shape[:-3]} do not broadcast "
                         f"with uv_px batch {uv.shape[:-3]}") from None
    sigma = check_positive(pixel_sigma_px, "pixel_sigma_px", batch + (M, n))
    if camera_weights is None:
        cw = np.ones(batch + (n,))
    else:
        cw = check_positive(camera_weights, "camera_weights")
        if cw.shape[-1:] != (n,):
            raise ValueError(f"camera_weights: expected shape (..., {n}), got {cw.shape}")
        cw = np.broadcast_to(cw / np.mean(cw, axis=-1, keepdims=True), batch + (n,))
    gate_probability = check_probability(gate_probability, "gate_probability")
    if max_rms_reprojection_px is not None:
        max_rms_reprojection_px = float(check_positive(max_rms_reprojection_px,
                                                       "max_rms_reprojection_px"))
    if int(iterations) < 1:
        raise ValueError(f"iterations: must be >= 1, got {iterations!r}")

    uv = np.broadcast_to(uv, batch + (M, n, 2))
    present = np.all(np.isfinite(uv), axis=-1)
    uv0 = np.where(present[..., None], uv, 0.0)
    K_b = np.broadcast_to(K, batch + (n, 3, 3))[..., None, :, :, :]
    T_b = np.broadcast_to(T, batch + (n, 4, 4))[..., None, :, :, :]
    Kinv_b = np.linalg.inv(K_b)

    def run(use: np.ndarray, uv_in: np.ndarray, Kx: np.ndarray, Tx: np.ndarray, Kix: np.ndarray,
            cwx: np.ndarray, sx: np.ndarray) -> tuple[np.ndarray, ...]:
        w = np.where(use, cwx / sx**2, 0.0)
        X, H, Hinv, det, r, depth = _solve(uv_in, w, Kx, Tx, Kix, int(iterations))
        e2 = np.sum(r * r, axis=-1)
        chi2 = np.sum(w * e2, axis=-1)
        cws = np.where(use, cwx, 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            rms = np.sqrt(np.sum(cws * e2, axis=-1) / np.sum(cws, axis=-1))
        nv = np.sum(use, axis=-1)
        code = np.zeros(nv.shape, dtype=np.int8)
        tr = np.trace(H, axis1=-2, axis2=-1)
        degenerate = ~np.isfinite(X).all(-1) | ~(det > 1e-14 * (tr / 3.0) ** 3)
        behind = np.any(use & ~(depth > 0), axis=-1)
        dof = np.maximum(2 * nv - 3, 1)
        dofs, at = np.unique(dof, return_inverse=True)  # a few values: each quantile once (cached)
        thresh = np.array([chi2_quantile(gate_probability, int(d)) for d in dofs])[at].reshape(dof.shape)
        bad_fit = chi2 > thresh
        if max_rms_reprojection_px is not None:
            bad_fit |= rms > max_rms_reprojection_px
        code[bad_fit] = FAILURE_REPROJECTION
        code[behind] = FAILURE_BEHIND_CAMERA
        code[degenerate] = FAILURE_DEGENERATE
        code[nv < 2] = FAILURE_TOO_FEW_VIEWS
        worst = np.argmax(w * e2, axis=-1)
        return X, Hinv, code, rms, chi2, nv, worst

    cw_p = np.broadcast_to(cw[..., None, :], batch + (M, n))
    X, cov, code, rms, chi2, nv, worst = run(present, uv0, K_b, T_b, Kinv_b, cw_p, sigma)
    use = present.copy()

    if drop_worst_view and n >= 3:
        retry = (code == FAILURE_REPROJECTION) & (nv >= 3)
        if np.any(retry):
            idx = np.nonzero(retry)
            bidx = idx[:-1]
            use_r = use[idx].copy()
            use_r[np.arange(use_r.shape[0]), worst[idx]] = False
            K_r = np.broadcast_to(K_b, batch + (1, n, 3, 3))[bidx + (0,)]
            T_r = np.broadcast_to(T_b, batch + (1, n, 4, 4))[bidx + (0,)]
            Ki_r = np.broadcast_to(Kinv_b, batch + (1, n, 3, 3))[bidx + (0,)]
            X2, cov2, code2, rms2, chi22, nv2, _ = run(use_r, uv0[idx], K_r, T_r, Ki_r,
                                                     cw_p[idx], sigma[idx])
            # accept the drop only if the dropped view is a clear outlier against the others:
            # innovation χ²₂ above the 1 − 10⁻⁶ quantile (a ~5σ test).  Without this test, good
            # points that failed the gate by chance would come back with a selection-biased
            # error (their NEES averages ~8 instead of 3).
            ar = np.arange(use_r.shape[0])
            d = worst[idx]
            Kd = np.broadcast_to(K_r, (ar.size, n, 3, 3))[ar, d]
            Td = np.broadcast_to(T_r, (ar.size, n, 4, 4))[ar, d]
            uvp_d, _, Jd = project(X2, Kd, Td)
            r_d = uv0[idx][ar, d] - uvp_d
            S = (Jd @ cov2 @ np.swapaxes(Jd, -1, -2)
                 + (sigma[idx][ar, d] ** 2 / cw_p[idx][ar, d])[:, None, None] * np.eye(2))
            det = S[:, 0, 0] * S[:, 1, 1] - S[:, 0, 1] * S[:, 1, 0]
            d2 = (S[:, 1, 1] * r_d[:, 0] ** 2 - 2 * S[:, 0, 1] * r_d[:, 0] * r_d[:, 1]
                  + S[:, 0, 0] * r_d[:, 1] ** 2) / det
            fixed = (code2 == POINT_OK) & (d2 > _DROP_VIEW_CHI2)
            fidx = tuple(a[fixed] for a in idx)
            X[fidx], cov[fidx], code[fidx] = X2[fixed], cov2[fixed], code2[fixed]
            rms[fidx], chi2[fidx], nv[fidx] = rms2[fixed], chi22[fixed], nv2[fixed]
            use[fidx] = use_r[fixed]

    valid = code == POINT_OK
    X = np.where(valid[..., None], X, np.nan)
    cov = np.where(valid[..., None, None], cov, np.nan)
    rms = np.where(nv >= 2, rms, np.nan)
    n_valid = np.sum(valid, axis=-1)
    reason = _cloud_reason(code)
    return Triangulation(
        X_W=X, cov_W=cov, valid=valid, failure_code=code, views_used=use, n_views=nv,
        rms_reprojection_px=rms, chi2=chi2, n_valid=n_valid,
        ok=scalar_or_array(np.asarray(n_valid > 0)), failure_reason=scalar_or_array(reason),
    )


def triangulate_from_observation(obs: Observation, *, pixel_sigma_px: float | None = None,
                                 **options: Any) -> Triangulation:
    """:func:`triangulate` on a :class:`vision.observation.Observation`.

    Uses ``obs.uv_px``, ``obs.K``, ``obs.T_CW`` and the observation's σ per track and view
    (``obs.sigma_uv_px``: its ``track_sigma_px`` where known, else ``obs.pixel_sigma_px``); pass
    ``pixel_sigma_px`` to override it (e.g. for a noise-free observation whose σ is 0).  ``options``
    are passed on.  An observation that is not ``ok`` gives a failed cloud whose ``failure_reason``
    names the observation's ``failure_reason``.
    """
    if pixel_sigma_px is None:
        if not obs.pixel_sigma_px > 0 and obs.track_sigma_px is None:
            raise ValueError(f"pixel_sigma_px: the observation's σ is {obs.pixel_sigma_px!r}; pass the σ to "
                             "assume (> 0) for a noise-free observation")
        sigma = obs.sigma_uv_px if obs.track_sigma_px is not None else obs.pixel_sigma_px
    else:
        sigma = pixel_sigma_px
        if not np.all(np.asarray(sigma) > 0):
            raise ValueError(f"pixel_sigma_px: must be > 0, got {sigma!r}")
    tri = triangulate(obs.uv_px, obs.K, obs.T_CW, pixel_sigma_px=sigma, **options)
    if not obs.ok:
        return Triangulation(
            X_W=np.full_like(tri.X_W, np.nan), cov_W=np.full_like(tri.cov_W, np.nan),
            valid=np.zeros_like(tri.valid), failure_code=tri.failure_code, views_used=tri.views_used,
            n_views=tri.n_views, rms_reprojection_px=tri.rms_reprojection_px, chi2=tri.chi2,
            n_valid=np.zeros_like(tri.n_valid), ok=False,
            failure_reason=f"observation failed: {obs.failure_reason}",
        )
    return tri
