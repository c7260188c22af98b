"""Ray-cast renderer of a target on Open3D's ``RaycastingScene`` (CPU, headless).

For one camera pose, target attitude and Sun direction, :func:`render` gives

- an intensity image through a :class:`~vision.sensor.SensorModel` (and the noiseless radiance):
  Lambertian diffuse term times the texture albedo, an optional Blinn–Phong specular term,
  self-shadowing by occlusion rays towards the Sun, and darkness in Earth's shadow;
- the ground truth of every pixel: z-depth (distance along the optical axis, *not* the range along
  the ray), a target mask, the hit point in the target body frame, the triangle id, and whether the
  point is sunlit.

Rays are cast only through the region of interest (ROI): the projected bounding box of the target,
widened by a margin and aligned to a 32-px grid (so SIFT's image pyramids of the crop and of the full
image sample the same pixels); the result is kept over the ROI (:class:`RenderResult` builds
full-size arrays on demand). Sensor noise is keyed by each pixel's position in the full image
(:class:`~vision.sensor.SensorModel`), so inside the ROI the image is the full-frame image exactly;
outside it is the black level (zero signal: the default sensor's read noise, 0.13 DN, rounds to 0
there but for 4.4 × 10⁻⁵ of the pixels).

Frames: the target's centre of mass is the origin of the Hill frame H (= world W); its attitude is
``q_HT`` (``R_HT`` maps body to Hill components); the camera pose is ``T_CW``.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import ArrayLike

from attitude.quaternion import check_quat, matrix_from_quat
from vision.camera import PinholeCamera, check_pose
from vision.earth import EarthScene
from vision.observation import REASON_EARTH_SHADOW, REASON_OUTSIDE_FOV
from vision.ray_coverage import coverage_mask, covered_rays
from vision.render_result import RenderResult
from vision.sensor import SensorModel
from vision.target import Target

__all__ = ["RenderResult", "cast_body_points", "render", "render_batch", "roi_of_target", "REASON_EARTH_SHADOW",
           "REASON_OUTSIDE_FOV", "REASON_BEHIND_CAMERA"]

#: ``failure_reason`` of a view whose camera has the whole target behind it.
REASON_BEHIND_CAMERA = "target behind camera"

_ROI_ALIGN_PX = 32


def _validate(camera, T_CW, target, q_HT, sun_H):
    if not isinstance(camera, PinholeCamera):
        raise ValueError(f"camera must be a PinholeCamera, got {type(camera).__name__}")
    if not isinstance(target, Target):
        raise ValueError(f"target must be a Target, got {type(target).__name__}")
    T = check_pose(T_CW, name="T_CW")
    if T.shape != (4, 4):
        raise ValueError(f"T_CW must be one (4, 4) pose, got shape {T.shape}")
    q = check_quat(q_HT, name="q_HT")
    if q.shape != (4,):
        raise ValueError(f"q_HT must have shape (4,), got {q.shape}")
    s = np.asarray(sun_H, dtype=float)
    if s.shape != (3,) or not np.all(np.isfinite(s)) or np.linalg.norm(s) == 0:
        raise ValueError(f"sun_H must be a finite non-zero 3-vector, got {np.asarray(sun_H).tolist()}")
    return T, q, s / np.linalg.norm(s)


def _pose_in_body(T_CW: np.ndarray, R_HT: np.ndarray):
    """Camera centre ``c_T`` and ``R_TC`` (camera → body) for a target at the origin of H."""
    R_CW, t_CW = T_CW[:3, :3], T_CW[:3, 3]
    c_H = -R_CW.T @ t_CW
    R_TC = R_HT.T @ R_CW.T
    return R_HT.T @ c_H, R_TC


def roi_of_target(camera: PinholeCamera, T_CW: ArrayLike, target: Target, q_HT: ArrayLike, *,
                  margin_px: int = 16, align_px: int = _ROI_ALIGN_PX) -> tuple[tuple[int, int, int, int], str]:
    """Region of interest around the projected bounding box of the target.

    Returns
    -------
    roi : tuple of int
        ``(x0, y0, x1, y1)`` in pixels (half-open), clipped to the image; the full frame when part of
        the box is behind the camera; ``(0, 0, 0, 0)`` when the target cannot be seen.
    failure_reason : str
        Empty when the target can be seen, else ``"target outside field of view"`` or
        ``"target behind camera"``.
    """
    T = np.asarray(T_CW, dtype=float)
    R_HT = matrix_from_quat(np.asarray(q_HT, dtype=float))
    X_C = (T[:3, :3] @ (R_HT @ target.bbox_corners_T.T)).T + T[:3, 3]
    z = X_C[:, 2]
    if np.all(z <= 0):
        return (0, 0, 0, 0), REASON_BEHIND_CAMERA
    if np.any(z <= 1e-6):
        return (0, 0, camera.width, camera.height), ""
    uv = camera.project(X_C)
    x0 = int(np.floor(uv[:, 0].min())) - margin_px
    y0 = int(np.floor(uv[:, 1].min())) - margin_px
    x1 = int(np.ceil(uv[:, 0].max())) + margin_px + 1
    y1 = int(np.ceil(uv[:, 1].max())) + margin_px + 1
    x0 = max(0, (x0 // align_px) * align_px)
    y0 = max(0, (y0 // align_px) * align_px)
    x1, y1 = min(camera.width, x1), min(camera.height, y1)
    if x1 <= x0 or y1 <= y0:
        return (0, 0, 0, 0), REASON_OUTSIDE_FOV
    return (x0, y0, x1, y1), ""


def cast_body_points(camera: PinholeCamera, T_CW: ArrayLike, target: Target, q_HT: ArrayLike,
                     uv_px: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Exact surface points seen through sub-pixel image positions, by casting one ray each.

    Parameters
    ----------
    camera, T_CW, target, q_HT :
        As in :func:`render`.
    uv_px : array_like, shape (N, 2)
        Pixel coordinates.

    Returns
    -------
    X_T : ndarray, shape (N, 3)
        First surface point along each pixel's ray, body frame, metres (NaN where the ray misses).
    depth_z_m : ndarray, shape (N,)
        Its z-depth (NaN where the ray misses).
    """
    import open3d as o3d

    T = check_pose(T_CW, name="T_CW")
    R_HT = matrix_from_quat(check_quat(q_HT, name="q_HT"))
    uv = np.asarray(uv_px, dtype=float).reshape(-1, 2)
    c_T, R_TC = _pose_in_body(T, R_HT)
    rays = np.empty((len(uv), 6), dtype=np.float32)
    rays[:, :3] = c_T
    rays[:, 3:] = camera.ray_directions(uv) @ R_TC.T
    hits = target.scene.cast_rays(o3d.core.Tensor(rays))
    t = hits["t_hit"].numpy()
    hit = np.isfinite(t)
    X = np.full((len(uv), 3), np.nan)
    z = np.full(len(uv), np.nan)
    if hit.any():
        X[hit] = target.point_on_triangles(hits["primitive_ids"].numpy().astype(np.int64)[hit],
                                           hits["primitive_uvs"].numpy()[hit].astype(np.float64))
        z[hit] = ((X[hit] - c_T) @ R_TC)[:, 2]
    return X, z


