"""The geometric observation mode: fixed surface features, visibility, projection, noise, outliers.

The fast counterpart of the rendered mode (:func:`vision.rendered.observe`), for large sweeps. It
returns the same :class:`~vision.observation.Observation`, so reconstruction cannot tell them apart.

Model (per epoch, per camera, per surface feature):

1. **Surface features** (:func:`surface_features`): points sampled uniformly by area on the target
   mesh, fixed for the target (seeded from ``target.seed``), each with its triangle normal, a
   physical scale ``s`` (log-uniform in ``scale_range_m``) and a random unit descriptor.
2. **Visibility**: a feature is seen by a camera when it projects inside the image, its imaged scale
   ``s·f/z`` is at least ``min_feature_px`` (so fewer features survive at long range, as with a real
   detector), its surface faces the camera within ``max_view_angle_deg``, the Sun is on the camera's
   side of the surface and within ``max_sun_incidence_deg`` of its normal, no part of the target
   occludes it from the camera, and no part of the target shadows it from the Sun (both by ray
   casting on the target's Open3D scene). Nothing is seen in Earth's umbra.
3. **Measurement**: the projection plus Gaussian pixel noise of ``pixel_sigma_px`` per axis; the
   descriptor is the feature's plus Gaussian noise of ``descriptor_noise`` (total norm), renormalised.
4. **Tracks**: features seen by at least ``min_views`` cameras.
5. **False matches**: each track independently becomes false with probability
   ``false_match_fraction``. A false track keeps its first view's measurement and, in one other view,
   takes the projection of a wrong point on the same viewing ray (depth offset uniform within the
   target's radius): a mismatch that passes the epipolar gate, the kind that survives the rendered
   pipeline. It keeps those two views only, gets an unrelated random descriptor, ``feature_id = -1``
   and ``X_T_true = NaN``.

Default parameters are calibrated against the rendered mode (FY-1-like target, two 1024-px 20°
cameras 10° apart, Sun from the side, 8 random attitudes; ``docs/vision.md``): 1500 features with
scales 0.01–0.15 m and a 3 px detection limit give mean track counts of 79 (rendered: 76) at 50 m
and 26 (rendered: 21) at 100 m; the rendered mode's pooled false-track fraction was 1–3 %, hence
``false_match_fraction = 0.02``. ``pixel_sigma_px = 0.5`` is our choice (003 gives no image-noise figure); it is
conservative: the rendered SIFT tracks differ between views by 0.18 px rms per axis at 50 m and
0.27 px at 100 m (about 0.13 and 0.19 px per view).

Surfaces are treated as two-sided (like the renderer), so meshes with inconsistent winding work.
:func:`observe_epochs` evaluates many epochs in one vectorised pass (one ray-casting call per batch).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from attitude.quaternion import check_quat, matrix_from_quat
from vision._blas import one_blas_thread
from vision.calibration import SiftCalibration
from vision.camera import PinholeCamera, cameras_per_view, check_pose
from vision.observation import (
    REASON_EARTH_SHADOW,
    REASON_OUTSIDE_FOV,
    REASON_TOO_FEW_MATCHES,
    Observation,
)
from vision.target import Target

__all__ = ["SurfaceFeatures", "observe", "observe_epochs", "observe_trials", "surface_features"]


@dataclass(frozen=True, eq=False)
class SurfaceFeatures:
    """A fixed set of feature points on a target's surface.

    Attributes
    ----------
    X_T : ndarray, shape (N, 3)
        Positions, body frame, metres.
    normal_T : ndarray, shape (N, 3)
        Unit normals of their triangles (winding direction; used two-sided).
    scale_m : ndarray, shape (N,)
        Physical size of each feature, metres (imaged size ``scale_m · f / z`` pixels).
    descriptors : ndarray, shape (N, D), float32
        Unit descriptors.
    triangle_id : ndarray, shape (N,)
        Triangle of each feature.
    area_m2 : float
        Area of the surface the features were sampled on, m² (the whole mesh, or its outer surface:
        :mod:`vision.outer_surface`); NaN when not known (then the mesh's).
    sites : vision.texture_sites.TextureSites or None
        The texture keypoint sites the features are (:func:`vision.texture_sites.site_features`):
        the calibrated mode then detects them by response rank and takes their sizes; None for
        features spread uniformly by area.
    """

    X_T: np.ndarray
    normal_T: np.ndarray
    scale_m: np.ndarray
    descriptors: np.ndarray
    triangle_id: np.ndarray
    area_m2: float = float("nan")
    sites: object = None

    def __len__(self) -> int:
        return int(len(self.X_T))


def surface_features(target: Target, *, n_features: int = 1500, descriptor_dim: int = 128,
                     scale_range_m: tuple[float, float] = (0.01, 0.15),
                     rng: np.random.Generator | int | None = None, surface: str = "all") -> SurfaceFeatures:
    """Sample feature points uniformly by area on the target surface.

    Parameters
    ----------
    target : Target
    n_features : int
        Number of points N.
    descriptor_dim : int
        Descriptor length D (128, like SIFT).
    scale_range_m : (float, float)
        Range of the log-uniform physical feature scale, metres.
    rng : Generator, int or None
        Random source; None derives a fixed stream from ``target.seed``, so the same target always
        has the same features.
    surface : str
        ``"all"``: the whole mesh; ``"outer"``: only points some camera outside the target can see
        (:func:`vision.outer_surface.outer_mask`), drawn by rejection, uniformly by area over them.
    """
    if not isinstance(target, Target):
        raise ValueError(f"target must be a Target, got {type(target).__name__}")
    if int(n_features) < 1:
        raise ValueError(f"n_features must be >= 1, got {n_features!r}")
    if int(descriptor_dim) < 1:
        raise ValueError(f"descriptor_dim must be >= 1, got {descriptor_dim!r}")
    lo, hi = (float(v) for v in scale_range_m)
    if not 0 < lo <= hi:
        raise ValueError(f"scale_range_m must satisfy 0 < min <= max, got {scale_range_m!r}")
    if surface not in ("all", "outer"):
        raise ValueError(f"surface must be 'all' or 'outer', got {surface!r}")
    if rng is None:
        rng = np.random.SeedSequence([target.seed, 0x5EED])
    rng = np.random.default_rng(rng)
    n = int(n_features)
    tid, X = _points_by_area(target, n, rng)
    area_m2 = float(target.triangle_areas_m2.sum())
    if surface == "outer":
        from vision.outer_surface import outer_mask, outer_surface_area_m2

        keep = outer_mask(target, X, target.triangle_normals_T[tid])
        tid, X = tid[keep], X[keep]
        while len(tid) < n:
            t2, X2 = _points_by_area(target, 2 * (n - len(tid)) + 16, rng)
            k2 = outer_mask(target, X2, target.triangle_normals_T[t2])
            tid, X = np.concatenate([tid, t2[k2]]), np.concatenate([X, X2[k2]])
        tid, X = tid[:n], X[:n]
        area_m2 = outer_surface_area_m2(target)
    scale = np.exp(rng.uniform(np.log(lo), np.log(hi), n))
    desc = rng.standard_normal((n, int(descriptor_dim))).astype(np.float32)
    desc /= np.linalg.norm(desc, axis=1, keepdims=True)
    return SurfaceFeatures(X, target.triangle_normals_T[tid].copy(), scale, desc, tid, area_m2)


def _points_by_area(target: Target, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points uniform by area on the mesh: triangle ids ``(n,)`` and body-frame points ``(n, 3)``, m."""
    area = target.triangle_areas_m2
    tid = rng.choice(len(area), size=n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    flip = r1 + r2 > 1.0
    r1 = np.where(flip, 1.0 - r1, r1)
    r2 = np.where(flip, 1.0 - r2, r2)
    return tid, target.point_on_triangles(tid, np.stack([r1, r2], axis=1))


def _default_features(target: Target) -> SurfaceFeatures:
    return target._cached("geometric_features", lambda: surface_features(target))


def observe(camera: PinholeCamera | Sequence[PinholeCamera], T_CW: ArrayLike, target: Target,
            q_HT: ArrayLike, sun_H: ArrayLike, *, rng: np.random.Generator | int | None = None,
            features: SurfaceFeatures | None = None, pixel_sigma_px: float = 0.5,
            false_match_fraction: float = 0.02, sun_visible_fraction: float = 1.0,
            min_views: int = 2, min_feature_px: float = 3.0, max_view_angle_deg: float = 75.0,
            max_sun_incidence_deg: float = 88.0, descriptor_noise: float = 0.2,
            margin_px: float = 0.0, noise_model: str = "fixed",
            calibration: SiftCalibration | None = None) -> Observation:
    """Geometric-mode observation of one epoch by n cameras (see module docstring for the model).

    Parameters
    ----------
    camera : PinholeCamera or sequence of n PinholeCamera
        Intrinsics (same image size).
    T_CW : array_like, shape (n, 4, 4)
        Camera poses, camera-from-world (world = Hill frame H, origin at the target's centre of mass).
    target : Target
        Target model.
    q_HT : array_like, shape (4,)
        Target attitude (body → Hill), Hamilton scalar-first.
    sun_H : array_like, shape (3,)
        Direction from the target to the Sun, Hill components.
    rng : Generator, int or None
        Random source of pixel noise, descriptor noise and false matches.
    features : SurfaceFeatures, optional
        Surface features (default: ``surface_features(target)``, computed once per target).
    pixel_sigma_px : float
        Gaussian pixel noise per axis, pixels.
    false_match_fraction : float
        Probability in [0, 1) that a track is a false match.
    sun_visible_fraction : float
        Fraction of the Sun seen from the target (0: Earth's umbra, empty observation).
    min_views : int
        Smallest number of views of a track (>= 2).
    min_feature_px : float
        Smallest imaged feature scale that is detected, pixels.
    max_view_angle_deg, max_sun_incidence_deg : float
        Largest angle between the surface normal and the direction to the camera / to the Sun.
    descriptor_noise : float
        Norm of the Gaussian noise added to the unit descriptor of each observation.
    margin_px : float
        Features closer than this to the image border are not seen.
    noise_model, calibration :
        ``"fixed"`` (the options above) or ``"calibrated"`` (the rendered-mode statistics,
        :func:`observe_epochs`).

    Returns
    -------
    Observation
    """
    T = check_pose(T_CW, name="T_CW")
    if T.ndim != 3:
        raise ValueError(f"T_CW must have shape (n, 4, 4), got {T.shape}")
    q = check_quat(q_HT, name="q_HT")
    if q.shape != (4,):
        raise ValueError(f"q_HT must have shape (4,), got {q.shape}")
    s = np.asarray(sun_H, dtype=float)
    if s.shape != (3,):
        raise ValueError(f"sun_H must have shape (3,), got {s.shape}")
    return observe_epochs(camera, T[None], target, q[None], s[None], rng=rng, features=features,
                          pixel_sigma_px=pixel_sigma_px, false_match_fraction=false_match_fraction,
                          sun_visible_fraction=np.array([sun_visible_fraction], dtype=float),
                          min_views=min_views, min_feature_px=min_feature_px,
                          max_view_angle_deg=max_view_angle_deg,
                          max_sun_incidence_deg=max_sun_incidence_deg,
                          descriptor_noise=descriptor_noise, margin_px=margin_px,
                          noise_model=noise_model, calibration=calibration)[0]


def observe_epochs(camera: PinholeCamera | Sequence[PinholeCamera], T_CW: ArrayLike, target: Target,
                   q_HT: ArrayLike, sun_H: ArrayLike, *, rng: np.random.Generator | int | None = None,
                   features: SurfaceFeatures | None = None, pixel_sigma_px: float = 0.5,
                   false_match_fraction: float = 0.02, sun_visible_fraction: ArrayLike = 1.0,
                   min_views: int = 2, min_feature_px: float = 3.0, max_view_angle_deg: float = 75.0,
                   max_sun_incidence_deg: float = 88.0, descriptor_noise: float = 0.2,
                   margin_px: float = 0.0, batch_size: int = 128, noise_model: str = "fixed",
                   calibration: SiftCalibration | None = None) -> list[Observation]:
    """Geometric-mode observations of E epochs in one vectorised pass.

    Same model and options as :func:`observe`, with ``T_CW`` of shape ``(E, n, 4, 4)``, ``q_HT``
    ``(E, 4)``, ``sun_H`` ``(E, 3)`` and ``sun_visible_fraction`` a scalar or ``(E,)``. Epochs are
    processed ``batch_size`` at a time. The random draws of one call depend on the whole batch, so
    give each epoch its own call (or its own ``rng``) when epochs must be independent streams.

    ``noise_model="calibrated"`` replaces the fixed σ, the ``min_feature_px`` limit and the
    ``false_match_fraction`` by the statistics measured on rendered images (``calibration``,
    default the shipped one of the target; :mod:`vision.geometric_calibrated`): detection
    probability, σ per keypoint size, correlated cross-view match survival, false matches, and
    descriptors that survive the epochs' viewpoint change as measured (the epochs of one call are
    taken as consecutive epochs of one trial), with false associations.

    Returns
    -------
    list of Observation
        One per epoch.
    """
    cams, T, q, sun, fsun = _checked(camera, T_CW, target, q_HT, sun_H, sun_visible_fraction, pixel_sigma_px,
                                     false_match_fraction, min_views, max_view_angle_deg,
                                     max_sun_incidence_deg, descriptor_noise)
    E = T.shape[0]
    feats = _default_features(target) if features is None else features
    rng = np.random.default_rng(rng)
    if noise_model == "calibrated":
        from vision.geometric_calibrated import observe_epochs_calibrated

        return observe_epochs_calibrated(
            cams, T, target, q, sun, fsun, feats, rng, calibration=calibration, min_views=int(min_views),
            cos_view=np.cos(np.deg2rad(max_view_angle_deg)), cos_sun=np.cos(np.deg2rad(max_sun_incidence_deg)),
            descriptor_noise=float(descriptor_noise), margin_px=float(margin_px), batch_size=int(batch_size))
    if noise_model != "fixed":
        raise ValueError(f"noise_model must be 'fixed' or 'calibrated', got {noise_model!r}")
    out: list[Observation] = []
    for b0 in range(0, E, int(batch_size)):
        sl = slice(b0, min(E, b0 + int(batch_size)))
        out.extend(_observe_batch(cams, T[sl], target, q[sl], sun[sl], fsun[sl], feats, rng,
                                  pixel_sigma_px=float(pixel_sigma_px),
                                  false_match_fraction=float(false_match_fraction),
                                  min_views=int(min_views), min_feature_px=float(min_feature_px),
                                  cos_view=np.cos(np.deg2rad(max_view_angle_deg)),
                                  cos_sun=np.cos(np.deg2rad(max_sun_incidence_deg)),
                                  descriptor_noise=float(descriptor_noise),
                                  margin_px=float(margin_px)))
    return out


def _checked(camera, T_CW, target, q_HT, sun_H, sun_visible_fraction, pixel_sigma_px, false_match_fraction,
             min_views, max_view_angle_deg, max_sun_incidence_deg, descriptor_noise):
    """The validated inputs of :func:`observe_epochs`: ``(cams, T, q, sun, fsun)``."""
    T = check_pose(T_CW, name="T_CW")
    if T.ndim != 4:
        raise ValueError(f"T_CW must have shape (E, n, 4, 4), got {T.shape}")
    E, n = T.shape[:2]
    q = check_quat(q_HT, name="q_HT")
    if q.shape != (E, 4):
        raise ValueError(f"q_HT must have shape ({E}, 4), got {q.shape}")
    sun = np.asarray(sun_H, dtype=float)
    if sun.shape != (E, 3) or not np.all(np.isfinite(sun)) or np.any(np.linalg.norm(sun, axis=1) == 0):
        raise ValueError(f"sun_H must be finite non-zero vectors of shape ({E}, 3), got {sun.shape}")
    fsun = np.broadcast_to(np.asarray(sun_visible_fraction, dtype=float), (E,))
    if np.any((fsun < 0) | (fsun > 1)) or not np.all(np.isfinite(fsun)):
        raise ValueError(f"sun_visible_fraction must be in [0, 1], got {sun_visible_fraction!r}")
    if not isinstance(target, Target):
        raise ValueError(f"target must be a Target, got {type(target).__name__}")
    cams = cameras_per_view(camera, n)
    if not (np.isfinite(pixel_sigma_px) and pixel_sigma_px >= 0):
        raise ValueError(f"pixel_sigma_px must be >= 0, got {pixel_sigma_px!r}")
    if not 0.0 <= false_match_fraction < 1.0:
        raise ValueError(f"false_match_fraction must be in [0, 1), got {false_match_fraction!r}")
    if not 2 <= int(min_views) <= n:
        raise ValueError(f"min_views must be in [2, {n}], got {min_views!r}")
    if not 0 < max_view_angle_deg <= 90 or not 0 < max_sun_incidence_deg <= 90:
        raise ValueError("max_view_angle_deg and max_sun_incidence_deg must be in (0, 90], got "
                         f"{max_view_angle_deg!r}, {max_sun_incidence_deg!r}")
    if not descriptor_noise >= 0:
        raise ValueError(f"descriptor_noise must be >= 0, got {descriptor_noise!r}")
    return cams, T, q, sun, fsun


def observe_trials(camera: PinholeCamera | Sequence[PinholeCamera], T_CW: ArrayLike, target: Target,
                   q_HT: ArrayLike, sun_H: ArrayLike, *, rngs: Sequence[np.random.Generator],
                   sun_visible_fraction: ArrayLike = 1.0, noise_model: str = "fixed", batch_size: int = 128,
                   **options) -> list[list[Observation]]:
    """R independent trials of E consecutive epochs: ``T_CW (R, E, n, 4, 4)``, ``q_HT (R, E, 4)``,
    ``sun_H (R, E, 3)``, ``sun_visible_fraction`` scalar or ``(R, E)``, one generator per trial.

    Each trial gives what :func:`observe_epochs` gives for its epochs with its own generator;
    ``options`` are those of :func:`observe_epochs`.  The calibrated model computes the projection,
    detection and ray casting of all the trials together
    (:func:`vision.geometric_calibrated.observe_trials_calibrated`); the fixed model calls
    :func:`observe_epochs` per trial.

    Returns
    -------
    list of list of Observation
        ``[trial][epoch]``.
    """
    T = np.asarray(T_CW, dtype=float)
    if T.ndim != 5:
        raise ValueError(f"T_CW must have shape (R, E, n, 4, 4), got {T.shape}")
    R, E = T.shape[:2]
    if len(rngs) != R:
        raise ValueError(f"rngs: expected one generator per trial ({R}), got {len(rngs)}")
    q = np.asarray(q_HT, dtype=float).reshape(R * E, -1)
    sun = np.asarray(sun_H, dtype=float).reshape(R * E, -1)
    fsun = np.broadcast_to(np.asarray(sun_visible_fraction, dtype=float), (R, E)).reshape(R * E)
    if noise_model != "calibrated":
        return [observe_epochs(camera, T[r], target, q.reshape(R, E, -1)[r], sun.reshape(R, E, -1)[r], rng=rngs[r],
                               sun_visible_fraction=fsun.reshape(R, E)[r], noise_model=noise_model,
                               batch_size=batch_size, **options) for r in range(R)]
    from vision.geometric_calibrated import observe_trials_calibrated

    o = {"pixel_sigma_px": 0.5, "false_match_fraction": 0.02, "min_views": 2, "max_view_angle_deg": 75.0,
         "max_sun_incidence_deg": 88.0, "descriptor_noise": 0.2, "margin_px": 0.0, "features": None,
         "calibration": None}
    unknown = set(options) - set(o)
    if unknown:
        raise ValueError(f"observe_trials: unknown options {sorted(unknown)}")
    o.update(options)
    cams, Tf, qf, sunf, fsunf = _checked(camera, T.reshape(R * E, *T.shape[2:]), target, q, sun, fsun,
                                         o["pixel_sigma_px"], o["false_match_fraction"], o["min_views"],
                                         o["max_view_angle_deg"], o["max_sun_incidence_deg"], o["descriptor_noise"])
    feats = _default_features(target) if o["features"] is None else o["features"]
    n = Tf.shape[1]
    return observe_trials_calibrated(cams, Tf.reshape(R, E, n, 4, 4), target, qf.reshape(R, E, 4),
                                     sunf.reshape(R, E, 3), fsunf.reshape(R, E), feats, list(rngs),
                                     calibration=o["calibration"], min_views=int(o["min_views"]),
                                     descriptor_noise=float(o["descriptor_noise"]), margin_px=float(o["margin_px"]),
                                     batch_size=int(batch_size))


@dataclass(eq=False)
class _Geometry:
    """Per-(epoch, camera, feature) geometry of a batch (arrays ``(E, n, N)`` unless noted)."""

    K: np.ndarray          # (n, 3, 3)
    uv: np.ndarray         # (E, n, N, 2)
    z: np.ndarray          # camera z-depth, m
    vis: np.ndarray        # bool: in the image, facing, lit side, (after _occlude) unoccluded and unshadowed
    in_fov: np.ndarray     # (E, n) the target is in the view at all
    cos_view: np.ndarray   # signed cosine of the view angle (normal · direction to the camera)
    cos_sun: np.ndarray    # (E, 1, N) normal · direction to the Sun
    c_T: np.ndarray        # (E, n, 3) camera centres, body frame, m
    R_CT: np.ndarray       # (E, n, 3, 3)
    brightness: np.ndarray | None = None   # relative to the image's exposure (calibrated mode; NaN: not computed)


@one_blas_thread()
def _geometry(cams, T, q, sun, fsun, feats, *, min_feature_px, cos_view, cos_sun, margin_px) -> _Geometry:
    """Projection and the cheap visibility tests (no ray casting) of a batch (one BLAS thread:
    :mod:`vision._blas`)."""
    K = np.stack([c.K for c in cams])                                   # (n, 3, 3)
    fx = K[:, 0, 0][None, :, None]
    fy = K[:, 1, 1][None, :, None]
    cx = K[:, 0, 2][None, :, None]
    cy = K[:, 1, 2][None, :, None]
    W, H = cams[0].image_size
    R_HT = matrix_from_quat(q)                                          # (E, 3, 3)
    R_CW, t_CW = T[..., :3, :3], T[..., :3, 3]                          # (E, n, 3, 3), (E, n, 3)
    # camera centres and Sun direction in the body frame
    R_CT = R_CW @ R_HT[:, None]                                         # (E, n, 3, 3)
    c_T = -np.einsum("enji,enj->eni", R_CT, t_CW)                       # (E, n, 3)
    s_T = np.einsum("eji,ej->ei", R_HT, sun / np.linalg.norm(sun, axis=1, keepdims=True))
    # camera-frame coordinates X_C = R_CT X_T + t_CW, laid out (E, n, 3, N)
    X_C = R_CT @ feats.X_T.T + t_CW[..., None]
    x, y, z = X_C[:, :, 0], X_C[:, :, 1], X_C[:, :, 2]                  # (E, n, N)
    with np.errstate(divide="ignore", invalid="ignore"):
        iz = 1.0 / z
        u = fx * x * iz + cx
        v = fy * y * iz + cy
    vis = ((z > 0) & (u >= -0.5 + margin_px) & (u <= W - 0.5 - margin_px)
           & (v >= -0.5 + margin_px) & (v <= H - 0.5 - margin_px))
    in_fov = vis.any(axis=2)                                            # (E, n) target seen at all
    with np.errstate(invalid="ignore"):
        vis &= feats.scale_m * np.sqrt(fx * fy) * iz >= min_feature_px
    # facing the camera (two-sided) and lit from the camera's side: cos of the view angle is
    # n·(c - X)/|c - X|, and |c - X| = |X_C|
    dist = np.sqrt(x * x + y * y + z * z)
    nX = np.sum(feats.normal_T * feats.X_T, axis=1)                     # (N,)
    ncam = (c_T @ feats.normal_T.T - nX) / dist                         # (E, n, N)
    nsun = (s_T @ feats.normal_T.T)[:, None, :]                         # (E, 1, N)
    side = np.where(ncam >= 0, 1.0, -1.0)
    vis &= (np.abs(ncam) >= cos_view) & (side * nsun >= cos_sun) & (fsun[:, None, None] > 0)
    return _Geometry(K=K, uv=np.stack([u, v], axis=-1), z=z, vis=vis, in_fov=in_fov, cos_view=ncam,
                     cos_sun=nsun, c_T=c_T, R_CT=R_CT)


def _occlude(g: _Geometry, target: Target, feats: SurfaceFeatures, sun_T: np.ndarray, *,
             drop_shadowed: bool = True) -> np.ndarray:
    """Occlusion towards the cameras and shadowing towards the Sun by ray casting (``g.vis`` in place).

    Returns the ``(E, N)`` mask of features whose side seen by the cameras is in the target's own
    shadow or faces away from the Sun; ``drop_shadowed`` also removes them from ``g.vis``.
    """
    import open3d as o3d

    vis = g.vis
    scene = target.scene
    eps = max(1e-3, 1e-4 * target.radius_m)
    at = np.flatnonzero(vis)                                            # flat (epoch, camera, feature)
    if len(at):
        N = vis.shape[2]
        en_i, f_i = np.divmod(at, N)                                    # flat (epoch, camera), feature
        side = np.where(np.take(g.cos_view, at) >= 0, 1.0, -1.0)
        org = feats.X_T[f_i] + eps * side[:, None] * feats.normal_T[f_i]
        rays = np.empty((len(at), 6), dtype=np.float32)
        rays[:, :3] = org
        rays[:, 3:] = g.c_T.reshape(-1, 3)[en_i] - org
        occ = scene.test_occlusions(o3d.core.Tensor(rays), tnear=0.0, tfar=1.0).numpy().astype(bool)
        vis[np.unravel_index(at[occ], vis.shape)] = False
    # Sun shadow: once per (epoch, feature) that some camera still sees; the side facing the Sun is
    # the side facing the cameras that see it (the lit test above).
    e_s, f_s = np.nonzero(vis.any(axis=1))
    dark = np.zeros(vis.shape[::2], dtype=bool)
    if len(e_s):
        sgn = np.where(g.cos_sun[e_s, 0, f_s] >= 0, 1.0, -1.0)
        org = feats.X_T[f_s] + eps * sgn[:, None] * feats.normal_T[f_s]
        rays = np.empty((len(e_s), 6), dtype=np.float32)
        rays[:, :3] = org
        rays[:, 3:] = sun_T[e_s]
        shadowed = scene.test_occlusions(o3d.core.Tensor(rays)).numpy().astype(bool)
        # the seen side faces away from the Sun when the cameras see the other side of the surface
        seen_side = np.where(g.cos_view[e_s, :, f_s] >= 0, 1.0, -1.0)
        away = np.all((seen_side * sgn[:, None] < 0) | ~vis[e_s, :, f_s], axis=1)
        dark[e_s, f_s] = shadowed | away
        if drop_shadowed:
            vis[e_s[shadowed], :, f_s[shadowed]] = False
    return dark


def _sun_T(q: np.ndarray, sun: np.ndarray) -> np.ndarray:
    return np.einsum("eji,ej->ei", matrix_from_quat(q), sun / np.linalg.norm(sun, axis=1, keepdims=True))


def _observe_batch(cams, T, target, q, sun, fsun, feats, rng, *, pixel_sigma_px, false_match_fraction,
                   min_views, min_feature_px, cos_view, cos_sun, descriptor_noise, margin_px):
    E, n = T.shape[:2]
    g = _geometry(cams, T, q, sun, fsun, feats, min_feature_px=min_feature_px, cos_view=cos_view,
                  cos_sun=cos_sun, margin_px=margin_px)
    _occlude(g, target, feats, _sun_T(q, sun))
    K, vis, in_fov, z, uv = g.K, g.vis, g.in_fov, g.z, g.uv
    W, H = cams[0].image_size
    out = []
    D = feats.descriptors.shape[1]
    size = (int(W), int(H))
    for e in range(E):
        if fsun[e] == 0.0:
            out.append(Observation.empty(K, T[e], size, pixel_sigma_px, REASON_EARTH_SHADOW,
                                         descriptor_dim=D))
            continue
        if in_fov[e].sum() < 2:
            out.append(Observation.empty(K, T[e], size, pixel_sigma_px, REASON_OUTSIDE_FOV,
                                         descriptor_dim=D))
            continue
        ve = vis[e]                                                     # (n, N)
        fid = np.nonzero(ve.sum(axis=0) >= min_views)[0]
        M = len(fid)
        if M == 0:
            out.append(Observation.empty(K, T[e], size, pixel_sigma_px, REASON_TOO_FEW_MATCHES,
                                         descriptor_dim=D))
            continue
        seen = ve[:, fid].T                                             # (M, n)
        uv_e = np.swapaxes(uv[e][:, fid], 0, 1).copy()                  # (M, n, 2)
        if pixel_sigma_px > 0:
            uv_e += pixel_sigma_px * rng.standard_normal(uv_e.shape)
        uv_e[~seen] = np.nan
        desc = feats.descriptors[fid].copy()
        if descriptor_noise > 0:
            desc += (descriptor_noise / np.sqrt(D)) * rng.standard_normal(desc.shape).astype(np.float32)
            desc /= np.linalg.norm(desc, axis=1, keepdims=True)
        ids = fid.astype(np.int64)
        X_true = feats.X_T[fid].copy()
        if false_match_fraction > 0:
            keep = _false_matches(rng, false_match_fraction, uv_e, seen, z[e][:, fid].T, cams, T[e],
                                  desc, ids, X_true, target.radius_m, pixel_sigma_px, margin_px)
            uv_e, desc, ids, X_true = uv_e[keep], desc[keep], ids[keep], X_true[keep]
        out.append(Observation(uv_px=uv_e, descriptors=desc, K=K, T_CW=T[e], image_size=size,
                               pixel_sigma_px=pixel_sigma_px, feature_id=ids, X_T_true=X_true,
                               failure_reason="" if len(ids) else REASON_TOO_FEW_MATCHES))
    return out


def _false_matches(rng, fraction, uv, seen, z, cams, T, desc, ids, X_true, radius_m, sigma, margin_px):
    """Turn a random fraction of tracks into epipolar-consistent mismatches (in place); keep mask."""
    M, n = seen.shape
    bad = np.nonzero(rng.random(M) < fraction)[0]
    keep = np.ones(M, dtype=bool)
    if len(bad) == 0:
        return keep
    first = np.argmax(seen[bad], axis=1)
    # another seen view, chosen uniformly
    other = np.empty(len(bad), dtype=np.int64)
    for k, m in enumerate(bad):
        cand = np.nonzero(seen[m])[0]
        cand = cand[cand != first[k]]
        other[k] = rng.choice(cand)
    # wrong point on the first view's ray, at a depth offset within the target's radius
    dz = rng.uniform(-radius_m, radius_m, len(bad))
    zf = z[bad, first]
    znew = np.maximum(zf + dz, 0.5 * zf)
    D = desc.shape[1]
    for k, m in enumerate(bad):
        i, j = first[k], other[k]
        X_Ci = cams[i].backproject(uv[m, i], znew[k])
        X_W = T[i, :3, :3].T @ (X_Ci - T[i, :3, 3])
        X_Cj = T[j, :3, :3] @ X_W + T[j, :3, 3]
        uv_j = cams[j].project(X_Cj) + sigma * rng.standard_normal(2)
        if not cams[j].in_image(uv_j, margin_px=margin_px):
            keep[m] = False
            continue
        row = np.full((n, 2), np.nan)
        row[i] = uv[m, i]
        row[j] = uv_j
        uv[m] = row
        d = rng.standard_normal(D).astype(np.float32)
        desc[m] = d / np.linalg.norm(d)
        ids[m] = -1
        X_true[m] = np.nan
    return keep
