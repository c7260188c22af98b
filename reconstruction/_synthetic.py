"""Private synthetic scenes for the reconstruction tests, benchmarks and the accuracy study.

A small stand-in for ``formation.geometry.symmetric_views`` (the camera ring of 003 §3.1) and for
the geometric observation mode of ``vision``, which other packages own: cameras on a cone around
the target at a given distance and pairwise optical-axis angle, an FY-1-like point set (1.4 m
bus, two 1.4 m × 3 m wings), pinhole projection with Gaussian pixel noise.  No occlusion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation
from scipy.stats import chi2 as _chi2

from attitude.batch import matrices_from_rotvecs, rotvecs_from_matrices
from reconstruction._geometry import project

__all__: list[str] = []


def ring_cameras(n_views: int, *, distance_m: float, axis_angle_deg: float,
                 image_px: int = 1024, fov_deg: float = 20.0) -> tuple[np.ndarray, np.ndarray]:
    """Cameras on a cone about +z of W, all aimed at the origin, adjacent axes ``axis_angle_deg``
    apart (``cos γ = cos²φ + sin²φ cos(2π/n)``, which is ``cos γ = 1 − (3/2) sin²φ`` for n = 3).

    Returns ``K (n, 3, 3)`` and ``T_CW (n, 4, 4)``.
    """
    gamma = np.radians(axis_angle_deg)
    if n_views == 1:
        phi = 0.0
    else:
        phi = np.arcsin(np.sqrt((1 - np.cos(gamma)) / (1 - np.cos(2 * np.pi / n_views))))
    f = 0.5 * image_px / np.tan(np.radians(fov_deg) / 2)
    K = np.array([[f, 0, image_px / 2], [0, f, image_px / 2], [0, 0, 1.0]])
    Ks, Ts = [], []
    for k in range(n_views):
        a = 2 * np.pi * k / n_views
        c = distance_m * np.array([np.sin(phi) * np.cos(a), np.sin(phi) * np.sin(a), np.cos(phi)])
        z = -c / np.linalg.norm(c)
        x = np.array([-np.sin(a), np.cos(a), 0.0])
        y = np.cross(z, x)
        R_WC = np.stack([x, y, z], axis=1)
        T = np.eye(4)
        T[:3, :3] = R_WC.T
        T[:3, 3] = -R_WC.T @ c
        Ks.append(K)
        Ts.append(T)
    return np.array(Ks), np.array(Ts)


def fy1_points(n_points: int, rng: np.random.Generator | int | None, *,
               batch: tuple[int, ...] = ()) -> np.ndarray:
    """Points on an FY-1-like body in T: half on a 1.4 m cube bus, half on two wings
    (x ∈ ±0.7 m, |y| ∈ [0.8, 3.8] m, z = 0).  Shape ``batch + (n_points, 3)``."""
    rng = np.random.default_rng(rng)
    shape = batch + (n_points,)
    on_bus = rng.random(shape) < 0.5
    face = rng.integers(0, 6, shape)
    uv = rng.uniform(-0.7, 0.7, shape + (2,))
    axis = face // 2
    sign = np.where(face % 2 == 0, 0.7, -0.7)
    bus = np.zeros(shape + (3,))
    for ax in range(3):
        o1, o2 = [o for o in range(3) if o != ax]
        m = axis == ax
        bus[m, ax] = sign[m]
        bus[m, o1] = uv[m, 0]
        bus[m, o2] = uv[m, 1]
    wing = np.stack([rng.uniform(-0.7, 0.7, shape),
                     rng.choice([-1.0, 1.0], shape) * rng.uniform(0.8, 3.8, shape),
                     np.zeros(shape)], -1)
    return np.where(on_bus[..., None], bus, wing)


def observe(X_W: np.ndarray, K: np.ndarray, T_CW: np.ndarray, sigma_px: float,
            rng: np.random.Generator | int | None) -> np.ndarray:
    """Noisy pixel observations ``(..., M, n, 2)`` of points ``(..., M, 3)`` (no occlusion)."""
    rng = np.random.default_rng(rng)
    uv, _, _ = project(X_W[..., :, None, :], K[..., None, :, :, :], T_CW[..., None, :, :, :])
    return uv + sigma_px * rng.standard_normal(uv.shape)


@dataclass(frozen=True)
class StudyResult:
    """Figures of the Monte-Carlo accuracy study (angles in degrees)."""

    n_views: int
    n_trials: int
    n_points: int
    anees: float
    anees_band: tuple[float, float]
    ml_rms_deg: float
    crlb_rms_deg: float
    ml_nees6: float
    ml_nees6_band: tuple[float, float]
    scalar_rms_deg: float
    robust_rms_deg: float
    robust_outlier_recall: float
    robust_inlier_kept: float
    replaced_rms_deg: float
    replaced_crlb_rms_deg: float

    @property
    def ml_over_crlb(self) -> float:
        return self.ml_rms_deg / self.crlb_rms_deg

    @property
    def scalar_over_ml(self) -> float:
        return self.scalar_rms_deg / self.ml_rms_deg

    @property
    def robust_over_clean(self) -> float:
        return self.robust_rms_deg / self.ml_rms_deg


def accuracy_study(*, n_views: int, n_trials: int, n_points: int = 200, distance_m: float = 50.0,
                   axis_angle_deg: float = 10.0, image_px: int = 1024, fov_deg: float = 20.0,
                   sigma_px: float = 0.5, increment_deg: float = 0.5 * np.sqrt(3),
                   outlier_fraction: float = 0.3,
                   rng: np.random.Generator | int | None = None, band: float = 0.95) -> StudyResult:
    """The done-when study of issue 6: triangulation NEES, ML vs CRLB vs scalar-weighted fit,
    robust fit with false matches (added to the true ones, and replacing some of them)."""
    from reconstruction.accuracy import attitude_increment_crlb
    from reconstruction.registration import fit_rigid, fit_rigid_ml
    from reconstruction.triangulation import triangulate

    rng = np.random.default_rng(rng)
    K, T = ring_cameras(n_views, distance_m=distance_m, axis_angle_deg=axis_angle_deg,
                        image_px=image_px, fov_deg=fov_deg)
    X_T = fy1_points(n_points, rng, batch=(n_trials,))
    R0 = Rotation.random(n_trials, random_state=rng).as_matrix()
    axis = rng.standard_normal((n_trials, 3))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    dR = matrices_from_rotvecs(np.radians(increment_deg) * axis)
    X0 = X_T @ np.swapaxes(R0, -1, -2)
    X1 = X0 @ np.swapaxes(dR, -1, -2)
    tri0 = triangulate(observe(X0, K, T, sigma_px, rng), K, T, pixel_sigma_px=sigma_px)
    tri1 = triangulate(observe(X1, K, T, sigma_px, rng), K, T, pixel_sigma_px=sigma_px)

    # --- triangulation consistency
    nees = []
    for tri, X in ((tri0, X0), (tri1, X1)):
        e = tri.X_W - X
        Winv = np.linalg.inv(np.where(tri.valid[..., None, None], tri.cov_W, np.eye(3)))
        nees.append(np.einsum("...i,...ij,...j->...", e, Winv, e)[tri.valid])
    nees = np.concatenate(nees)
    m = nees.size
    lo, hi = (_chi2.ppf((1 - band) / 2, 3 * m) / m, _chi2.ppf(1 - (1 - band) / 2, 3 * m) / m)

    def err_rms(R_hat: np.ndarray) -> tuple[float, np.ndarray]:
        e = rotvecs_from_matrices(dR @ np.swapaxes(R_hat, -1, -2))
        return float(np.degrees(np.sqrt(np.nanmean(np.sum(e * e, -1))))), e

    # --- ML with covariances, and its 6-dof consistency
    ml = fit_rigid_ml(tri0.X_W, tri1.X_W, tri0.cov_W, tri1.cov_W, robust=False)
    ml_rms, e_ml = err_rms(ml.R)
    dt = -(ml.t)  # true translation is zero: δt = t_true − t̂
    d6 = np.concatenate([e_ml, dt], -1)
    nees6 = np.einsum("...i,...ij,...j->...", d6, np.linalg.inv(ml.cov), d6)
    lo6, hi6 = (_chi2.ppf((1 - band) / 2, 6 * n_trials) / n_trials,
                _chi2.ppf(1 - (1 - band) / 2, 6 * n_trials) / n_trials)
    crlb = attitude_increment_crlb(X0, K, T, pixel_sigma_px=sigma_px, R_delta=dR)
    crlb_rms = float(np.degrees(np.sqrt(np.mean(crlb.rms_angle_rad**2))))

    # --- the paper's scalar-weighted fit (003 eq 12–13 with the weights of flag P003-4 (docs/papers.md#p003-4))
    w = 1.0 / (0.5 * (tri0.rms_reprojection_px + tri1.rms_reprojection_px) + 0.1)
    sc = fit_rigid(tri0.X_W, tri1.X_W, np.where(np.isfinite(w), w, 0.0))
    sc_rms, _ = err_rms(sc.R)

    # --- false matches added: 30 % of all correspondences are wrong track pairs
    n_out = int(round(outlier_fraction / (1 - outlier_fraction) * n_points))
    i = rng.integers(0, n_points, (n_trials, n_out))
    j = (i + rng.integers(1, n_points, (n_trials, n_out))) % n_points
    take = np.take_along_axis
    P = np.concatenate([tri0.X_W, take(tri0.X_W, i[..., None], 1)], 1)
    Q = np.concatenate([tri1.X_W, take(tri1.X_W, j[..., None], 1)], 1)
    cP = np.concatenate([tri0.cov_W, take(tri0.cov_W, i[..., None, None], 1)], 1)
    cQ = np.concatenate([tri1.cov_W, take(tri1.cov_W, j[..., None, None], 1)], 1)
    rb = fit_rigid_ml(P, Q, cP, cQ, robust=True, rng=rng)
    rb_rms, _ = err_rms(rb.R)
    good = np.isfinite(tri0.X_W[..., 0]) & np.isfinite(tri1.X_W[..., 0])
    recall = float(np.mean(~rb.inliers[:, n_points:]))
    kept = float(np.sum(rb.inliers[:, :n_points] & good) / np.sum(good))

    # --- false matches replacing 30 % of the true ones (a derangement of a random subset)
    n_rep = int(round(outlier_fraction * n_points))
    perm = np.argsort(rng.random((n_trials, n_points)), -1)[:, :n_rep]
    Qr, cQr = tri1.X_W.copy(), tri1.cov_W.copy()
    rolled = np.roll(perm, 1, axis=-1)
    ar = np.arange(n_trials)[:, None]
    Qr[ar, perm] = tri1.X_W[ar, rolled]
    cQr[ar, perm] = tri1.cov_W[ar, rolled]
    rr = fit_rigid_ml(tri0.X_W, Qr, tri0.cov_W, cQr, robust=True, rng=rng)
    rr_rms, _ = err_rms(rr.R)
    vis = np.ones((n_trials, n_points, n_views), bool)
    vis[ar, perm] = False
    crlb_r = attitude_increment_crlb(X0, K, T, pixel_sigma_px=sigma_px, R_delta=dR, visible=vis,
                                     visible_next=vis)  # a replaced match is lost at both epochs
    return StudyResult(
        n_views=n_views, n_trials=n_trials, n_points=n_points,
        anees=float(np.mean(nees)), anees_band=(float(lo), float(hi)),
        ml_rms_deg=ml_rms, crlb_rms_deg=crlb_rms,
        ml_nees6=float(np.mean(nees6)), ml_nees6_band=(float(lo6), float(hi6)),
        scalar_rms_deg=sc_rms, robust_rms_deg=rb_rms, robust_outlier_recall=recall,
        robust_inlier_kept=kept, replaced_rms_deg=rr_rms,
        replaced_crlb_rms_deg=float(np.degrees(np.sqrt(np.mean(crlb_r.rms_angle_rad**2)))),
    )