def _mip_level(tex: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Mip level per pixel from screen-space texel derivatives (``tex`` (h, w, 2), NaN off target).

    Per axis the smaller of the forward and backward differences is used, so texture seams and
    silhouettes do not blur their neighbours; ``level = log2(max(|∂s/∂u|, |∂s/∂v|))``.
    """
    big = np.float32(1e6)

    def deriv(axis: int) -> np.ndarray:
        d = np.diff(tex, axis=axis)
        n = np.sqrt((d ** 2).sum(-1))
        n = np.where(np.isfinite(n), n, big)
        pad_shape = list(n.shape)
        pad_shape[axis] = 1
        pad = np.full(pad_shape, big, dtype=n.dtype)
        fwd = np.concatenate([n, pad], axis=axis)
        bwd = np.concatenate([pad, n], axis=axis)
        return np.minimum(fwd, bwd)

    rho = np.maximum(deriv(0), deriv(1))
    rho = np.where(rho >= big, 1.0, rho)
    with np.errstate(divide="ignore"):
        level = np.log2(np.maximum(rho, 1.0))
    return np.where(valid, level, 0.0).astype(np.float32)


def _cast_box(camera: PinholeCamera, T: np.ndarray, target: Target, q: np.ndarray, roi: bool,
              roi_margin_px: int) -> tuple[tuple[int, int, int, int], str]:
    """The pixel box rays are cast through (the ROI, or the whole image) and why none is cast."""
    box, reason = roi_of_target(camera, T, target, q, margin_px=int(roi_margin_px))
    if roi:
        return box, reason
    return (0, 0, camera.width, camera.height), reason if reason == REASON_BEHIND_CAMERA else ""


def _check_light(sun_visible_fraction: float, ambient: float) -> float:
    """The visible Sun fraction as a float, after checking it and the ambient level."""
    f_sun = float(sun_visible_fraction)
    if not 0.0 <= f_sun <= 1.0:
        raise ValueError(f"sun_visible_fraction must be in [0, 1], got {sun_visible_fraction!r}")
    if not (np.isfinite(ambient) and ambient >= 0):
        raise ValueError(f"ambient must be >= 0, got {ambient!r}")
    return f_sun


def render(camera: PinholeCamera, T_CW: ArrayLike, target: Target, q_HT: ArrayLike, sun_H: ArrayLike,
           *, rng: np.random.Generator | int | None = None, sensor: SensorModel | None = None,
           sun_visible_fraction: float = 1.0, ambient: float = 0.0, specular: bool = True,
           shadows: bool = True, roi: bool = True, roi_margin_px: int = 16,
           earth: EarthScene | None = None) -> RenderResult:
    """Render the target seen by one camera, with per-pixel ground truth.

    Parameters
    ----------
    camera : PinholeCamera
        Intrinsics.
    T_CW : array_like, shape (4, 4)
        Camera pose, camera-from-world (world = Hill frame H).
    target : Target
        Target model (body frame T, origin at the centre of mass = origin of H).
    q_HT : array_like, shape (4,)
        Target attitude, Hamilton scalar-first, body → Hill.
    sun_H : array_like, shape (3,)
        Direction from the target to the Sun, Hill components (normalised here).
    rng : Generator, int or None
        Random source of the sensor noise.
    sensor : SensorModel, optional
        Sensor chain (default ``SensorModel()``).
    sun_visible_fraction : float
        Fraction of the solar disc seen from the target: 1 in sunlight, 0 in Earth's umbra (the image
        is then dark and ``failure_reason`` is ``"target in Earth shadow"``), in between in the penumbra.
    ambient : float
        Diffuse ambient illumination (e.g. Earthshine) in units of the direct Sun, >= 0.
    specular, shadows : bool
        Include the Blinn–Phong specular term and the self-shadowing occlusion rays.
    earth : EarthScene, optional
        The Earth behind the target in the ROI and its albedo light on the target (:mod:`vision.earth`);
        None: black sky, no Earth light.
    roi : bool
        Ray-cast only the region of interest (True) or the full frame (False).
    roi_margin_px : int
        Margin around the projected bounding box, pixels.

    Returns
    -------
    RenderResult
    """
    T, q, s_H = _validate(camera, T_CW, target, q_HT, sun_H)
    f_sun = _check_light(sun_visible_fraction, ambient)
    sensor = SensorModel() if sensor is None else sensor
    rng = np.random.default_rng(rng)
    H, W = camera.height, camera.width
    image = np.zeros((H, W), dtype=sensor.dtype)
    radiance = np.zeros((H, W), dtype=np.float32)
    depth = np.full((H, W), np.nan, dtype=np.float32)
    mask = np.zeros((H, W), dtype=bool)
    X_img = np.full((H, W, 3), np.nan, dtype=np.float32)
    tri_img = np.full((H, W), -1, dtype=np.int32)
    lit_img = np.zeros((H, W), dtype=bool)

    R_HT = matrix_from_quat(q)
    box, reason = _cast_box(camera, T, target, q, roi, roi_margin_px)

    def result(st: str, exposure_s: float = float("nan")) -> RenderResult:
        rs = (slice(box[1], box[3]), slice(box[0], box[2]))
        return RenderResult(image[rs], radiance[rs], depth[rs], mask[rs], X_img[rs], tri_img[rs], lit_img[rs], box,
                            st, camera, T, exposure_s)

    if reason:
        return result(reason)
    x0, y0, x1, y1 = box
    h, w = y1 - y0, x1 - x0
    c_T, R_TC = _pose_in_body(T, R_HT)
    uu, vv = np.meshgrid(np.arange(x0, x1, dtype=np.float64), np.arange(y0, y1, dtype=np.float64))
    d_C = np.stack([(uu - camera.cx) / camera.fx, (vv - camera.cy) / camera.fy, np.ones_like(uu)], -1)
    d_T = d_C @ R_TC.T
    rays = np.empty((h, w, 6), dtype=np.float32)
    rays[..., :3] = c_T
    rays[..., 3:] = d_T

    import open3d as o3d

    scene = target.scene
    hits = scene.cast_rays(o3d.core.Tensor(rays))
    t_hit = hits["t_hit"].numpy()
    hit = np.isfinite(t_hit)
    if not hit.any():
        return result(REASON_OUTSIDE_FOV)
    tid = hits["primitive_ids"].numpy().astype(np.int64)[hit]
    bary = hits["primitive_uvs"].numpy()[hit].astype(np.float64)
    X = target.point_on_triangles(tid, bary)                     # (N, 3) body frame, exact on face
    # z-depth: the ray direction has unit z in the camera frame, so t_hit is the z-depth
    z = ((X - c_T) @ R_TC)[:, 2]
    n = target.triangle_normals_T[tid]
    v = c_T - X
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    n = np.where((np.sum(n * v, axis=1) < 0)[:, None], -n, n)   # two-sided: face the camera
    # texture with mip-mapping from screen-space derivatives
    tex = np.full((h, w, 2), np.nan, dtype=np.float32)
    tex[hit] = target.texture_coords(tid, bary)
    level = _mip_level(tex, hit)[hit]
    albedo = target.sample_albedo(tex[hit], level, tid).astype(np.float64)
    # direct sunlight
    s_T = R_HT.T @ s_H
    cos_i = n @ s_T
    lit = cos_i > 0.0
    if shadows and lit.any():
        eps = max(1e-3, 1e-4 * target.radius_m)
        idx = np.nonzero(lit)[0]
        sray = np.empty((len(idx), 6), dtype=np.float32)
        sray[:, :3] = X[idx] + eps * n[idx]
        sray[:, 3:] = s_T
        occluded = scene.test_occlusions(o3d.core.Tensor(sray)).numpy().astype(bool)
        lit[idx[occluded]] = False
    L = albedo * np.maximum(cos_i, 0.0) * lit
    if specular:
        ks = np.array([m.specular for m in target.materials])[target.triangle_material[tid]]
        ns = np.array([m.shininess for m in target.materials])[target.triangle_material[tid]]
        hvec = s_T + v
        hvec /= np.maximum(np.linalg.norm(hvec, axis=1, keepdims=True), 1e-12)
        L = L + ks * np.maximum(np.sum(n * hvec, axis=1), 0.0) ** ns * lit
    L = f_sun * L + ambient * albedo
    if earth is not None:
        L = L + albedo * earth.albedo_irradiance(n @ R_HT.T, s_H)
    # place into the full-size images
    rs = (slice(y0, y1), slice(x0, x1))
    rad_roi = np.zeros((h, w), dtype=np.float32)
    rad_roi[hit] = L
    if earth is not None:
        rad_roi[~hit] = earth.background(camera, T, box, s_H)[~hit]
    radiance[rs] = rad_roi
    sub = depth[rs]
    sub[hit] = z
    mask[rs] = hit
    subX = X_img[rs]
    subX[hit] = X
    subT = tri_img[rs]
    subT[hit] = tid
    subL = lit_img[rs]
    subL[hit] = lit & (f_sun > 0)
    exposure = sensor.exposure_for(rad_roi)
    image[rs] = sensor.apply(rad_roi, rng=rng, exposure_s=exposure, origin_px=(x0, y0))
    return result(REASON_EARTH_SHADOW if f_sun == 0.0 else "", exposure)


# ----------------------------------------------------------------------------------------------
# all views of one epoch in one call (the faster rendered mode, issue 16 item 7)
# ----------------------------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def _mip_rho(tex: np.ndarray, flat: np.ndarray, cols: np.ndarray, w: int,
             rho: np.ndarray) -> None:  # pragma: no cover - compiled
    """:func:`_mip_level_at`'s texel footprint at each hit, in one compiled pass over the hits in raster
    order (``flat`` ascending): the float32 distance to each of the 4 neighbours (1e6 where it is not a
    hit: off the target or off the ROI), the larger of the smaller vertical and the smaller horizontal
    one, 1 where both directions have no neighbour (the float32 operations of :func:`_mip_level`, no
    fused multiply-adds).  The neighbours a row above and below are found by two cursors moving forward."""
    big = np.float32(1e6)
    n = flat.shape[0]
    up = down = 0
    for i in range(n):
        f = flat[i]
        while up < n and flat[up] < f - w:
            up += 1
        while down < n and flat[down] < f + w:
            down += 1
        d_up = _texel_step(tex, i, up, big) if up < n and flat[up] == f - w else big
        d_down = _texel_step(tex, i, down, big) if down < n and flat[down] == f + w else big
        d_left = _texel_step(tex, i, i - 1, big) if cols[i] > 0 and i > 0 and flat[i - 1] == f - 1 else big
        d_right = (_texel_step(tex, i, i + 1, big) if cols[i] < w - 1 and i + 1 < n and flat[i + 1] == f + 1
                   else big)
        r = max(min(d_down, d_up), min(d_right, d_left))
        rho[i] = np.float32(1.0) if r >= big else r


@numba.njit(cache=True, nogil=True, inline="always")
def _texel_step(tex: np.ndarray, i: int, j: int, big: np.float32) -> np.float32:  # pragma: no cover - compiled
    du = tex[j, 0] - tex[i, 0]
    dv = tex[j, 1] - tex[i, 1]
    n = np.float32(np.sqrt(du * du + dv * dv))
    return n if np.isfinite(n) else big


def _mip_level_at(tex_hit: np.ndarray, flat: np.ndarray, cols: np.ndarray, w: int) -> np.ndarray:
    """:func:`_mip_level` at the hit pixels only (``flat = row · w + col`` ascending, ``cols`` their columns
    in an ROI ``w`` wide), from their texel coordinates ``tex_hit`` (``(N, 2)`` float32): the same float32
    operations on the same neighbour differences, so the same values."""
    rho = np.empty(len(flat), dtype=np.float32)
    _mip_rho(np.ascontiguousarray(tex_hit, dtype=np.float32), flat, cols, int(w), rho)
    with np.errstate(divide="ignore"):
        return np.log2(np.maximum(rho, 1.0)).astype(np.float32)


def _roi_arrays(box: tuple[int, int, int, int], flat: np.ndarray, L: np.ndarray, z: np.ndarray, X: np.ndarray,
                tid: np.ndarray, lit: np.ndarray) -> tuple[np.ndarray, ...]:
    """A view's output arrays over its ROI but the image (radiance, depth, mask, X_T, triangle, lit) with the
    hits ``flat`` (raster order) placed by :func:`_place_hits` and the off-target values elsewhere."""
    shape = (box[3] - box[1], box[2] - box[0])
    a = (np.empty(shape, dtype=np.float32), np.empty(shape, dtype=np.float32), np.empty(shape, dtype=bool),
         np.empty(shape + (3,), dtype=np.float32), np.empty(shape, dtype=np.int32), np.empty(shape, dtype=bool))
    rad, depth, mask, X_img, tri, lit_img = a
    _place_hits(flat, L, z, X, tid, lit, rad.reshape(-1), depth.reshape(-1), mask.reshape(-1), X_img.reshape(-1, 3),
                tri.reshape(-1), lit_img.reshape(-1))
    return a


def _off_target(box: tuple[int, int, int, int], image_dtype: type) -> tuple[np.ndarray, ...]:
    """A view's output arrays over its ROI, as off the target: image, radiance, depth, mask, X_T, triangle, lit."""
    none = np.empty(0, dtype=np.int64)
    return (np.zeros((box[3] - box[1], box[2] - box[0]), dtype=image_dtype),
            *_roi_arrays(box, none, np.empty(0), np.empty(0), np.empty((0, 3)), none, np.empty(0, dtype=bool)))


