"""Benchmarks of ``reconstruction``: triangulation and registration against pycolmap and OpenCV,
and the accuracy study of issue 6 (NEES, ML registration vs the Cramér–Rao bound, the paper's
scalar-weighted fit, robustness to false matches) for 3 and 2 views.

Geometry (003 §3, issue 6): cameras 50 m from the target, 10° between adjacent optical axes,
1024 × 1024 px over 20°, σ = 0.5 px, 200 points on an FY-1-like body, attitude increment
[0.5°, 0.5°, 0.5°] in size (0.866°) about a random axis, random attitude per trial.

``coobs bench --only reconstruction`` (1000 trials, 10⁴ registrations; add ``--quick`` for 100
trials, 10³ registrations).
"""

from __future__ import annotations

import numpy as np

from experiments.bench import BenchRow, best_time, throughput_row

SIGMA = 0.5


def _triangulation_rows(quick: bool) -> list[BenchRow]:
    import cv2
    import pycolmap

    from reconstruction._synthetic import fy1_points, observe, ring_cameras
    from reconstruction.triangulation import triangulate

    rows = []
    rng = np.random.default_rng(0)
    n_pts = 2_000 if quick else 20_000
    n_peer = 500 if quick else 2_000
    for n_views in (3, 2):
        K, T = ring_cameras(n_views, distance_m=50.0, axis_angle_deg=10.0)
        X = fy1_points(n_pts, rng)
        uv = observe(X, K, T, SIGMA, rng)
        t_ours = best_time(lambda uv=uv, K=K, T=T: triangulate(uv, K, T, pixel_sigma_px=SIGMA))
        tri = triangulate(uv, K, T, pixel_sigma_px=SIGMA)
        err_ours = np.sqrt(np.nanmean(np.sum((tri.X_W - X) ** 2, -1)))

        cam = pycolmap.Camera(model="PINHOLE", width=1024, height=1024,
                              params=[K[0, 0, 0], K[0, 1, 1], K[0, 0, 2], K[0, 1, 2]])
        poses = [pycolmap.Rigid3d(T[k, :3, :]) for k in range(n_views)]
        opts = pycolmap.EstimateTriangulationOptions()
        opts.ransac.max_error = 4.0 * SIGMA / K[0, 0, 0]  # angular, rad
        opts.ransac.random_seed = 0
        X_cm = np.full((n_peer, 3), np.nan)

        def colmap_loop(uv=uv, poses=poses, cam=cam, opts=opts, X_cm=X_cm, n_views=n_views):
            for m in range(n_peer):
                r = pycolmap.estimate_triangulation(uv[m], poses, [cam] * n_views, opts)
                if r is not None:
                    X_cm[m] = r["xyz"]

        t_cm = best_time(colmap_loop, repeat=1) * n_pts / n_peer
        err_cm = np.sqrt(np.nanmean(np.sum((X_cm - X[:n_peer]) ** 2, -1)))
        err_ours_sub = np.sqrt(np.nanmean(np.sum((tri.X_W[:n_peer] - X[:n_peer]) ** 2, -1)))
        rows.append(throughput_row(
            f"triangulation, {n_views} views, {n_pts} points (batched)", t_ours, t_cm, n_pts,
            "points/s", "pycolmap estimate_triangulation loop",
            f"pycolmap timed on {n_peer} points and scaled"))
        rows.append(BenchRow(
            f"triangulation RMS 3-D error, {n_views} views", err_ours_sub * 1e3, "mm",
            "pycolmap estimate_triangulation", err_cm * 1e3, err_cm / err_ours_sub,
            f"same {n_peer} points; σ = {SIGMA} px at 50 m"))
        if n_views == 2:
            P1, P2 = K[0] @ T[0, :3], K[1] @ T[1, :3]
            a, b = uv[:, 0].T.copy(), uv[:, 1].T.copy()
            t_cv = best_time(lambda P1=P1, P2=P2, a=a, b=b: cv2.triangulatePoints(P1, P2, a, b))
            Xh = cv2.triangulatePoints(P1, P2, a, b)
            err_cv = np.sqrt(np.mean(np.sum(((Xh[:3] / Xh[3]).T - X) ** 2, -1)))
            rows.append(throughput_row(
                f"triangulation, 2 views, {n_pts} points", t_ours, t_cv, n_pts, "points/s",
                "OpenCV triangulatePoints (linear DLT, no refinement or covariance)",
                "ours includes Gauss-Newton, covariance and gating"))
            rows.append(BenchRow(
                "triangulation RMS 3-D error, 2 views", err_ours * 1e3, "mm",
                "OpenCV triangulatePoints", err_cv * 1e3, err_cv / err_ours,
                f"{n_pts} points"))
    return rows


