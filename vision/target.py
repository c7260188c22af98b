"""Target models: the procedural FY-1-like satellite and meshes loaded from files.

A :class:`Target` is a triangle mesh in the target body frame T (metres, origin at the centre of mass
assumed at the reference point chosen at construction), with

- a texture atlas: one grey-level albedo image holding every surface's texture, looked up through
  per-triangle-corner texture coordinates (in atlas texels);
- a material per triangle: a reflectance scale and a specular (Blinn–Phong) term.

Procedural textures imitate what a feature detector finds on a real spacecraft: multi-layer
insulation (MLI) with wrinkles, creases, tape seams and labels; solar-cell grids with per-cell
reflectance scatter, string gaps and interconnects; painted panel backs with ribs, harness and
stains. Every chart (box face, cylinder side) gets its own region of the atlas, so no texture patch
repeats on the target (repeats cause false matches).

FY-1-like dimensions (:func:`fy1_target`) and their sources:

- bus: 1.42 × 1.42 × 1.20 m hexahedron — FY-1C as described by NSMC/CMA (Liu, Zhang, Yang,
  "FY-1C polar orbiting meteorological satellite of China", geospatialworld.net: "a hexahedron of
  1.42 m × 1.42 m × 1.2 m ... with three solar cell arrays, the total length of the satellite is
  10.556 m");
- wings: two wings of three 1.17 m panels, 3.51 m of cells per wing ("two solar arrays about 3.5 m
  long each", FAS / Encyclopedia Astronautica for FY-1A/B), with 2 cm hinge gaps, on a 1.018 m yoke
  so that the tip-to-tip span is the published 10.556 m. Panel width 1.20 m and thickness 0.025 m
  are assumptions (not published);
- antennas and instruments: two 0.8 m whip antennas, a 0.3 m helix can and a scanner-radiometer box
  with a radiant-cooler box on the Earth face — sizes are illustrative, not from drawings.

Body axes of the FY-1-like model: +z the Earth-facing (instrument) face, ±y along the wings,
+x completes the right-handed frame; the cell side of the wings faces +x.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "Material",
    "Target",
    "fy1_target",
    "load_mesh",
    "procedural_texture",
    "TEXTURE_KINDS",
]

TEXTURE_KINDS = ("mli", "solar_cells", "panel_back", "structure", "radiator")

_MIP_LEVELS = 5          # levels 0..4 of the texture pyramid (1×..16× texel)
_CHART_PAD = 2 ** _MIP_LEVELS  # texels of reflected padding around each chart in the atlas


@dataclass(frozen=True)
class Material:
    """Reflectance of one surface type.

    Attributes
    ----------
    name : str
        Human-readable name (``"MLI gold"``).
    kind : str
        Procedural texture family, one of :data:`TEXTURE_KINDS`.
    albedo : float
        Diffuse reflectance scale in [0, 1]; the texture value (in [0, 1]) multiplies it.
    specular : float
        Blinn–Phong specular coefficient (0 = purely Lambertian).
    shininess : float
        Blinn–Phong exponent.
    """

    name: str
    kind: str
    albedo: float
    specular: float = 0.0
    shininess: float = 20.0

    def __post_init__(self) -> None:
        if self.kind not in TEXTURE_KINDS:
            raise ValueError(f"kind must be one of {TEXTURE_KINDS}, got {self.kind!r}")
        if not 0.0 <= float(self.albedo) <= 1.0:
            raise ValueError(f"albedo must be in [0, 1], got {self.albedo!r}")
        if float(self.specular) < 0.0 or float(self.shininess) <= 0.0:
            raise ValueError(f"specular must be >= 0 and shininess > 0, got {self.specular!r}, "
                             f"{self.shininess!r}")


@dataclass(frozen=True, eq=False)
class Target:
    """A textured triangle mesh in the target body frame T.

    Attributes
    ----------
    name : str
        Model name.
    vertices_T : ndarray, shape (V, 3)
        Vertex positions, body frame, metres.
    triangles : ndarray, shape (F, 3), int32
        Vertex indices of each triangle.
    triangle_uv : ndarray, shape (F, 3, 2), float32
        Texture coordinates of each triangle corner in atlas texels (x = column, y = row; texel
        centres at integers).
    triangle_material : ndarray, shape (F,), int32
        Index into ``materials`` of each triangle.
    materials : tuple of Material
        Surface reflectances.
    texture : ndarray, shape (Ht, Wt), float32
        Albedo atlas, values in [0, 1]. ``Ht`` and ``Wt`` are multiples of 2**(levels-1).
    texel_m : float
        Nominal texel size of procedural textures, metres.
    seed : int
        Seed the textures (and the geometric mode's surface features) are derived from.
    description : str
        Dimensions and their sources.
    """

    name: str
    vertices_T: np.ndarray
    triangles: np.ndarray
    triangle_uv: np.ndarray
    triangle_material: np.ndarray
    materials: tuple[Material, ...]
    texture: np.ndarray
    texel_m: float
    seed: int = 0
    description: str = ""
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        V = np.asarray(self.vertices_T, dtype=float)
        F = np.asarray(self.triangles, dtype=np.int32)
        if V.ndim != 2 or V.shape[1] != 3 or len(V) < 3 or not np.all(np.isfinite(V)):
            raise ValueError(f"vertices_T must be finite with shape (V>=3, 3), got {V.shape}")
        if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0 or F.min() < 0 or F.max() >= len(V):
            raise ValueError(f"triangles must be (F, 3) indices into vertices_T, got shape {F.shape}")
        uv = np.asarray(self.triangle_uv, dtype=np.float32)
        if uv.shape != (len(F), 3, 2):
            raise ValueError(f"triangle_uv must have shape ({len(F)}, 3, 2), got {uv.shape}")
        mat = np.asarray(self.triangle_material, dtype=np.int32)
        if mat.shape != (len(F),) or mat.min() < 0 or mat.max() >= len(self.materials):
            raise ValueError("triangle_material must be (F,) indices into materials")
        tex = np.asarray(self.texture, dtype=np.float32)
        step = 2 ** (_MIP_LEVELS - 1)
        if tex.ndim != 2 or tex.shape[0] % step or tex.shape[1] % step:
            raise ValueError(f"texture must be 2-D with sides multiple of {step}, got {tex.shape}")
        if not float(self.texel_m) > 0:
            raise ValueError(f"texel_m must be > 0, got {self.texel_m!r}")
        object.__setattr__(self, "vertices_T", V)
        object.__setattr__(self, "triangles", F)
        object.__setattr__(self, "triangle_uv", uv)
        object.__setattr__(self, "triangle_material", mat)
        object.__setattr__(self, "materials", tuple(self.materials))
        object.__setattr__(self, "texture", tex)
        object.__setattr__(self, "texel_m", float(self.texel_m))
        object.__setattr__(self, "seed", int(self.seed))

    # The Open3D scene cannot be pickled (Dask ships targets to workers): drop the cache.
    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_cache"] = {}
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)

    # --- derived geometry (cached) -----------------------------------------------------------

    @property
    def n_triangles(self) -> int:
        return int(len(self.triangles))

    def _cached(self, key: str, fn):
        if key not in self._cache:
            self._cache[key] = fn()
        return self._cache[key]

    @property
    def triangle_normals_T(self) -> np.ndarray:
        """Unit triangle normals ``(F, 3)`` from the winding (right-hand rule), body frame."""
        def fn():
            p = self.vertices_T[self.triangles]
            n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
            return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        return self._cached("normals", fn)

    @property
    def triangle_areas_m2(self) -> np.ndarray:
        """Triangle areas ``(F,)``, m²."""
        def fn():
            p = self.vertices_T[self.triangles]
            return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        return self._cached("areas", fn)

    @property
    def bbox_T(self) -> np.ndarray:
        """Axis-aligned bounding box in the body frame, ``[[xmin, ymin, zmin], [xmax, ymax, zmax]]``."""
        return np.stack([self.vertices_T.min(axis=0), self.vertices_T.max(axis=0)])

    @property
    def bbox_corners_T(self) -> np.ndarray:
        """The 8 corners ``(8, 3)`` of :attr:`bbox_T`."""
        lo, hi = self.bbox_T
        idx = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
        return np.where(idx == 0, lo, hi)

    @property
    def radius_m(self) -> float:
        """Radius of the sphere about the body origin that encloses the mesh, metres."""
        return float(np.linalg.norm(self.vertices_T, axis=1).max())

    @property
    def scene(self):
        """Open3D ``RaycastingScene`` of the mesh in the body frame (built once, cached)."""
        def fn():
            import open3d as o3d

            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(o3d.core.Tensor(self.vertices_T.astype(np.float32)),
                                o3d.core.Tensor(self.triangles.astype(np.uint32)))
            return scene
        return self._cached("scene", fn)

    @property
    def texture_pyramid(self) -> tuple[np.ndarray, ...]:
        """Mip-map levels of :attr:`texture` (level l is 2**l times coarser, box-filtered)."""
        def fn():
            import cv2

            levels = [self.texture]
            for _ in range(1, _MIP_LEVELS):
                t = levels[-1]
                levels.append(cv2.resize(t, (t.shape[1] // 2, t.shape[0] // 2),
                                         interpolation=cv2.INTER_AREA))
            return tuple(levels)
        return self._cached("pyramid", fn)

    def point_on_triangles(self, triangle_id: ArrayLike, bary_uv: ArrayLike) -> np.ndarray:
        """Body-frame points ``(..., 3)`` at barycentric ``(b1, b2)`` on triangles (Open3D's convention).

        The point is ``(1 - b1 - b2) p0 + b1 p1 + b2 p2``.
        """
        tid = np.asarray(triangle_id, dtype=np.int64)
        b = np.asarray(bary_uv, dtype=float)
        p = self.vertices_T[self.triangles[tid]]
        return ((1.0 - b[..., 0] - b[..., 1])[..., None] * p[..., 0, :] + b[..., 0, None] * p[..., 1, :]
                + b[..., 1, None] * p[..., 2, :])

    def texture_coords(self, triangle_id: ArrayLike, bary_uv: ArrayLike) -> np.ndarray:
        """Atlas texel coordinates ``(..., 2)`` at barycentric ``(b1, b2)`` on triangles."""
        tid = np.asarray(triangle_id, dtype=np.int64)
        b = np.asarray(bary_uv, dtype=np.float32)
        t = self.triangle_uv[tid]
        return ((1.0 - b[..., 0] - b[..., 1])[..., None] * t[..., 0, :] + b[..., 0, None] * t[..., 1, :]
                + b[..., 1, None] * t[..., 2, :])

    def sample_albedo(self, tex_xy: ArrayLike, level: ArrayLike, triangle_id: ArrayLike) -> np.ndarray:
        """Diffuse albedo at atlas coordinates ``tex_xy`` (``(N, 2)``) with mip ``level`` (``(N,)``).

        Trilinear filtering: bilinear in the two pyramid levels around ``level``, blended linearly.
        The result is the texture value times the triangle's material albedo.
        """

        xy = np.asarray(tex_xy, dtype=np.float32).reshape(-1, 2)
        lev = np.clip(np.asarray(level, dtype=np.float32).reshape(-1), 0.0, _MIP_LEVELS - 1.0)
        pyr = self.texture_pyramid
        out = np.zeros(len(xy), dtype=np.float32)
        lo = np.floor(lev).astype(np.int64)
        frac = lev - lo
        for l in np.unique(lo):
            sel = np.nonzero(lo == l)[0]
            acc = np.zeros(len(sel), dtype=np.float32)
            for ll, w in ((int(l), 1.0 - frac[sel]), (min(int(l) + 1, _MIP_LEVELS - 1), frac[sel])):
                scale = np.float32(0.5 ** ll)
                mx = (xy[sel, 0] + np.float32(0.5)) * scale - np.float32(0.5)
                my = (xy[sel, 1] + np.float32(0.5)) * scale - np.float32(0.5)
                acc += w * _remap_points(pyr[ll], mx, my)
            out[sel] = acc
        albedo = np.array([m.albedo for m in self.materials], dtype=np.float32)
        return out * albedo[self.triangle_material[np.asarray(triangle_id, dtype=np.int64).reshape(-1)]]


def _remap_points(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear samples of ``img`` at float32 points (OpenCV remap on a (rows, 1024) grid)."""
    import cv2

    n = len(x)
    if n == 0:
        return np.zeros(0, dtype=np.float32)
    cols = 1024
    rows = -(-n // cols)
    mx = np.zeros(rows * cols, dtype=np.float32)
    my = np.zeros(rows * cols, dtype=np.float32)
    mx[:n], my[:n] = x, y
    out = cv2.remap(img, mx.reshape(rows, cols), my.reshape(rows, cols),
                    interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out.reshape(-1)[:n]


# ----------------------------------------------------------------------------------------------
# procedural textures
# ----------------------------------------------------------------------------------------------


def _noise(rng: np.random.Generator, shape: tuple[int, int], sigma_tx: float) -> np.ndarray:
    """White noise low-passed with a Gaussian of ``sigma_tx`` texels, normalised to unit std.

    Wide kernels are applied on a coarser grid (at most 2 texels of sigma there) and resized up, so
    the cost does not grow with the kernel and the border reflection does not mirror the pattern.
    """
    import cv2

    h, w = shape
    if sigma_tx <= 0.3:
        n = rng.standard_normal(shape).astype(np.float32)
    else:
        f = max(1.0, sigma_tx / 2.0)
        m = 4  # margin cells on the coarse grid, cropped after resizing
        sh, sw = int(np.ceil(h / f)) + 2 * m, int(np.ceil(w / f)) + 2 * m
        n = rng.standard_normal((sh, sw)).astype(np.float32)
        n = cv2.GaussianBlur(n, (0, 0), sigmaX=float(sigma_tx / f), borderType=cv2.BORDER_REFLECT)
        if f > 1.0:
            n = cv2.resize(n, (int(round(sw * f)), int(round(sh * f))), interpolation=cv2.INTER_CUBIC)
        o = int(round(m * f)) if f > 1.0 else m
        n = np.ascontiguousarray(n[o:o + h, o:o + w])
    s = float(n.std())
    return n / s if s > 0 else n


def _fractal(rng, shape, texel_m, scales_m, amps) -> np.ndarray:
    out = np.zeros(shape, dtype=np.float32)
    for s, a in zip(scales_m, amps, strict=True):
        out += a * _noise(rng, shape, s / texel_m)
    return out


def _labels(rng, img: np.ndarray, texel_m: float, count: int) -> None:
    """Draw ``count`` label-like rectangles with random glyph blocks into ``img`` (in place)."""
    h, w = img.shape
    for _ in range(count):
        lw = int(rng.uniform(0.10, 0.28) / texel_m)
        lh = int(rng.uniform(0.06, 0.16) / texel_m)
        if lw >= w - 4 or lh >= h - 4 or lw < 6 or lh < 6:
            continue
        x0 = int(rng.integers(2, w - lw - 2))
        y0 = int(rng.integers(2, h - lh - 2))
        bg = rng.uniform(0.85, 1.0)
        img[y0:y0 + lh, x0:x0 + lw] = bg
        gw, gh = max(2, int(0.015 / texel_m)), max(2, int(0.025 / texel_m))
        for gy in range(y0 + 2, y0 + lh - gh - 1, gh + 1):
            for gx in range(x0 + 2, x0 + lw - gw - 1, gw + 1):
                if rng.random() < 0.55:
                    img[gy:gy + gh, gx:gx + gw] = rng.uniform(0.05, 0.3)


def _tex_mli(rng, shape, texel_m) -> np.ndarray:
    h, w = shape
    base = _fractal(rng, shape, texel_m, (0.008, 0.02, 0.05, 0.12, 0.3), (0.2, 0.3, 0.4, 0.4, 0.3))
    # wrinkles and creases: thin ridges along zero crossings of band-passed noise
    ridges = np.zeros(shape, dtype=np.float32)
    for s, a in ((0.03, 0.5), (0.07, 0.6), (0.15, 0.4)):
        n = _noise(rng, shape, s / texel_m)
        ridges += a * np.exp(-(n / 0.18) ** 2)
    img = 0.62 + 0.07 * base + 0.35 * (ridges - ridges.mean())
    # tape seams
    for axis, size in ((0, h), (1, w)):
        pos = rng.uniform(0.25, 0.6) / texel_m * rng.uniform(0.5, 1.0)
        width = max(2, int(0.025 / texel_m))
        step = max(int(rng.uniform(0.35, 0.7) / texel_m), 4 * width)
        p = int(pos) % step
        while p < size - width:
            if axis == 0:
                img[p:p + width, :] = 0.92 + 0.04 * _noise(rng, (width, w), 1.0)
            else:
                img[:, p:p + width] = 0.92 + 0.04 * _noise(rng, (h, width), 1.0)
            p += step
    _labels(rng, img, texel_m, count=int(rng.integers(1, 3)) * max(1, int(h * w * texel_m ** 2 / 0.8)))
    return np.clip(img, 0.03, 1.0)


def _tex_solar(rng, shape, texel_m) -> np.ndarray:
    h, w = shape
    cw, ch = max(3, round(0.04 / texel_m)), max(3, round(0.06 / texel_m))
    ny, nx = h // ch + 1, w // cw + 1
    # cell reflectance: per-module (6 x 10 cells) and per-cell scatter, a few odd cells
    mod = 0.2 * rng.standard_normal((ny // 10 + 1, nx // 6 + 1))
    cell = 0.5 + np.repeat(np.repeat(mod, 10, axis=0), 6, axis=1)[:ny, :nx] \
        + 0.15 * rng.standard_normal((ny, nx))
    u = rng.random((ny, nx))
    cell[u < 0.04] = rng.uniform(0.85, 1.0, int((u < 0.04).sum()))
    cell[(u >= 0.04) & (u < 0.07)] = 0.08
    cell = np.clip(cell, 0.05, 1.0).astype(np.float32)
    img = np.repeat(np.repeat(cell, ch, axis=0), cw, axis=1)[:h, :w].copy()
    img[::ch, :] = 0.08            # inter-cell gaps
    img[:, ::cw] = 0.08
    # strings: every 6 cells across, a wider gap with a bright interconnect beside it
    for x in range(0, w, 6 * cw):
        img[:, x:x + 2] = 0.05
        img[:, x + 2:x + 3] = 0.9
    for y in range(0, h, 10 * ch):
        img[y:y + 2, :] = 0.05
    img += 0.12 * _noise(rng, shape, 0.08 / texel_m) + 0.04 * _noise(rng, shape, 0.6)
    _labels(rng, img, texel_m, count=max(1, int(h * w * texel_m ** 2 / 0.4)))
    return np.clip(img, 0.02, 1.0)


def _tex_panel_back(rng, shape, texel_m) -> np.ndarray:
    h, w = shape
    img = 0.78 + 0.05 * _fractal(rng, shape, texel_m, (0.01, 0.05, 0.2), (0.5, 0.7, 0.6))
    rib = max(1, int(0.012 / texel_m))
    step = int(0.25 / texel_m)
    img[:, ::step] -= 0.25
    img[::step, :] -= 0.25
    for _ in range(rib - 1):
        img[:, 1::step] -= 0.2
        img[1::step, :] -= 0.2
    # harness cables: a few dark polylines; stains: soft dark blobs
    import cv2

    for _ in range(max(2, int(h * w * texel_m ** 2 / 0.3))):
        pts = np.stack([rng.uniform(0, w, 4), rng.uniform(0, h, 4)], axis=1).astype(np.int32)
        cv2.polylines(img, [pts], False, float(rng.uniform(0.1, 0.3)),
                      thickness=max(1, int(0.01 / texel_m)))
    stains = np.exp(-(np.maximum(_noise(rng, shape, 0.08 / texel_m) - 1.2, 0) * 3.0))
    img = img * (0.6 + 0.4 * stains)
    _labels(rng, img, texel_m, count=max(1, int(h * w * texel_m ** 2 / 1.0)))
    return np.clip(img, 0.03, 1.0)


def _tex_structure(rng, shape, texel_m) -> np.ndarray:
    h, w = shape
    img = 0.6 + 0.12 * _fractal(rng, shape, texel_m, (0.01, 0.04, 0.15), (0.4, 0.6, 0.5))
    step = max(3, int(0.06 / texel_m))
    yy, xx = np.mgrid[0:h, 0:w]
    bolts = ((xx % step == step // 2) & ((yy % step == step // 2) | (yy < 2) | (yy > h - 3)))
    img[bolts] = 0.15
    return np.clip(img, 0.03, 1.0)


def _tex_radiator(rng, shape, texel_m) -> np.ndarray:
    h, w = shape
    stripe = max(2, int(0.04 / texel_m))
    xx = np.arange(w)[None, :]
    img = np.where((xx // stripe) % 2 == 0, 0.9, 0.25).astype(np.float32) * np.ones((h, 1), np.float32)
    img += 0.06 * _fractal(rng, shape, texel_m, (0.01, 0.05), (0.6, 0.6))
    _labels(rng, img, texel_m, count=1)
    return np.clip(img, 0.03, 1.0)


_GENERATORS = {
    "mli": _tex_mli,
    "solar_cells": _tex_solar,
    "panel_back": _tex_panel_back,
    "structure": _tex_structure,
    "radiator": _tex_radiator,
}


def procedural_texture(kind: str, width_m: float, height_m: float, *, texel_m: float = 0.005,
                       rng: np.random.Generator | int | None = None) -> np.ndarray:
    """A procedural albedo texture of one surface patch.

    Parameters
    ----------
    kind : str
        One of :data:`TEXTURE_KINDS`.
    width_m, height_m : float
        Patch size, metres (texture columns along the width).
    texel_m : float, optional
        Texel size, metres.
    rng : Generator, int or None
        Random source.

    Returns
    -------
    ndarray, shape (ceil(height_m/texel_m), ceil(width_m/texel_m)), float32
        Texture values in [0, 1] (multiplied by the material albedo when rendered).
    """
    if kind not in _GENERATORS:
        raise ValueError(f"kind must be one of {TEXTURE_KINDS}, got {kind!r}")
    if not (width_m > 0 and height_m > 0 and texel_m > 0):
        raise ValueError(f"width_m, height_m and texel_m must be > 0, got {width_m}, {height_m}, {texel_m}")
    rng = np.random.default_rng(rng)
    shape = (max(2, int(np.ceil(height_m / texel_m))), max(2, int(np.ceil(width_m / texel_m))))
    return _GENERATORS[kind](rng, shape, float(texel_m)).astype(np.float32)


# ----------------------------------------------------------------------------------------------
# mesh builder with per-chart atlas packing
# ----------------------------------------------------------------------------------------------


@dataclass
class _Chart:
    width_m: float
    height_m: float
    kind: str
    tri_slice: slice           # triangles of this chart
    uv_m: np.ndarray           # (n_tri, 3, 2) chart-local coordinates, metres
    image: np.ndarray | None = None   # explicit texture (texels), else procedural


class _MeshBuilder:
    def __init__(self) -> None:
        self.vertices: list[np.ndarray] = []
        self.triangles: list[np.ndarray] = []
        self.material: list[np.ndarray] = []
        self.charts: list[_Chart] = []
        self.nv = 0
        self.nf = 0

    def add(self, verts, tris, uv_m, material: int, kind: str, width_m: float, height_m: float):
        verts = np.asarray(verts, float)
        tris = np.asarray(tris, np.int64)
        self.vertices.append(verts)
        self.triangles.append(tris + self.nv)
        self.material.append(np.full(len(tris), material, np.int32))
        self.charts.append(_Chart(width_m, height_m, kind, slice(self.nf, self.nf + len(tris)),
                                  np.asarray(uv_m, float)))
        self.nv += len(verts)
        self.nf += len(tris)

    def add_box(self, center, size, materials, kinds, R=None) -> None:
        """Box with faces ordered +x, -x, +y, -y, +z, -z; per-face material index and texture kind."""
        c = np.asarray(center, float)
        h = 0.5 * np.asarray(size, float)
        R = np.eye(3) if R is None else np.asarray(R, float)
        if np.isscalar(materials) or isinstance(materials, int):
            materials = [materials] * 6
        if isinstance(kinds, str):
            kinds = [kinds] * 6
        for f, (axis, sgn) in enumerate(((0, 1), (0, -1), (1, 1), (1, -1), (2, 1), (2, -1))):
            a1, a2 = [(1, 2), (2, 0), (0, 1)][axis]
            if sgn < 0:
                a1, a2 = a2, a1
            n = np.zeros(3)
            n[axis] = sgn
            e1 = np.zeros(3)
            e1[a1] = 1
            e2 = np.zeros(3)
            e2[a2] = 1
            h1, h2, hn = h[a1], h[a2], h[axis]
            loc = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
            corners = c + (R @ (n * hn + loc[:, :1] * h1 * e1 + loc[:, 1:] * h2 * e2).T).T
            uv = (loc + 1.0) * np.array([h1, h2])
            tris = np.array([[0, 1, 2], [0, 2, 3]])
            self.add(corners, tris, uv[tris], materials[f], kinds[f], 2 * h1, 2 * h2)

    def add_cylinder(self, p0, p1, radius, material, kind, n_seg=24, caps=True) -> None:
        p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
        ax = p1 - p0
        L = float(np.linalg.norm(ax))
        ax = ax / L
        ref = np.array([1.0, 0, 0]) if abs(ax[0]) < 0.9 else np.array([0, 1.0, 0])
        e1 = np.cross(ax, ref)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(ax, e1)
        th = np.linspace(0, 2 * np.pi, n_seg + 1)
        ring = radius * (np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2)
        verts = np.concatenate([p0 + ring, p1 + ring])
        k = n_seg + 1
        i = np.arange(n_seg)
        tris = np.concatenate([np.stack([i, i + 1, k + i + 1], 1), np.stack([i, k + i + 1, k + i], 1)])
        uv = np.stack([np.concatenate([th * radius, th * radius]), np.r_[np.zeros(k), np.full(k, L)]], 1)
        self.add(verts, tris, uv[tris], material, kind, 2 * np.pi * radius, L)
        if caps:
            for p, sgn in ((p0, -1), (p1, 1)):
                ring_c = p + ring[:-1]
                verts = np.concatenate([p[None], ring_c])
                j = np.arange(n_seg)
                tris = np.stack([np.zeros(n_seg, int), 1 + j, 1 + (j + 1) % n_seg], 1)
                if sgn < 0:
                    tris = tris[:, [0, 2, 1]]
                uvc = np.concatenate([[[radius, radius]],
                                      radius + radius * np.stack([np.cos(th[:-1]), np.sin(th[:-1])], 1)])
                self.add(verts, tris, uvc[tris], material, kind, 2 * radius, 2 * radius)

    def build(self, *, name, materials, texel_m, seed, description) -> Target:
        V = np.concatenate(self.vertices)
        Fi = np.concatenate(self.triangles)
        mat = np.concatenate(self.material)
        atlas, tri_uv = _pack_atlas(self.charts, self.nf, texel_m=texel_m, seed=seed)
        return Target(name=name, vertices_T=V, triangles=Fi, triangle_uv=tri_uv,
                      triangle_material=mat, materials=tuple(materials), texture=atlas,
                      texel_m=texel_m, seed=seed, description=description)


def _pack_atlas(charts: list[_Chart], n_tri: int, *, texel_m: float, seed: int, pad: int = _CHART_PAD):
    """Shelf-pack charts into one atlas, generate their textures, and map chart UVs to texels."""
    import cv2

    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(len(charts))]
    sizes = []
    for ch in charts:
        if ch.image is not None:
            sizes.append(ch.image.shape)
        else:
            sizes.append((max(2, int(np.ceil(ch.height_m / texel_m))),
                          max(2, int(np.ceil(ch.width_m / texel_m)))))
    total = sum((h + 2 * pad) * (w + 2 * pad) for h, w in sizes)
    atlas_w = max(int(np.ceil(np.sqrt(total) * 1.15)), max(w for _, w in sizes) + 2 * pad)
    order = sorted(range(len(charts)), key=lambda i: -sizes[i][0])
    pos = [None] * len(charts)
    x = y = shelf_h = 0
    for i in order:
        h, w = sizes[i][0] + 2 * pad, sizes[i][1] + 2 * pad
        if x + w > atlas_w:
            x, y, shelf_h = 0, y + shelf_h, 0
        pos[i] = (x + pad, y + pad)
        x += w
        shelf_h = max(shelf_h, h)
    step = 2 ** (_MIP_LEVELS - 1)
    H = int(np.ceil((y + shelf_h) / step) * step)
    W = int(np.ceil(atlas_w / step) * step)
    atlas = np.full((H, W), 0.5, dtype=np.float32)
    tri_uv = np.zeros((n_tri, 3, 2), dtype=np.float32)
    for i, ch in enumerate(charts):
        h, w = sizes[i]
        x0, y0 = pos[i]
        if ch.image is not None:
            img = ch.image.astype(np.float32)
            scale = np.array([1.0, 1.0])
        else:
            img = _GENERATORS[ch.kind](rngs[i], (h, w), texel_m).astype(np.float32)
            scale = np.array([1.0 / texel_m, 1.0 / texel_m])
        padded = cv2.copyMakeBorder(img, pad, pad, pad, pad, cv2.BORDER_REFLECT)
        atlas[y0 - pad:y0 + h + pad, x0 - pad:x0 + w + pad] = padded
        # chart metres -> texel coordinates (texel centres at integers): u along columns
        tri_uv[ch.tri_slice] = ch.uv_m * scale - 0.5 + np.array([x0, y0])
    return atlas, tri_uv


# ----------------------------------------------------------------------------------------------
# the FY-1-like target
# ----------------------------------------------------------------------------------------------

FY1_BUS_SIZE_M = (1.42, 1.42, 1.20)
FY1_SPAN_M = 10.556
FY1_PANEL_LENGTH_M = 1.17          # three per wing: 3.51 m of cells per wing
FY1_PANEL_WIDTH_M = 1.20
FY1_PANEL_THICKNESS_M = 0.025
FY1_PANEL_GAP_M = 0.02


def fy1_target(*, seed: int = 0, texel_m: float = 0.005) -> Target:
    """The procedural FY-1-like target of paper 003 (dimensions and sources in the module docstring).

    Parameters
    ----------
    seed : int, optional
        Seed of the procedural textures (and of the geometric mode's surface features).
    texel_m : float, optional
        Texture resolution, metres per texel (0.005 m resolves the pixel footprint of a 20° 1024-px
        camera down to 17 m range).

    Returns
    -------
    Target
        Body frame: origin at the bus centre, +z Earth face, wings along ±y, cells facing +x.
    """
    if not texel_m > 0:
        raise ValueError(f"texel_m must be > 0, got {texel_m!r}")
    materials = (
        Material("MLI gold (bus sides)", "mli", 0.55, specular=0.25, shininess=25.0),
        Material("MLI silver (bus top and bottom)", "mli", 0.80, specular=0.25, shininess=25.0),
        Material("solar cells", "solar_cells", 0.45, specular=0.35, shininess=60.0),
        Material("solar panel back (white paint)", "panel_back", 0.80),
        Material("structure (yoke, hinges)", "structure", 0.55, specular=0.1),
        Material("antenna (white)", "structure", 0.85, specular=0.1),
        Material("instrument and radiator", "radiator", 0.75, specular=0.1),
    )
    MLI_GOLD, MLI_SILVER, CELLS, BACK, STRUCT, ANT, INSTR = range(7)
    b = _MeshBuilder()
    bx, by, bz = FY1_BUS_SIZE_M
    b.add_box((0, 0, 0), FY1_BUS_SIZE_M,
              [MLI_GOLD, MLI_GOLD, MLI_GOLD, MLI_GOLD, MLI_SILVER, MLI_SILVER], "mli")
    half_span = 0.5 * FY1_SPAN_M
    wing_len = 3 * FY1_PANEL_LENGTH_M + 2 * FY1_PANEL_GAP_M
    yoke_len = half_span - 0.5 * by - wing_len
    for s in (1.0, -1.0):
        # yoke: two struts from the bus side to the first panel, and a hinge bar
        y_root, y_tip = s * 0.5 * by, s * (0.5 * by + yoke_len)
        for z in (-0.35, 0.35):
            b.add_cylinder((0, y_root, z * 0.5), (0, y_tip, z), 0.02, STRUCT, "structure", n_seg=10)
        b.add_box((0, y_tip, 0), (0.05, 0.04, FY1_PANEL_WIDTH_M * 0.9), STRUCT, "structure")
        for k in range(3):
            y0 = 0.5 * by + yoke_len + k * (FY1_PANEL_LENGTH_M + FY1_PANEL_GAP_M)
            yc = s * (y0 + 0.5 * FY1_PANEL_LENGTH_M)
            b.add_box((0, yc, 0), (FY1_PANEL_THICKNESS_M, FY1_PANEL_LENGTH_M, FY1_PANEL_WIDTH_M),
                      [CELLS, BACK, STRUCT, STRUCT, STRUCT, STRUCT],
                      ["solar_cells", "panel_back", "structure", "structure", "structure", "structure"])
    # Earth face (+z): scanner radiometer box with a radiant-cooler box, antennas
    b.add_box((0.25, 0.15, 0.5 * bz + 0.15), (0.55, 0.45, 0.30), INSTR, "radiator")
    b.add_box((-0.35, -0.35, 0.5 * bz + 0.09), (0.35, 0.35, 0.18), INSTR, "radiator")
    b.add_cylinder((-0.45, 0.45, 0.5 * bz), (-0.45, 0.45, 0.5 * bz + 0.30), 0.08, ANT, "structure")
    for x, y in ((0.6, -0.6), (-0.6, 0.6)):
        b.add_cylinder((x, y, 0.5 * bz), (x * 1.3, y * 1.3, 0.5 * bz + 0.8), 0.015, ANT, "structure",
                       n_seg=8)
    # a thruster/adapter ring on the anti-Earth face (-z)
    b.add_cylinder((0, 0, -0.5 * bz), (0, 0, -0.5 * bz - 0.12), 0.30, STRUCT, "structure", n_seg=32)
    desc = (f"FY-1-like: bus {bx} x {by} x {bz} m (FY-1C, NSMC/CMA); two wings of three "
            f"{FY1_PANEL_LENGTH_M} x {FY1_PANEL_WIDTH_M} m panels on a {yoke_len:.3f} m yoke, "
            f"tip-to-tip span {FY1_SPAN_M} m (FY-1C published); panel width, antennas and instrument "
            "boxes assumed")
    return b.build(name="FY-1-like", materials=materials, texel_m=texel_m, seed=seed, description=desc)


# ----------------------------------------------------------------------------------------------
# mesh files
# ----------------------------------------------------------------------------------------------

_MESH_SUFFIXES = (".obj", ".stl", ".ply", ".gltf", ".glb", ".off")


def load_mesh(path: str | Path, *, unit_m: float, name: str | None = None,
              center: str = "bbox", texture: str = "auto", texel_m: float = 0.01,
              seed: int = 0, albedo_range: tuple[float, float] = (0.35, 0.85)) -> Target:
    """Load a triangle mesh file (OBJ, STL, PLY, glTF/GLB, OFF) as a :class:`Target`.

    Parameters
    ----------
    path : str or Path
        Mesh file, read by Open3D.
    unit_m : float
        Length of one file unit in metres (e.g. 0.0254 for inches, 1e-3 for millimetres).
    name : str, optional
        Model name (default: the file stem).
    center : {"bbox", "area", "none"}
        Body-frame origin: the bounding-box centre, the area-weighted surface centroid, or the file's
        origin.
    texture : {"auto", "file", "procedural"}
        ``"file"`` uses the file's single texture image (error when there is none), ``"procedural"``
        generates one, ``"auto"`` uses the file's texture when there is exactly one with complete
        texture coordinates and falls back to procedural otherwise. File texture coordinates are read
        with v up (OBJ/OpenGL convention, which Open3D returns; its assimp reader converts glTF's
        top-left origin to it); the image is used as grey-level albedo.
    texel_m : float
        Procedural texel size, metres.
    seed : int
        Seed of the procedural texture and per-material albedos.
    albedo_range : (float, float)
        Range of the random albedo given to each of the file's materials (procedural texture).

    Notes
    -----
    The procedural fallback maps every triangle to one of six planar charts (±x, ±y, ±z, by the
    dominant direction of its normal, "box mapping"); each chart is a generic MLI-like texture over
    the mesh's projected extent. Material groups of the file get random albedos from
    ``albedo_range``. Degenerate (zero-area) triangles are dropped.
    """
    import open3d as o3d

    p = Path(path)
    if not p.is_file():
        raise ValueError(f"path: no such file {str(p)!r}")
    if p.suffix.lower() not in _MESH_SUFFIXES:
        raise ValueError(f"path: unsupported mesh format {p.suffix!r}; use one of {_MESH_SUFFIXES}")
    if not (np.isfinite(unit_m) and unit_m > 0):
        raise ValueError(f"unit_m must be > 0, got {unit_m!r}")
    if center not in ("bbox", "area", "none"):
        raise ValueError(f"center must be 'bbox', 'area' or 'none', got {center!r}")
    if texture not in ("auto", "file", "procedural"):
        raise ValueError(f"texture must be 'auto', 'file' or 'procedural', got {texture!r}")
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        mesh = o3d.io.read_triangle_mesh(str(p), enable_post_processing=False)
    V = np.asarray(mesh.vertices, dtype=float) * float(unit_m)
    Fi = np.asarray(mesh.triangles, dtype=np.int64)
    if len(V) < 3 or len(Fi) == 0:
        raise ValueError(f"path: {str(p)!r} has no triangles that Open3D can read")
    mat_ids = (np.asarray(mesh.triangle_material_ids, dtype=np.int64)
               if mesh.has_triangle_material_ids() else np.zeros(len(Fi), np.int64))
    uvs = np.asarray(mesh.triangle_uvs, dtype=float)
    textures = [np.asarray(t) for t in mesh.textures if np.asarray(t).ndim >= 2]
    has_file_tex = len(textures) == 1 and uvs.shape == (3 * len(Fi), 2)
    if texture == "file" and not has_file_tex:
        raise ValueError(f"texture='file' but {str(p)!r} has no single texture with complete UVs")
    # drop degenerate triangles
    pt = V[Fi]
    area = 0.5 * np.linalg.norm(np.cross(pt[:, 1] - pt[:, 0], pt[:, 2] - pt[:, 0]), axis=1)
    keep = area > 1e-12 * max(1.0, float(np.ptp(V, axis=0).max()) ** 2)
    Fi, mat_ids, area = Fi[keep], mat_ids[keep], area[keep]
    uvs = uvs.reshape(-1, 3, 2)[keep] if has_file_tex else None
    if center == "bbox":
        V = V - 0.5 * (V.min(axis=0) + V.max(axis=0))
    elif center == "area":
        V = V - (area[:, None] * V[Fi].mean(axis=1)).sum(axis=0) / area.sum()
    # compact material ids
    uniq, mat = np.unique(mat_ids, return_inverse=True)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 7]))
    materials = tuple(Material(f"material {int(u)}", "mli", float(rng.uniform(*albedo_range)),
                               specular=0.1, shininess=20.0) for u in uniq)
    use_file = has_file_tex and texture in ("auto", "file")
    nm = name or p.stem
    if use_file:
        img = textures[0].astype(np.float32)
        if img.ndim == 3:
            img = img[..., :3].mean(axis=2)
        img = img / (255.0 if textures[0].dtype == np.uint8 else max(1.0, float(img.max())))
        step = 2 ** (_MIP_LEVELS - 1)
        h, w = img.shape
        H, W = int(np.ceil(h / step) * step), int(np.ceil(w / step) * step)
        import cv2

        atlas = cv2.copyMakeBorder(img, 0, H - h, 0, W - w, cv2.BORDER_REPLICATE)
        # Open3D returns texture coordinates with v up (OBJ/OpenGL; assimp flips glTF to this)
        tri_uv = np.stack([uvs[..., 0] * w - 0.5, (1.0 - uvs[..., 1]) * h - 0.5], axis=-1)
        tri_uv = tri_uv.astype(np.float32)
        materials = tuple(Material(m.name, m.kind, 1.0, m.specular, m.shininess) for m in materials)
        return Target(name=nm, vertices_T=V, triangles=Fi, triangle_uv=tri_uv,
                      triangle_material=mat, materials=materials, texture=atlas,
                      texel_m=texel_m, seed=seed,
                      description=f"{p.name}, unit {unit_m} m, file texture")
    # procedural box mapping: one planar chart per (connected piece, dominant normal axis and sign),
    # so that no two surfaces share texels
    pt = V[Fi]
    n = np.cross(pt[:, 1] - pt[:, 0], pt[:, 2] - pt[:, 0])
    axis = np.argmax(np.abs(n), axis=1)
    sign = n[np.arange(len(n)), axis] >= 0
    piece = _mesh_pieces(V, Fi)
    key = piece * 6 + axis * 2 + (~sign)
    order = np.argsort(key, kind="stable")
    Fi, mat, key, pt, axis = Fi[order], mat[order], key[order], pt[order], axis[order]
    bounds = np.flatnonzero(np.r_[True, key[1:] != key[:-1], True])
    charts = []
    for b0, b1 in zip(bounds[:-1], bounds[1:], strict=True):
        a = int(axis[b0])
        a1, a2 = [(1, 2), (2, 0), (0, 1)][a]
        p2 = np.stack([pt[b0:b1][..., a1], pt[b0:b1][..., a2]], axis=-1)
        lo2 = p2.reshape(-1, 2).min(axis=0)
        ext = p2.reshape(-1, 2).max(axis=0) - lo2
        charts.append(_Chart(float(ext[0]) + texel_m, float(ext[1]) + texel_m, "mli",
                             slice(int(b0), int(b1)), p2 - lo2))
    atlas, tri_uv = _pack_atlas(charts, len(Fi), texel_m=texel_m, seed=seed, pad=8)
    return Target(name=nm, vertices_T=V, triangles=Fi, triangle_uv=tri_uv, triangle_material=mat,
                  materials=materials, texture=atlas, texel_m=texel_m, seed=seed,
                  description=f"{p.name}, unit {unit_m} m, procedural box-mapped texture")


def _mesh_pieces(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Connected piece of every triangle (vertices merged by position to 1e-6 of the mesh size)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    tol = 1e-6 * max(1e-12, float(np.ptp(V, axis=0).max()))
    _, vid = np.unique(np.round(V / tol).astype(np.int64), axis=0, return_inverse=True)
    f = vid.reshape(-1)[F]
    nv = int(f.max()) + 1
    r = np.concatenate([f[:, 0], f[:, 1]])
    c = np.concatenate([f[:, 1], f[:, 2]])
    _, lab = connected_components(coo_matrix((np.ones(len(r)), (r, c)), shape=(nv, nv)), directed=False)
    return lab[f[:, 0]].astype(np.int64)