@numba.njit(cache=True, nogil=True)
def _place_hits(flat: np.ndarray, L: np.ndarray, z: np.ndarray, X: np.ndarray, tid: np.ndarray, lit: np.ndarray,
                radiance: np.ndarray, depth: np.ndarray, mask: np.ndarray, X_img: np.ndarray, tri_img: np.ndarray,
                lit_img: np.ndarray) -> None:  # pragma: no cover - compiled
    """A view's flattened ROI arrays (``X_img`` ``(h w, 3)``) written in one pass, each pixel once: the hit
    values (float64 rounded to float32, as NumPy's assignment does) at the hit pixels ``flat`` (ascending),
    and between them the off-target values: 0, NaN, False, NaN, −1, False."""
    start = 0
    for i in range(flat.shape[0] + 1):
        stop = flat[i] if i < flat.shape[0] else radiance.shape[0]
        if stop > start:
            radiance[start:stop] = 0.0
            depth[start:stop] = np.nan
            mask[start:stop] = False
            X_img[start:stop] = np.nan
            tri_img[start:stop] = -1
            lit_img[start:stop] = False
        if i < flat.shape[0]:
            radiance[stop] = np.float32(L[i])
            depth[stop] = np.float32(z[i])
            mask[stop] = True
            for k in range(3):
                X_img[stop, k] = np.float32(X[i, k])
            tri_img[stop] = tid[i]
            lit_img[stop] = lit[i]
        start = stop + 1