def _registration_rows(quick: bool) -> list[BenchRow]:
    import pycolmap
    from scipy.spatial.transform import Rotation

    from attitude.batch import rotvecs_from_matrices
    from reconstruction.registration import fit_rigid

    B = 1_000 if quick else 10_000
    rng = np.random.default_rng(1)
    R = Rotation.random(B, random_state=rng).as_matrix()
    t = rng.uniform(-5, 5, (B, 3))
    P = rng.uniform(-2, 2, (B, 200, 3))
    Q = P @ np.swapaxes(R, -1, -2) + t[:, None, :] + 0.01 * rng.standard_normal(P.shape)
    R_cm = np.empty((B, 3, 3))

    def loop():
        for b in range(B):  # same contiguous (200, 3) rows; the result as a NumPy R, like ours
            R_cm[b] = pycolmap.estimate_rigid3d(P[b], Q[b]).rotation.matrix()

    Pf, Qf = P.reshape(B, -1), Q.reshape(B, -1)
    fit_rigid(P[:2], Q[:2])  # compiles (or loads from cache) the Numba kernel outside the timing
    # the machine is shared: ours and the peer are timed alternately, best of the same repeats
    t_ours = t_cm = t_read = float("inf")
    for _ in range(5):
        t_ours = min(t_ours, best_time(lambda: fit_rigid(P, Q), repeat=1))
        t_cm = min(t_cm, best_time(loop, repeat=1))
        t_read = min(t_read, best_time(lambda: (np.vecdot(Pf, Pf), np.vecdot(Qf, Qf)), repeat=1))
    fit = fit_rigid(P, Q)
    diff = np.max(np.linalg.norm(rotvecs_from_matrices(fit.R @ np.swapaxes(R_cm, -1, -2)), axis=-1))

    def rms(Rh):
        e = rotvecs_from_matrices(R @ np.swapaxes(Rh, -1, -2))
        return np.degrees(np.sqrt(np.mean(np.sum(e * e, -1))))

    return [throughput_row(
        f"rigid registration, {B} problems x 200 points (batched)", t_ours, t_cm, B,
        "problems/s", "pycolmap estimate_rigid3d loop",
        f"target >= 10x; ours: compiled Numba kernel, one thread, warmed up; one NumPy read of "
        f"the {P.nbytes * 2 / 1e6:.0f} MB input alone takes "
        f"{t_read * 1e3:.1f} ms ({t_cm / t_read:.0f}x the peer); max |R_ours R_colmap^T| = "
        f"{diff:.1e} rad; rotation RMS error {rms(fit.R):.5f} deg (ours) vs {rms(R_cm):.5f} deg "
        "(pycolmap)")]


def _study_rows(quick: bool) -> list[BenchRow]:
    from reconstruction._synthetic import accuracy_study

    n_trials = 100 if quick else 1000
    rows = []
    for n_views in (3, 2):
        s = accuracy_study(n_views=n_views, n_trials=n_trials, rng=2026 + n_views)
        tag = f"{n_views} views, {n_trials} trials"
        rows += [
            BenchRow(f"triangulation ANEES, {tag}", s.anees, "", "chi2 95% band upper",
                     s.anees_band[1], float("nan"),
                     f"band [{s.anees_band[0]:.4f}, {s.anees_band[1]:.4f}], expected 3"),
            BenchRow(f"ML registration attitude-increment RMS, {tag}", s.ml_rms_deg, "deg",
                     "Cramer-Rao bound", s.crlb_rms_deg, s.crlb_rms_deg / s.ml_rms_deg,
                     f"target: within 10% of the bound; 6-dof NEES {s.ml_nees6:.2f} "
                     f"(band {s.ml_nees6_band[0]:.2f}-{s.ml_nees6_band[1]:.2f})"),
            BenchRow(f"ML vs scalar-weighted fit (003 eq 12), {tag}", s.ml_rms_deg, "deg",
                     "scalar-weighted Kabsch, w = 1/(W_rho + 0.1 px)", s.scalar_rms_deg,
                     s.scalar_rms_deg / s.ml_rms_deg, "ratio = how many times worse eq 12 is"),
            BenchRow(f"robust ML, 30% false matches added, {tag}", s.robust_rms_deg, "deg",
                     "same fit without false matches", s.ml_rms_deg,
                     s.ml_rms_deg / s.robust_rms_deg,
                     f"target: within 20%; false matches rejected "
                     f"{100 * s.robust_outlier_recall:.1f}%, true kept "
                     f"{100 * s.robust_inlier_kept:.1f}%"),
            BenchRow(f"robust ML, 30% of matches replaced by false ones, {tag}",
                     s.replaced_rms_deg, "deg", "Cramer-Rao bound of the 70% true matches",
                     s.replaced_crlb_rms_deg, s.replaced_crlb_rms_deg / s.replaced_rms_deg,
                     f"clean fit {s.ml_rms_deg:.4f} deg; the information lost bounds the "
                     f"ratio to sqrt(1/0.7) = 1.195"),
        ]
    return rows


def run(*, quick: bool) -> list[BenchRow]:
    """Triangulation vs pycolmap/OpenCV, batched registration vs pycolmap, accuracy study."""
    return _triangulation_rows(quick) + _registration_rows(quick) + _study_rows(quick)
