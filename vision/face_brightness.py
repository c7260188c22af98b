"""A surface's brightness in an image relative to the camera's auto-exposure (issue 16).

The rendered mode's camera sets its exposure per image (:class:`vision.sensor.SensorModel`: the
99th percentile of the target's radiance at 80 % of the full well), so how bright a face comes out
depends on the rest of the target in the same image: a solar wing lit at grazing incidence is
well exposed when it is all the camera sees and almost black beside a bus lit face-on.  SIFT finds
few keypoints on faces a few digital numbers above the noise, so the detection density of a face
depends on that relative brightness, not only on its own Sun incidence.

Both the calibration (:mod:`experiments.studies.rendered_calibration`, per pixel of the rendered
images) and the calibrated geometric mode (:mod:`vision.geometric_calibrated`, per feature) use the
same texture-free model, so the factor measured by one applies to the other:

- the *face radiance* of a surface point seen from its camera-facing side is the renderer's
  Lambert and Blinn–Phong terms with the material's mean albedo, specular weight and shininess
  (:func:`face_radiance`), zero where the point is not lit;
- the image's *reference radiance* is the :data:`EXPOSURE_PERCENTILE` percentile, over the visible
  target surface weighted by its area in pixels, of the face radiance ignoring cast shadows
  (:func:`reference_radiance`);
- the *relative brightness* ``b`` of a point is its face radiance (with its own shadow) over the
  reference, binned by :data:`BRIGHTNESS_EDGES` (bin 0: not lit).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from vision.calibration.tables import bin_index
from vision.sensor import SensorModel

__all__ = ["BRIGHTNESS_EDGES", "EXPOSURE_PERCENTILE", "brightness_bin", "entry_brightness", "exposure_sample", "face_radiance",
           "material_optics", "reference_radiance", "sample_references"]

#: relative brightness bins: bin 0 holds the points that are not lit (b = 0), then steps of √2 from
#: 0.1 to 0.8 (on FY-1's solar wings b = 0.1–0.2 is about 7–15 digital numbers of 255, where the
#: rendered images' keypoints thin out)
BRIGHTNESS_EDGES = np.array([0.0, 1e-12, 0.1, 0.14, 0.2, 0.28, 0.4, 0.56, 0.8, np.inf])
#: percentile of the radiance the renderer's default auto-exposure places at its level
EXPOSURE_PERCENTILE = float(SensorModel().auto_exposure_percentile)
#: area-uniform points of the outer surface used to find an image's reference radiance in the
#: geometric mode (drawn once per target from its seed)
EXPOSURE_SAMPLE_POINTS = 4000


def material_optics(target) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean albedo, specular weight and shininess of each of the target's materials, ``(P,)`` each."""
    m = target.materials
    return (np.array([x.albedo for x in m], dtype=float), np.array([x.specular for x in m], dtype=float),
            np.array([x.shininess for x in m], dtype=float))


