"""Registration when the correspondences are unknown: Open3D ICP and FPFH features + RANSAC.

Open3D is imported inside the functions, so that importing this module stays light.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from reconstruction._geometry import as_float, check_points, check_positive, check_probability
from reconstruction.registration.result import KABSCH_REASONS, RigidRegistration

__all__ = ["register_fpfh_ransac", "register_icp"]


def _o3d_cloud(X):
    import open3d as o3d

    pc = o3d.geometry.PointCloud()
    pc.points = o3d.utility.Vector3dVector(np.ascontiguousarray(X, dtype=float))
    return pc


def _single_cloud(X, name):
    X = check_points(X, name)
    if X.ndim != 2:
        raise ValueError(f"{name}: expected one cloud (N, 3), got {X.shape}")
    return X[np.all(np.isfinite(X), -1)]


def _o3d_result(P, Q, T, fitness_inliers, method, reason=""):
    ok = reason == ""
    R = T[:3, :3] if ok else np.full((3, 3), np.nan)
    t = T[:3, 3] if ok else np.full(3, np.nan)
    inl = fitness_inliers & ok
    rms = np.nan
    if ok and np.any(inl):
        from scipy.spatial import cKDTree

        d, _ = cKDTree(Q).query(P[inl] @ R.T + t)
        rms = float(np.sqrt(np.mean(d * d)))
    return RigidRegistration(
        R=R, t=t, cov=np.full((6, 6), np.nan), inliers=inl, n_inliers=np.asarray(int(inl.sum())),
        rms_m=np.asarray(rms), chi2=np.asarray(np.nan), dof=np.asarray(3 * int(inl.sum()) - 6),
        ok=ok, failure_reason=reason, method=method,
    )


def register_icp(P: ArrayLike, Q: ArrayLike, *, max_correspondence_m: float,
                 R0: ArrayLike | None = None, t0: ArrayLike | None = None,
                 point_to_plane: bool = False, normal_radius_m: float | None = None,
                 max_iterations: int = 100) -> RigidRegistration:
    """Open3D ICP for ``Q ≈ R P + t`` when correspondences are unknown (clouds of any sizes).

    Parameters
    ----------
    P : array_like (N, 3)
        Source cloud, m (NaN rows dropped).
    Q : array_like (M, 3)
        Target cloud, m.
    max_correspondence_m : float
        Open3D's ``max_correspondence_distance``, m.
    R0, t0 : optional
        Initial motion (default identity): ICP converges only from close to the answer; use
        :func:`register_fpfh_ransac` for a global start.
    point_to_plane : bool
        Point-to-plane ICP (normals estimated on Q within ``normal_radius_m``).
    max_iterations : int
        ICP iterations.

    Returns
    -------
    RigidRegistration
        ``method="icp"``; ``inliers`` marks the P points with a correspondence at the end.
    """
    import open3d as o3d

    P = _single_cloud(P, "P")
    Q = _single_cloud(Q, "Q")
    dmax = float(check_positive(max_correspondence_m, "max_correspondence_m"))
    T0 = np.eye(4)
    if R0 is not None:
        T0[:3, :3] = as_float(R0, "R0")
    if t0 is not None:
        T0[:3, 3] = as_float(t0, "t0")
    if len(P) < 3 or len(Q) < 3:
        return _o3d_result(P, Q, T0, np.zeros(len(P), bool), "icp", KABSCH_REASONS[1])
    src, tgt = _o3d_cloud(P), _o3d_cloud(Q)
    reg = o3d.pipelines.registration
    if point_to_plane:
        rad = float(check_positive(normal_radius_m, "normal_radius_m")) if normal_radius_m \
            else 3.0 * dmax
        tgt.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=rad, max_nn=30))
        est = reg.TransformationEstimationPointToPlane()
    else:
        est = reg.TransformationEstimationPointToPoint()
    res = reg.registration_icp(src, tgt, dmax, T0, est,
                               reg.ICPConvergenceCriteria(max_iteration=int(max_iterations)))
    corr = np.asarray(res.correspondence_set)
    inl = np.zeros(len(P), bool)
    if corr.size:
        inl[corr[:, 0]] = True
    reason = "" if inl.sum() >= 3 else "fewer than 3 correspondences within max_correspondence_m"
    return _o3d_result(P, Q, np.asarray(res.transformation), inl, "icp", reason)


def register_fpfh_ransac(P: ArrayLike, Q: ArrayLike, *, voxel_size_m: float, max_iterations: int = 100000,
                         confidence: float = 0.999, refine_with_icp: bool = True,
                         rng: np.random.Generator | int | None = None) -> RigidRegistration:
    """Global registration with Open3D FPFH features and RANSAC (correspondences unknown).

    Normals and FPFH descriptors are computed at radii of 2 and 5 ``voxel_size_m`` after a voxel
    down-sampling; RANSAC on feature matches (mutual filter, edge-length and distance checkers)
    gives the start, refined by point-to-point ICP on the full clouds.  Open3D's RANSAC draws from
    its own generator; it is seeded from ``rng`` (``open3d.utility.random.seed``) so that a given
    ``rng`` gives the same result.

    Parameters
    ----------
    P, Q : array_like (N, 3), (M, 3)
        Source and target clouds, m.
    voxel_size_m : float
        Down-sampling voxel, m; the scale of the features and of the inlier distance (1.5 voxel).
    max_iterations, confidence :
        RANSAC budget.
    refine_with_icp : bool
        Refine the RANSAC motion with ICP (distance 1.5 voxel).
    rng : numpy.random.Generator or int or None

    Returns
    -------
    RigidRegistration
        ``method="fpfh_ransac"``.
    """
    import open3d as o3d

    P = _single_cloud(P, "P")
    Q = _single_cloud(Q, "Q")
    v = float(check_positive(voxel_size_m, "voxel_size_m"))
    confidence = check_probability(confidence, "confidence")
    rng = np.random.default_rng(rng)
    if len(P) < 3 or len(Q) < 3:
        return _o3d_result(P, Q, np.eye(4), np.zeros(len(P), bool), "fpfh_ransac",
                           KABSCH_REASONS[1])
    reg = o3d.pipelines.registration
    o3d.utility.random.seed(int(rng.integers(0, 2**31 - 1)))

    def prep(X: np.ndarray) -> tuple[o3d.geometry.PointCloud, reg.Feature]:
        pc = _o3d_cloud(X).voxel_down_sample(v)
        pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2 * v, max_nn=30))
        f = reg.compute_fpfh_feature(pc, o3d.geometry.KDTreeSearchParamHybrid(radius=5 * v,
                                                                             max_nn=100))
        return pc, f

    src, fs = prep(P)
    tgt, ft = prep(Q)
    dist = 1.5 * v
    res = reg.registration_ransac_based_on_feature_matching(
        src, tgt, fs, ft, True, dist, reg.TransformationEstimationPointToPoint(False), 3,
        [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9),
         reg.CorrespondenceCheckerBasedOnDistance(dist)],
        reg.RANSACConvergenceCriteria(int(max_iterations), confidence))
    T = np.asarray(res.transformation)
    if not np.asarray(res.correspondence_set).size:
        return _o3d_result(P, Q, T, np.zeros(len(P), bool), "fpfh_ransac",
                           "no FPFH/RANSAC consensus")
    if refine_with_icp:
        icp = register_icp(P, Q, max_correspondence_m=dist, R0=T[:3, :3], t0=T[:3, 3])
        if icp.ok:
            return RigidRegistration(**{**icp.__dict__, "method": "fpfh_ransac"})
    from scipy.spatial import cKDTree

    d, _ = cKDTree(Q).query(P @ T[:3, :3].T + T[:3, 3])
    return _o3d_result(P, Q, T, d < dist, "fpfh_ransac")
