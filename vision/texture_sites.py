"""Feature sites from the target's own textures: where a SIFT detector finds keypoints at an image scale.

The calibrated geometric mode (:mod:`vision.geometric_calibrated`) draws its features from these
sites instead of uniformly over the surface.  Rendered SIFT keypoints do not spread evenly over a
face: they cluster on the textured spots (labels, tape seams, creases, cell gaps, ribs, bolts), and
the spread of the tracked points (their lever arm) is what sets the rotation error of a
registration.  The sites reproduce that spread from the textures the renderer samples:

1. The target's albedo atlas (:attr:`vision.target.Target.texture`, ``texel_m`` per texel; each
   atlas texel is multiplied by its material's albedo where a triangle covers it) is resampled to
   the image footprint ``m/px`` (range over focal length: 1024 px over 20° gives 14 mm/px at 40 m,
   27 mm/px at 80 m), scaled to 8 bits and given to OpenCV SIFT (the rendered mode's detector,
   :func:`vision.features.detect`) with a low contrast threshold (:data:`SITE_CONTRAST_THRESHOLD`),
   so that there are more sites than the densest measured bin asks for.
2. Every keypoint is mapped back through the triangles' texture coordinates to the body-frame
   surface points whose texture it is (one site per triangle whose texture triangle contains it:
   a box-mapped mesh such as TOPEX reuses a texture region on parallel faces); sites not on the
   target's outer surface (:func:`vision.outer_surface.outer_mask`) are dropped.
3. Each site keeps its SIFT diameter in metres (``size_px · footprint``) and its response; its
   *detection rank* is its response's quantile among the sites of its material, and the density
   of its material's sites over the material's outer area is stored with it.

Footprints are quantised to quarter octaves (:func:`footprint_level`) and the sites of a target are
computed once per level (about 0.1–1.5 s) and cached on the target.  Nothing here is random: the
same target and footprint give the same sites.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision.target import Target

__all__ = ["SITE_CONTRAST_THRESHOLD", "TextureSites", "footprint_level", "outer_area_by_material_m2",
           "site_features", "texture_image", "texture_sites"]

#: OpenCV SIFT contrast threshold of the site detection (the default 0.04 gives about 60 sites per
#: m² on FY-1 at 14 mm/px, fewer than the densest measured bin; the calibrated mode picks among the
#: sites by response, :mod:`vision.geometric_calibrated`)
SITE_CONTRAST_THRESHOLD = 0.005
#: grey level of an atlas texel of value 1 and albedo 1 in the 8-bit image given to SIFT
_GREY_FULL = 255.0
#: footprints are quantised to this fraction of an octave
FOOTPRINT_STEP_OCTAVES = 0.25
#: Lowe ratio of the rendered mode's matching (:func:`vision.features.match_pair`)
RATIO_TEST = 0.6
#: scales of the Rayleigh law of the true match's descriptor distance tabulated by :func:`_rayleigh_scale`
_SCALE_GRID = np.geomspace(1e-3, 1e2, 400)
#: survivals at which each material's Rayleigh scale is tabulated (uniform, for a fast lookup)
_SURVIVAL_GRID = np.linspace(0.0, 1.0, 1001)
#: radius of the flat surface a site needs around it (:func:`_flat_support`) over its SIFT diameter
SUPPORT_RADIUS_OVER_SIZE = 0.75
#: largest angle between the site's normal and the surface normal within its support, degrees
SUPPORT_MAX_TILT_DEG = 25.0
#: side of the atlas buckets of the keypoint → triangle search, resampled pixels
_BUCKET_PX = 16
#: area-uniform points of the Monte-Carlo estimate of each material's outer area
_AREA_SAMPLES = 50_000


@dataclass(frozen=True, eq=False)
class TextureSites:
    """Keypoint sites on a target's outer surface at one image footprint.

    Attributes
    ----------
    X_T : ndarray (N, 3)
        Site positions, body frame, m.
    normal_T : ndarray (N, 3)
        Unit normals of their triangles.
    triangle_id : ndarray (N,)
        Triangle of each site.
    size_m : ndarray (N,)
        SIFT keypoint diameter on the surface, m (diameter in px times the footprint).
    response : ndarray (N,)
        SIFT response.
    detection_rank : ndarray (N,)
        Quantile of the site's response among the sites of its material, in (0, 1): 0 strongest.
    material : ndarray (N,)
        Material of each site (index into the target's materials).
    density_per_m2 : ndarray (N,)
        Sites per m² of outer surface of the site's material.
    descriptor_gap : ndarray (N,)
        Distance of the site's unit SIFT descriptor to the nearest descriptor of another site's
        keypoint at this footprint (not of the same blob): small on repeated patterns (solar-cell
        grids, ribs), where the ratio test of the matching rejects the site.
    footprint_m_per_px : float
        Image footprint the texture was resampled to, m/px.
    area_m2 : float
        Outer surface area of the target, m².
    n_materials : int
        Number of the target's materials.
    """

    X_T: np.ndarray
    normal_T: np.ndarray
    triangle_id: np.ndarray
    size_m: np.ndarray
    response: np.ndarray
    detection_rank: np.ndarray
    material: np.ndarray
    density_per_m2: np.ndarray
    descriptor_gap: np.ndarray
    footprint_m_per_px: float
    area_m2: float
    n_materials: int

    def __len__(self) -> int:
        return int(len(self.X_T))

    @property
    def density_by_material(self) -> np.ndarray:
        """Sites per m² of each material's outer surface ``(P,)`` (0 for a material without sites)."""
        out = np.zeros(int(self.n_materials))
        out[self.material] = self.density_per_m2
        return out

    def _log_scale_by_material(self) -> np.ndarray:
        """``log c`` per material ``(P, G)`` at the survivals of :data:`_SURVIVAL_GRID`: the Rayleigh scale
        at which the mean survival over that material's sites is the grid's value (computed once)."""
        if "_log_scale" not in self.__dict__:
            out = np.zeros((int(self.n_materials), len(_SURVIVAL_GRID)))
            for m in np.unique(self.material):
                gap = self.descriptor_gap[self.material == m]
                sub = gap[:: max(1, len(gap) // 4000)]
                mean = np.array([np.mean(1.0 - np.exp(-((RATIO_TEST * sub / c) ** 2))) for c in _SCALE_GRID])
                out[m] = np.log(_rayleigh_scale(mean, _SURVIVAL_GRID))
            object.__setattr__(self, "_log_scale", out)
        return self.__dict__["_log_scale"]

    def pair_survival(self, survival, site) -> np.ndarray:
        """Probability that a view pair matches site ``site`` when the mean over the sites of its material
        is ``survival``.

        The ratio test keeps a site when the descriptor distance of its true match, ``d``, is below
        ``RATIO_TEST · descriptor_gap``.  With ``d`` Rayleigh-distributed of a scale ``c`` (the viewpoint
        and noise change of a descriptor between views), a site survives with ``1 − exp(−(RATIO_TEST ·
        gap / c)²)``; ``c`` is chosen so that the mean over the sites of the site's material is the
        ``survival`` given, which already carries the measured factor of that material
        (:mod:`vision.calibration.survival_factors`): the gaps spread the survival within a material,
        not between materials (:func:`_rayleigh_scale`).  ``survival`` and ``site`` broadcast.
        """
        S = np.asarray(survival, dtype=float)
        site = np.asarray(site, dtype=np.int64)
        c = np.exp(_interp_rows(self._log_scale_by_material(), self.material[site], S))
        return 1.0 - np.exp(-((RATIO_TEST * self.descriptor_gap[site] / c) ** 2))


def _interp_rows(table: np.ndarray, row: np.ndarray, survival: np.ndarray) -> np.ndarray:
    """``table[row]`` interpolated linearly at ``survival`` on :data:`_SURVIVAL_GRID` (uniform, held beyond)."""
    x = np.clip(np.asarray(survival, dtype=float), 0.0, 1.0) * (len(_SURVIVAL_GRID) - 1)
    x, row = np.broadcast_arrays(x, row)
    i = np.minimum(x.astype(np.int64), len(_SURVIVAL_GRID) - 2)
    w = x - i
    return (1.0 - w) * table[row, i] + w * table[row, i + 1]


def _rayleigh_scale(mean_survival: np.ndarray, survival: np.ndarray) -> np.ndarray:
    """Scale ``c`` of the true match's distance at which the sites' mean survival (``mean_survival``
    on :data:`_SCALE_GRID`, decreasing) is ``survival`` (interpolated in log c)."""
    s = np.clip(survival, mean_survival[-1], mean_survival[0])
    return np.exp(np.interp(-s, -mean_survival, np.log(_SCALE_GRID)))


def footprint_level(footprint_m_per_px: float) -> float:
    """The footprint quantised to :data:`FOOTPRINT_STEP_OCTAVES` of an octave (nearest in log), m/px."""
    fp = float(footprint_m_per_px)
    if not fp > 0:
        raise ValueError(f"footprint_m_per_px must be > 0, got {footprint_m_per_px!r}")
    step = FOOTPRINT_STEP_OCTAVES
    return float(2.0 ** (step * round(np.log2(fp) / step)))


def _atlas_albedo(target: Target) -> np.ndarray:
    """The atlas times each texel's material albedo (texels no triangle covers keep the atlas value)."""
    import cv2

    def compute() -> np.ndarray:
        H, W = target.texture.shape
        mat = np.full((H, W), -1, dtype=np.int32)
        pts = np.round(target.triangle_uv).astype(np.int32)
        for m in np.unique(target.triangle_material):
            lay = np.zeros((H, W), dtype=np.uint8)
            cv2.fillPoly(lay, list(pts[target.triangle_material == m]), 1)
            mat[lay > 0] = m
        albedo = np.array([m.albedo for m in target.materials], dtype=np.float32)
        return np.where(mat >= 0, target.texture * albedo[np.maximum(mat, 0)], target.texture)

    return target._cached("texture_sites_albedo_atlas", compute)


def texture_image(target: Target, footprint_m_per_px: float) -> tuple[np.ndarray, float]:
    """The albedo atlas resampled to ``footprint_m_per_px`` as an 8-bit image, and the scale
    (resampled px per atlas texel)."""
    import cv2

    scale = float(target.texel_m) / float(footprint_m_per_px)
    atlas = _atlas_albedo(target)
    img = cv2.resize(atlas, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR)
    return np.clip(np.round(img * _GREY_FULL), 0, 255).astype(np.uint8), scale


def _containing_triangles(target: Target, xy_tx: np.ndarray, bucket_tx: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (point, triangle) pair whose texture triangle contains atlas point ``xy_tx (K, 2)`` (texels):
    point indices, triangle ids and barycentric ``(b1, b2)`` (Open3D's convention)."""
    uv = target.triangle_uv.astype(float)                                  # (F, 3, 2)
    lo = np.floor(uv.min(axis=1) / bucket_tx).astype(np.int64)
    hi = np.floor(uv.max(axis=1) / bucket_tx).astype(np.int64)
    nb = hi - lo + 1
    n_cols = int(max(hi[:, 0].max(), np.floor(xy_tx[:, 0].max() / bucket_tx) if len(xy_tx) else 0)) + 2
    # (triangle, bucket) pairs
    count = nb[:, 0] * nb[:, 1]
    tri = np.repeat(np.arange(len(uv)), count)
    k = np.arange(len(tri)) - np.repeat(np.cumsum(count) - count, count)
    bx = lo[tri, 0] + k % nb[tri, 0]
    by = lo[tri, 1] + k // nb[tri, 0]
    tb = by * n_cols + bx
    # points sorted by bucket
    pb = (np.floor(xy_tx[:, 1] / bucket_tx).astype(np.int64) * n_cols
          + np.floor(xy_tx[:, 0] / bucket_tx).astype(np.int64))
    order = np.argsort(pb, kind="stable")
    start = np.searchsorted(pb[order], tb, side="left")
    stop = np.searchsorted(pb[order], tb, side="right")
    m = stop - start
    tri_p = np.repeat(tri, m)
    j = np.arange(int(m.sum())) - np.repeat(np.cumsum(m) - m, m)
    pt = order[np.repeat(start, m) + j]
    # barycentric test
    t0, t1, t2 = uv[tri_p, 0], uv[tri_p, 1], uv[tri_p, 2]
    a, b = t1 - t0, t2 - t0
    d = xy_tx[pt] - t0
    det = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    ok = np.abs(det) > 1e-12
    with np.errstate(invalid="ignore", divide="ignore"):
        b1 = (d[:, 0] * b[:, 1] - d[:, 1] * b[:, 0]) / det
        b2 = (a[:, 0] * d[:, 1] - a[:, 1] * d[:, 0]) / det
    eps = 1e-9
    inside = ok & (b1 >= -eps) & (b2 >= -eps) & (b1 + b2 <= 1 + eps)
    return pt[inside], tri_p[inside], np.stack([b1[inside], b2[inside]], axis=1)


def outer_area_by_material_m2(target: Target) -> np.ndarray:
    """Outer surface area of each material ``(P,)``, m² (area-uniform points tested with
    :func:`vision.outer_surface.outer_mask`; seeded from ``target.seed``, computed once per target)."""
    from vision.outer_surface import outer_mask

    def compute() -> np.ndarray:
        rng = np.random.default_rng(np.random.SeedSequence([target.seed, 0x0A7E4]))
        area = target.triangle_areas_m2
        tid = rng.choice(len(area), size=_AREA_SAMPLES, p=area / area.sum())
        r = rng.random((_AREA_SAMPLES, 2))
        r = np.where(r.sum(axis=1, keepdims=True) > 1.0, 1.0 - r, r)
        outer = outer_mask(target, target.point_on_triangles(tid, r), target.triangle_normals_T[tid])
        mat = target.triangle_material[tid[outer]]
        return float(area.sum()) / _AREA_SAMPLES * np.bincount(mat, minlength=len(target.materials)).astype(float)

    return target._cached("outer_area_by_material_m2", compute)


def texture_sites(target: Target, footprint_m_per_px: float) -> TextureSites:
    """The keypoint sites of ``target`` at the footprint level of ``footprint_m_per_px`` (module
    docstring; cached on the target per level)."""
    level = footprint_level(footprint_m_per_px)
    return target._cached(f"texture_sites_{level:.6g}", lambda: _compute_sites(target, level))


def _compute_sites(target: Target, footprint_m_per_px: float) -> TextureSites:
    from vision.features import detect
    from vision.outer_surface import outer_mask, outer_surface_area_m2

    img, scale = texture_image(target, footprint_m_per_px)
    kp = detect(img, detector="sift", options={"contrastThreshold": SITE_CONTRAST_THRESHOLD})
    xy_tx = (kp.uv_px + 0.5) / scale - 0.5                                  # atlas texels, centres at integers
    pt, tid, bary = _containing_triangles(target, xy_tx, _BUCKET_PX / scale)
    X = target.point_on_triangles(tid, bary)
    nrm = target.triangle_normals_T[tid]
    outer = outer_mask(target, X, nrm) if len(X) else np.zeros(0, dtype=bool)
    pt, tid, X, nrm = pt[outer], tid[outer], X[outer], nrm[outer]
    size_m = kp.size_px[pt] * float(footprint_m_per_px)
    flat = _flat_support(target, X, nrm, SUPPORT_RADIUS_OVER_SIZE * size_m) if len(X) else np.zeros(0, dtype=bool)
    pt, tid, X, nrm, size_m = pt[flat], tid[flat], X[flat], nrm[flat], size_m[flat]
    used = np.unique(pt)                                                  # keypoints some site keeps
    gap = np.full(len(kp), 2.0)
    gap[used] = _descriptor_gap(kp.subset(used))
    gap = gap[pt]
    response = kp.response[pt]
    mat = target.triangle_material[tid]
    area_m = outer_area_by_material_m2(target)
    count_m = np.bincount(mat, minlength=len(target.materials)).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        dens_m = np.where(area_m > 0, count_m / area_m, 0.0)
    rank = np.empty(len(pt))
    for m in np.unique(mat):
        sel = np.flatnonzero(mat == m)
        order = sel[np.argsort(-response[sel], kind="stable")]
        rank[order] = (np.arange(len(sel)) + 0.5) / len(sel)
    return TextureSites(X, nrm, tid, size_m, response, rank, mat, dens_m[mat], gap, float(footprint_m_per_px),
                        outer_surface_area_m2(target), len(target.materials))


def _flat_support(target: Target, X_T: np.ndarray, normal_T: np.ndarray, radius_m: np.ndarray,
                  k: int = 8) -> np.ndarray:
    """``(N,)`` bool: sites with the target's surface present, unoccluded and within
    :data:`SUPPORT_MAX_TILT_DEG` of their normal at ``k`` points ``radius_m`` around them (on either
    side of the surface), probed by rays cast along the normal.

    A keypoint needs its neighbourhood on one flat face: the atlas chart of a thin strip (a solar
    panel's 25 mm edge), of a thin cylinder (a yoke) or a texture detail against a face's border
    holds SIFT keypoints of the texture that no image of the 3-D surface shows.
    """
    import open3d as o3d

    X = np.asarray(X_T, dtype=float)
    n = np.asarray(normal_T, dtype=float)
    r = np.asarray(radius_m, dtype=float)
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    a = np.cross(n, helper)
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(n, a)
    phi = 2.0 * np.pi * np.arange(k) / k
    P = X[:, None, :] + r[:, None, None] * (np.cos(phi)[None, :, None] * a[:, None, :]
                                            + np.sin(phi)[None, :, None] * b[:, None, :])   # (N, k, 3)
    eps = np.maximum(r, 1e-3)[:, None, None]
    cos_max = np.cos(np.radians(SUPPORT_MAX_TILT_DEG))
    ok = np.zeros(len(X), dtype=bool)
    for sign in (1.0, -1.0):
        origin = P + sign * eps * n[:, None, :]
        direction = np.broadcast_to(-sign * n[:, None, :], P.shape)
        rays = np.concatenate([origin, direction], axis=-1).reshape(-1, 6).astype(np.float32)
        hit = target.scene.cast_rays(o3d.core.Tensor(rays))
        t = hit["t_hit"].numpy().reshape(len(X), k)
        pid = hit["primitive_ids"].numpy().reshape(len(X), k).astype(np.int64)
        valid = np.isfinite(t) & (pid < target.n_triangles)
        nh = target.triangle_normals_T[np.where(valid, pid, 0)]
        good = valid & (np.abs(t - eps[:, :, 0]) < 0.5 * eps[:, :, 0]) & (np.abs(np.sum(nh * n[:, None, :], axis=-1)) >= cos_max)
        ok |= good.all(axis=1)
    return ok


def _descriptor_gap(kp, k: int = 8) -> np.ndarray:
    """Per keypoint: distance to the nearest descriptor of a keypoint farther than its own diameter
    (the same blob at another orientation or scale does not count), among its ``k`` approximate
    nearest neighbours (OpenCV FLANN, 4 kd-trees, 128 checks: deterministic); 2.0, the largest
    distance of unit descriptors, where none of them qualifies."""
    import cv2

    n = len(kp)
    out = np.full(n, 2.0)
    if n < 2:
        return out
    desc = np.ascontiguousarray(kp.descriptors, dtype=np.float32)
    cv2.setRNGSeed(0)
    flann = cv2.FlannBasedMatcher({"algorithm": 1, "trees": 4}, {"checks": 128})
    for i, row in enumerate(flann.knnMatch(desc, desc, k=min(k + 1, n))):
        for m in row:
            if np.hypot(*(kp.uv_px[m.trainIdx] - kp.uv_px[i])) > max(float(kp.size_px[i]), 1.0):
                out[i] = m.distance
                break
    return out


def site_features(target: Target, footprint_m_per_px: float, *, fillers=None, descriptor_dim: int = 128,
                  rng: np.random.Generator | int | None = None):
    """The sites at this footprint as :class:`vision.geometric.SurfaceFeatures` for the calibrated
    mode: the sites first (``sites`` set; ``scale_m`` each site's diameter), then the features of
    ``fillers`` that have a flat neighbourhood of the sites' median diameter (uniform features that
    carry a bin's measured density beyond its material's sites,
    :func:`vision.geometric_calibrated.filler_feature_count`; ``area_m2`` the flat outer area they
    stand for).  ``rng`` draws the sites' unit
    descriptors (None: a stream derived from ``target.seed`` and the footprint level, so a target's
    sites always have the same descriptors)."""
    from vision.geometric import SurfaceFeatures

    sites = texture_sites(target, footprint_m_per_px)
    if rng is None:
        rng = np.random.SeedSequence([target.seed, 0x517E, int(round(1e6 * sites.footprint_m_per_px))])
    rng = np.random.default_rng(rng)
    desc = rng.standard_normal((len(sites), int(descriptor_dim))).astype(np.float32)
    desc /= np.linalg.norm(desc, axis=1, keepdims=True)
    parts = [(sites.X_T, sites.normal_T, sites.size_m, desc, sites.triangle_id)]
    area_m2 = sites.area_m2
    if fillers is not None and len(fillers):
        # fillers too need a flat neighbourhood of a keypoint's size (the sites' median diameter); their
        # density is that of the flat outer surface they are left on
        flat = _flat_support(target, fillers.X_T, fillers.normal_T,
                             np.full(len(fillers), SUPPORT_RADIUS_OVER_SIZE * float(np.median(sites.size_m))))
        parts.append((fillers.X_T[flat], fillers.normal_T[flat], fillers.scale_m[flat], fillers.descriptors[flat],
                      fillers.triangle_id[flat]))
        area_m2 = sites.area_m2 * float(np.mean(flat))
    X, nrm, size, d, tid = (np.concatenate(p) for p in zip(*parts, strict=True))
    return SurfaceFeatures(X, nrm, size, d, tid, area_m2, sites=sites)