def face_radiance(material: ArrayLike, cos_sun: ArrayLike, n_dot_h: ArrayLike, lit: ArrayLike,
                  optics: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """Texture-free radiance (the renderer's units: 1 is a white Lambertian face under the full Sun)
    of surface points of these materials: ``albedo · cos_sun + specular · max(n·h, 0)^shininess``
    where ``lit``, 0 elsewhere; ``cos_sun`` and ``n_dot_h`` on the camera-facing side (``h`` the
    half vector between the Sun and the camera)."""
    albedo, ks, ns = optics
    m = np.asarray(material, dtype=np.int64)
    L = albedo[m] * np.maximum(cos_sun, 0.0) + ks[m] * _power(n_dot_h, ns[m])
    return np.where(np.asarray(lit, dtype=bool), L, 0.0)


def _power(x: np.ndarray, exponent: np.ndarray) -> np.ndarray:
    """``max(x, 0) ** exponent`` (exponent > 0) as ``exp(exponent · log x)``: several times faster than
    ``**`` with an array of exponents, equal to a few units in the last place."""
    with np.errstate(divide="ignore"):
        return np.exp(exponent * np.log(np.maximum(x, 0.0)))


def reference_radiance(radiance: ArrayLike, weight: ArrayLike | None = None, axis: int = -1) -> np.ndarray:
    """The :data:`EXPOSURE_PERCENTILE` percentile of the positive ``radiance`` along ``axis``, each
    value weighted by ``weight`` (pixels of area; None: one each), by the inverted weighted CDF;
    NaN where nothing is positive.

    The values are ordered by integer keys that pack each value's float32 bits (ordered as integers
    for non-negative floats) above its index; only the brightest eighth is sorted where it holds
    the weight above the percentile (it runs for every trial of a calibrated sweep)."""
    L = np.moveaxis(np.asarray(radiance, dtype=float), axis, -1)
    w = np.ones_like(L) if weight is None else np.moveaxis(np.broadcast_to(weight, np.shape(radiance)), axis, -1)
    shape, M = L.shape[:-1], L.shape[-1]
    L = np.maximum(L.reshape(-1, M), 0.0)
    w = np.where(L > 0, w.reshape(-1, M), 0.0)
    total = w.sum(axis=1)
    above = (1.0 - EXPOSURE_PERCENTILE / 100.0) * total                  # the weight above the percentile
    shift = max(1, (M - 1).bit_length())
    key = (L.astype(np.float32).view(np.int32).astype(np.int64) << shift) | np.arange(M)
    k = min(M, max(64, M // 8))
    top = np.sort(np.partition(key, M - k, axis=1)[:, M - k:] if k < M else key, axis=1)[:, ::-1]
    idx = top & ((1 << shift) - 1)                                        # brightest first
    cw = np.cumsum(np.take_along_axis(w, idx, 1), axis=1)
    short = cw[:, -1] <= above                                            # the percentile is below the top k
    rows = np.arange(len(L))
    # the smallest value whose weight at or above it exceeds `above` (the inverted CDF at the percentile)
    i = np.minimum(np.sum(cw <= above[:, None], axis=1), idx.shape[1] - 1)
    ref = L[rows, idx[rows, i]]
    if short.any():                                                       # sort those rows in full
        r = np.flatnonzero(short)
        full = (np.sort(key[r], axis=1) & ((1 << shift) - 1))[:, ::-1]
        cwf = np.cumsum(np.take_along_axis(w[r], full, 1), axis=1)
        j = np.minimum(np.sum(cwf <= above[r, None], axis=1), M - 1)
        ref[r] = L[r, full[np.arange(len(r)), j]]
    return np.where(total > 0, ref, np.nan).reshape(shape)


def brightness_bin(b: ArrayLike) -> np.ndarray:
    """Index of the bin of :data:`BRIGHTNESS_EDGES` of relative brightness ``b`` (NaN: bin 0), by the
    calibration's own binning (one comparison per edge: this runs on every detection candidate)."""
    b = np.nan_to_num(np.asarray(b, dtype=float), nan=0.0)
    return bin_index(BRIGHTNESS_EDGES, b, "right", 0, len(BRIGHTNESS_EDGES) - 2)


def exposure_sample(target):
    """The target's fixed area-uniform sample of its outer surface (:data:`EXPOSURE_SAMPLE_POINTS`,
    cached on the target)."""
    from vision.geometric import surface_features

    return target._cached("exposure_sample", lambda: surface_features(
        target, n_features=EXPOSURE_SAMPLE_POINTS, descriptor_dim=1, surface="outer",
        rng=np.random.SeedSequence([target.seed, 0xE7905])))


def sample_references(R_CT: np.ndarray, c_T: np.ndarray, s_T: np.ndarray, f_px: np.ndarray, target) -> np.ndarray:
    """Reference radiance ``(E, n)`` of each camera's image from the target's exposure sample: the
    sample points in front of a camera and not hidden by the target (tabulated per direction), weighted
    by their area in pixels, with the face radiance ignoring cast shadows.  ``R_CT (E, n, 3, 3)``,
    ``c_T (E, n, 3)`` the cameras in the body frame, ``s_T (E, 3)`` the Sun, ``f_px (n,)``.

    Every per-point quantity is a dot product, so the arrays are ``(E·n, M)`` matrix products
    (no ``(E, n, M, 3)`` intermediates): this runs for every trial of a calibrated sweep."""
    P = _sample_optics(target)
    X, nrm = P["X"], P["normal"]                                          # float32: enough for a percentile
    E, n = c_T.shape[:2]
    c = c_T.reshape(-1, 3).astype(np.float32)                             # (K, 3), K = E n
    s = np.repeat(s_T, n, axis=0).astype(np.float32)                      # (K, 3)
    dist = np.sqrt(np.maximum(np.sum(c * c, 1)[:, None] - 2.0 * (c @ X.T) + P["X2"], 1e-12))
    cos_v = (c @ nrm.T - P["Xn"]) / dist                                  # signed: normal · direction to the camera
    abs_v = np.abs(cos_v)
    sn = s @ nrm.T
    cos_s = np.where(cos_v >= 0, sn, -sn)                                 # Sun on the camera-facing side
    v_dot_s = (np.sum(c * s, 1)[:, None] - s @ X.T) / dist
    n_dot_h = (abs_v + cos_s) / np.sqrt(np.maximum(2.0 + 2.0 * v_dot_s, 1e-12))
    r3 = R_CT[:, :, 2, :].reshape(-1, 3).astype(np.float32)
    z = r3 @ X.T - np.sum(r3 * c, 1)[:, None]                             # depth along the optical axis
    L = P["albedo"] * cos_s + P["specular"] * _power(n_dot_h, P["shininess"])
    L = np.where((cos_s > 0) & (z > 0), L, 0.0)
    f = np.repeat(np.asarray(f_px, dtype=np.float32)[None], E, axis=0).reshape(-1, 1)
    area_px = P["area_m2"] * abs_v * (f / np.maximum(z, 1e-6)) ** 2
    # the points the target hides from the camera: the table of the direction nearest the camera's
    area_px *= P["visible"][np.argmax(c @ P["directions"].T, axis=1)]
    return reference_radiance(L, area_px).reshape(E, n)


def _optics(target) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return target._cached("material_optics", lambda: material_optics(target))


#: directions (spread evenly over the sphere, about 6.4° apart) at which the exposure sample's
#: occlusion is tabulated once per target; a camera takes the table of the one nearest its own
#: direction from the target's centre
OCCLUSION_DIRECTIONS = 1000


def _fibonacci_directions(n: int) -> np.ndarray:
    """``n`` unit vectors spread evenly over the sphere (the Fibonacci lattice), ``(n, 3)``."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (3.0 - np.sqrt(5.0)) * i
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _visible_from(target, X: np.ndarray, normal: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """``(G, M)`` float32: 1 where point ``m`` is not hidden by the target towards direction ``g``
    (a ray from its side facing that way, ray casting), 0 where hidden."""
    import open3d as o3d

    eps = max(1e-3, 1e-4 * target.radius_m)
    out = np.empty((len(directions), len(X)), dtype=np.float32)
    for g0 in range(0, len(directions), 100):
        d = directions[g0:g0 + 100]                                       # (g, 3)
        side = np.where(d @ normal.T >= 0, 1.0, -1.0)                     # (g, M)
        org = X[None] + eps * side[..., None] * normal[None]
        rays = np.concatenate([org, np.broadcast_to(d[:, None], org.shape)], axis=-1).reshape(-1, 6)
        hit = target.scene.test_occlusions(o3d.core.Tensor(rays.astype(np.float32))).numpy()
        out[g0:g0 + 100] = ~hit.reshape(len(d), len(X)).astype(bool)
    return out


def _sample_optics(target) -> dict:
    """The exposure sample's points, normals and the constants :func:`sample_references` needs per point
    (the same :func:`face_radiance` terms, laid out per point; cached on the target)."""
    def make() -> dict:
        S = exposure_sample(target)
        albedo, ks, ns = _optics(target)
        m = target.triangle_material[S.triangle_id]
        f32 = np.float32
        D = _fibonacci_directions(OCCLUSION_DIRECTIONS)
        return {"directions": D.astype(f32), "visible": _visible_from(target, S.X_T, S.normal_T, D),
                "X": S.X_T.astype(f32), "normal": S.normal_T.astype(f32),
                "X2": np.sum(S.X_T**2, 1)[None].astype(f32), "Xn": np.sum(S.X_T * S.normal_T, 1)[None].astype(f32),
                "albedo": albedo[m][None].astype(f32), "specular": ks[m][None].astype(f32),
                "shininess": ns[m][None].astype(f32), "area_m2": f32(S.area_m2 / len(S.X_T))}

    return target._cached("exposure_sample_optics", make)


def entry_brightness(g, target, feats, s_T: np.ndarray, f_px: np.ndarray, at: np.ndarray, e_i: np.ndarray,
                     f_i: np.ndarray, cos_sun: np.ndarray) -> np.ndarray:
    """Relative brightness, if lit, of the geometric mode's (epoch, camera, feature) entries at the
    flat indices ``at`` of ``g.vis`` (``vision.geometric._Geometry``; ``e_i``, ``f_i`` their epochs
    and features, ``cos_sun`` the Sun's incidence on their camera-facing side): their face radiance
    over their image's :func:`sample_references`.

    The half vector's cosine comes from dot products the geometry already has: ``n·v`` (its
    ``cos_view``), ``n·s`` and ``v·s = (c·s − X·s) / |c − X|``, the distance from the depth and the
    pixel's ray, so no per-entry vectors are formed."""
    ref = sample_references(g.R_CT, g.c_T, s_T, f_px, target).reshape(-1)       # (E n,)
    E, n, N = g.vis.shape
    en_i = at // N
    cam = en_i % n
    uv = g.uv.reshape(-1, 2)[at]
    x = (uv[:, 0] - g.K[cam, 0, 2]) / g.K[cam, 0, 0]
    y = (uv[:, 1] - g.K[cam, 1, 2]) / g.K[cam, 1, 1]
    dist = np.take(g.z, at) * np.sqrt(1.0 + x * x + y * y)
    c_dot_s = np.einsum("eni,ei->en", g.c_T, s_T).reshape(-1)[en_i]
    X_dot_s = np.take(s_T @ feats.X_T.T, e_i * N + f_i)
    v_dot_s = (c_dot_s - X_dot_s) / dist
    n_dot_h = (np.abs(np.take(g.cos_view, at)) + cos_sun) / np.sqrt(np.maximum(2.0 + 2.0 * v_dot_s, 1e-12))
    L = face_radiance(target.triangle_material[feats.triangle_id[f_i]], cos_sun, n_dot_h, cos_sun > 0,
                      _optics(target))
    with np.errstate(invalid="ignore", divide="ignore"):
        return L / np.take(ref, en_i)