@numba.njit(cache=True, nogil=True)
def _shadow_rays(X: np.ndarray, n: np.ndarray, idx: np.ndarray, eps: float, s_T: np.ndarray,
                 rays: np.ndarray) -> None:  # pragma: no cover - compiled
    """The float32 occlusion rays towards the Sun from the hits ``idx``: origin ``X + eps n`` (float64, no
    fused multiply-add), direction ``s_T``."""
    for j in range(idx.shape[0]):
        i = idx[j]
        for k in range(3):
            rays[j, k] = np.float32(X[i, k] + eps * n[i, k])
            rays[j, 3 + k] = np.float32(s_T[k])


#: rows per BLAS call in :func:`_matmul_rows` (a multiple of OpenBLAS's row blocking)
_MATMUL_ROWS = 2048


def _matmul_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` for a tall ``a`` (N, 3), in blocks of 2048 rows: the same per-row values, but each
    OpenBLAS call is below its threading threshold, so no BLAS threads spin on a loaded machine (one
    threaded (300 000, 3) × (3, 3) product costs 40× the CPU time of the blocked one there)."""
    out = np.empty((len(a),) + b.shape[1:], dtype=np.result_type(a, b))
    for i in range(0, len(a), _MATMUL_ROWS):
        np.matmul(a[i:i + _MATMUL_ROWS], b, out=out[i:i + _MATMUL_ROWS])
    return out


@numba.njit(cache=True, nogil=True)
def _facing_normals(X: np.ndarray, c_T: np.ndarray, normals: np.ndarray, tid: np.ndarray, s_T: np.ndarray,
                    n: np.ndarray, n_dot_h: np.ndarray) -> None:  # pragma: no cover - compiled
    """:func:`render`'s per-hit geometry in one pass, with its float64 operations in its order: the
    unit view direction ``v = (c - X) / |c - X|``, the triangle normal turned towards the camera
    (``n``), and ``n · h`` with the half vector ``h = (s + v) / max(|s + v|, 1e-12)`` (specular)."""
    for i in range(X.shape[0]):
        a0, a1, a2 = c_T[0] - X[i, 0], c_T[1] - X[i, 1], c_T[2] - X[i, 2]
        r = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        a0, a1, a2 = a0 / r, a1 / r, a2 / r
        t = tid[i]
        m0, m1, m2 = normals[t, 0], normals[t, 1], normals[t, 2]
        if m0 * a0 + m1 * a1 + m2 * a2 < 0:
            m0, m1, m2 = -m0, -m1, -m2
        n[i, 0], n[i, 1], n[i, 2] = m0, m1, m2
        h0, h1, h2 = s_T[0] + a0, s_T[1] + a1, s_T[2] + a2
        r = np.sqrt(h0 * h0 + h1 * h1 + h2 * h2)
        r = r if not r < 1e-12 else 1e-12                            # np.maximum: NaN stays NaN
        n_dot_h[i] = m0 * (h0 / r) + m1 * (h1 / r) + m2 * (h2 / r)


def render_batch(cameras: list[PinholeCamera], T_CW: ArrayLike, target: Target, q_HT: ArrayLike,
                 sun_H: ArrayLike, *, rngs: list[np.random.Generator], sensor: SensorModel | None = None,
                 sun_visible_fraction: float = 1.0, ambient: float = 0.0, specular: bool = True,
                 shadows: bool = True, roi: bool = True, roi_margin_px: int = 16,
                 earth: EarthScene | None = None) -> list[RenderResult]:
    """:func:`render` of the n views of one epoch in one call: the same :class:`RenderResult` per view.

    The rays of all views go to Open3D in one ``cast_rays`` call and the shadow rays in one
    ``test_occlusions`` call, the mip level is computed at the hit pixels only, and the camera rays
    are built from one row and one column of normalised coordinates; per-view matrix products keep
    their shapes, so every output array equals :func:`render`'s (``tests/vision/test_render_batch.py``).

    Parameters
    ----------
    cameras : list of n PinholeCamera
    T_CW : array_like, shape (n, 4, 4)
        Camera poses (world = Hill frame H).
    rngs : list of n Generator
        The sensor-noise stream of each view (what :func:`render` takes as ``rng``).
    target, q_HT, sun_H, sensor, sun_visible_fraction, ambient, specular, shadows, roi, roi_margin_px, earth :
        As in :func:`render`.
    """
    import open3d as o3d

    T_all = check_pose(T_CW, name="T_CW")
    if T_all.ndim != 3 or len(T_all) != len(cameras) or len(rngs) != len(cameras):
        raise ValueError(f"cameras, T_CW, rngs: need one each per view, got {len(cameras)}, "
                         f"{T_all.shape}, {len(rngs)}")
    f_sun = _check_light(sun_visible_fraction, ambient)
    sensor = SensorModel() if sensor is None else sensor
    views = []
    for cam, T_v, rng in zip(cameras, T_all, rngs, strict=True):
        T, q, s_H = _validate(cam, T_v, target, q_HT, sun_H)
        R_HT = matrix_from_quat(q)
        v = {"cam": cam, "T": T, "rng": np.random.default_rng(rng)}
        box, reason = _cast_box(cam, T, target, q, roi, roi_margin_px)
        v["box"], v["reason"] = box, reason
        if not reason:
            x0, y0, x1, y1 = box
            c_T, R_TC = _pose_in_body(T, R_HT)
            cover = coverage_mask(cam, target, c_T, R_TC, box)
            if cover is None:
                cover = np.ones((y1 - y0, x1 - x0), dtype=bool)
            v.update(c_T=c_T, R_TC=R_TC, cover=cover, n_rays=np.count_nonzero(cover))
        views.append(v)
    s_T = R_HT.T @ s_H
    cast = [v for v in views if not v["reason"]]
    if cast:
        rays = np.empty((sum(v["n_rays"] for v in cast), 6), dtype=np.float32)   # every view's, in one array
        start = 0
        for v in cast:
            cam, n_rays = v["cam"], v["n_rays"]
            v["rows"], v["cols"] = np.empty(n_rays, dtype=np.int64), np.empty(n_rays, dtype=np.int64)
            d_C, rays_v = np.empty((n_rays, 3)), rays[start:start + n_rays]
            covered_rays(v["cover"], v["box"][0], v["box"][1], (cam.cx, cam.cy, cam.fx, cam.fy), v["c_T"],
                          v["rows"], v["cols"], d_C, rays_v)
            rays_v[:, 3:] = _matmul_rows(d_C, v["R_TC"].T)
            start += n_rays
        hits = target.scene.cast_rays(o3d.core.Tensor.from_numpy(rays))
        t_all = hits["t_hit"].numpy()
        pid_all = hits["primitive_ids"].numpy()
        uv_all = hits["primitive_uvs"].numpy()
    start = 0
    occl = []
    eps = max(1e-3, 1e-4 * target.radius_m)
    for v in cast:
        w = v["box"][2] - v["box"][0]
        n_rays = v["n_rays"]
        sl = slice(start, start + n_rays)
        start += n_rays
        got = np.isfinite(t_all[sl])
        rows, cols = np.compress(got, v["rows"]), np.compress(got, v["cols"])
        v["hit_flat"] = rows * w + cols
        if not got.any():
            v["reason"] = REASON_OUTSIDE_FOV
            continue
        tid = np.compress(got, pid_all[sl]).astype(np.int64)
        bary = np.compress(got, uv_all[sl], axis=0).astype(np.float64)   # (a boolean index costs 10x here)
        X = target.point_on_triangles(tid, bary)
        z = _matmul_rows(X - v["c_T"], v["R_TC"])[:, 2]
        n, n_dot_h = np.empty_like(X), np.empty(len(X))
        _facing_normals(X, v["c_T"], target.triangle_normals_T, tid, s_T, n, n_dot_h)
        tex_hit = target.texture_coords(tid, bary)
        level = _mip_level_at(tex_hit, v["hit_flat"], cols, w)
        albedo = target.sample_albedo(tex_hit, level, tid).astype(np.float64)
        cos_i = _matmul_rows(n, s_T)
        lit = cos_i > 0.0
        v.update(tid=tid, X_hit=X, z=z, n=n, n_dot_h=n_dot_h, albedo=albedo, cos_i=cos_i, lit_hit=lit)
        if shadows and lit.any():
            idx = np.flatnonzero(lit)
            sray = np.empty((len(idx), 6), dtype=np.float32)
            _shadow_rays(X, n, idx, eps, s_T, sray)
            occl.append((v, idx, sray))
    if occl:
        occluded = target.scene.test_occlusions(o3d.core.Tensor.from_numpy(np.concatenate([o[2] for o in occl]))).numpy()
        start = 0
        for v, idx, _ in occl:
            v["lit_hit"][idx[occluded[start:start + len(idx)].astype(bool)]] = False
            start += len(idx)
    out = []
    ks_tri = np.array([m.specular for m in target.materials])[target.triangle_material]
    ns_tri = np.array([m.shininess for m in target.materials])[target.triangle_material]
    for v in views:
        if v["reason"]:
            out.append(RenderResult(*_off_target(v["box"], sensor.dtype), v["box"], v["reason"], v["cam"], v["T"],
                                    float("nan")))
            continue
        tid, lit, n, albedo = v["tid"], v["lit_hit"], v["n"], v["albedo"]
        L = albedo * np.maximum(v["cos_i"], 0.0) * lit
        if specular:
            L = L + ks_tri[tid] * np.maximum(v["n_dot_h"], 0.0) ** ns_tri[tid] * lit
        L = f_sun * L + ambient * albedo
        if earth is not None:
            L = L + albedo * earth.albedo_irradiance(_matmul_rows(n, R_HT.T), s_H)
        x0, y0 = v["box"][:2]
        flat = v["hit_flat"]                                     # row-major, the order of [hit]
        rad_roi, depth, mask, X_img, tri_img, lit_img = _roi_arrays(v["box"], flat, L, v["z"], v["X_hit"], tid,
                                                                    lit & (f_sun > 0))
        if earth is not None:
            rad_roi[~mask] = earth.background(v["cam"], v["T"], v["box"], s_H)[~mask]
        # the positive radiances in raster order: the hits' alone (no ROI-sized mask) without the Earth
        exposure = sensor.exposure_for(rad_roi if earth is not None else rad_roi.reshape(-1)[flat])
        image = sensor.apply(rad_roi, rng=v["rng"], exposure_s=exposure, origin_px=(x0, y0))
        out.append(RenderResult(image, rad_roi, depth, mask, X_img, tri_img, lit_img, v["box"],
                                REASON_EARTH_SHADOW if f_sun == 0.0 else "", v["cam"], v["T"], exposure))
    return out
