"""The target model: a textured triangle mesh in the body frame T, with per-triangle materials.

A :class:`Target` is a triangle mesh in the target body frame T (metres, origin at the centre of mass
assumed at the reference point chosen at construction), with

- a texture atlas: one grey-level albedo image holding every surface's texture, looked up through
  per-triangle-corner texture coordinates (in atlas texels), with a mip-map pyramid for trilinear
  filtering;
- a material per triangle: a reflectance scale and a specular (Blinn–Phong) term.

Builders: :func:`vision.target.fy1_target` (procedural FY-1-like satellite) and
:func:`vision.target.load_mesh` (bundled NASA meshes and mesh files).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numba
import numpy as np
from numpy.typing import ArrayLike

from vision.target.textures import TEXTURE_KINDS

if TYPE_CHECKING:
    import open3d as o3d

__all__ = ["Material", "Target", "MIP_LEVELS"]

#: Levels 0..4 of the texture pyramid (1×..16× texel); atlas sides are multiples of 2**(levels-1).
MIP_LEVELS = 5


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
        step = 2 ** (MIP_LEVELS - 1)
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
        """Number of triangles F."""
        return int(len(self.triangles))

    def _cached(self, key: str, fn: Callable[[], Any]) -> Any:
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
    def scene(self) -> o3d.t.geometry.RaycastingScene:
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
            for _ in range(1, MIP_LEVELS):
                t = levels[-1]
                levels.append(cv2.resize(t, (t.shape[1] // 2, t.shape[0] // 2),
                                         interpolation=cv2.INTER_AREA))
            return tuple(levels)
        return self._cached("pyramid", fn)

    def point_on_triangles(self, triangle_id: ArrayLike, bary_uv: ArrayLike) -> np.ndarray:
        """Body-frame points ``(..., 3)`` at barycentric ``(b1, b2)`` on triangles (Open3D's convention).

        The point is ``(1 - b1 - b2) p0 + b1 p1 + b2 p2``.
        """
        corners = self._cached("corners", lambda: np.ascontiguousarray(  # (F, 9): p0, p1, p2 side by side
            self.vertices_T[self.triangles].reshape(len(self.triangles), 9)))
        return _barycentric(corners, triangle_id, bary_uv, np.float64)

    def texture_coords(self, triangle_id: ArrayLike, bary_uv: ArrayLike) -> np.ndarray:
        """Atlas texel coordinates ``(..., 2)`` at barycentric ``(b1, b2)`` on triangles."""
        uv_rows = self._cached("uv_rows", lambda: np.ascontiguousarray(  # (F, 6): t0, t1, t2 side by side
            self.triangle_uv.reshape(len(self.triangle_uv), 6)))
        return _barycentric(uv_rows, triangle_id, bary_uv, np.float32)

    def sample_albedo(self, tex_xy: ArrayLike, level: ArrayLike, triangle_id: ArrayLike) -> np.ndarray:
        """Diffuse albedo at atlas coordinates ``tex_xy`` (``(N, 2)``) with mip ``level`` (``(N,)``).

        Trilinear filtering: bilinear in the two pyramid levels around ``level``, blended linearly
        (the float32 sum of the float64 weighted samples, lower level first).  Each pyramid level is
        sampled in one OpenCV call, at every point that needs it.  The result is the texture value
        times the triangle's material albedo.
        """
        import cv2

        xy = np.ascontiguousarray(tex_xy, dtype=np.float32).reshape(-1, 2)
        lev = np.clip(np.asarray(level, dtype=np.float32).reshape(-1), 0.0, MIP_LEVELS - 1.0)
        if not np.isfinite(lev).all():
            raise ValueError(f"level: must be finite, got {lev[~np.isfinite(lev)][0]!r}")
        albedo = self._cached("triangle_albedo", lambda: np.array(
            [m.albedo for m in self.materials], dtype=np.float32)[self.triangle_material])[
            np.asarray(triangle_id, dtype=np.int64).reshape(-1)]
        lev, albedo = (a if len(a) == len(xy) else np.broadcast_to(a, (len(xy),)).copy() for a in (lev, albedo))
        lo = np.floor(lev).astype(np.int64)
        mx, my, start, slot = _level_maps(xy, lo, _REMAP_COLS)
        sample = np.empty(start[-1], dtype=np.float32)
        for ll in np.flatnonzero(np.diff(start)):
            grid = slice(start[ll], start[ll + 1])
            sample[grid] = cv2.remap(self.texture_pyramid[ll], mx[grid].reshape(-1, _REMAP_COLS),
                                     my[grid].reshape(-1, _REMAP_COLS), interpolation=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_REPLICATE).reshape(-1)
        out = np.empty(len(xy), dtype=np.float32)
        _blend_levels(lev, lo, sample, slot, albedo, out)
        return out


#: width of the grid :meth:`Target.sample_albedo` hands OpenCV its sample points on
_REMAP_COLS = 1024


@numba.njit(cache=True, nogil=True)
def _level_maps(xy: np.ndarray, lo: np.ndarray, cols: int) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                     np.ndarray]:  # pragma: no cover - compiled
    """Each point's coordinates in the pyramid levels ``lo`` and ``min(lo + 1, top)`` (float32
    ``(x + 0.5) 2⁻ˡ - 0.5``), on one grid of ``cols`` columns per level, zero-padded: the maps ``mx`` and
    ``my``, level ``l``'s grid at ``start[l]:start[l + 1]``, and each point's two slots in them (``slot``)."""
    count = np.zeros(MIP_LEVELS, dtype=np.int64)
    for i in range(lo.shape[0]):
        count[lo[i]] += 1
        count[min(lo[i] + 1, MIP_LEVELS - 1)] += 1
    start = np.zeros(MIP_LEVELS + 1, dtype=np.int64)
    for ll in range(MIP_LEVELS):
        start[ll + 1] = start[ll] + -(-count[ll] // cols) * cols
    mx, my = np.zeros(start[-1], dtype=np.float32), np.zeros(start[-1], dtype=np.float32)
    slot = np.empty((lo.shape[0], 2), dtype=np.int64)
    next_slot = start[:-1].copy()
    half = np.float32(0.5)
    scales = np.array([1.0 / (1 << ll) for ll in range(MIP_LEVELS)], dtype=np.float32)
    for i in range(xy.shape[0]):
        for j in range(2):
            ll = min(lo[i] + j, MIP_LEVELS - 1)
            k = next_slot[ll]
            next_slot[ll] = k + 1
            scale = scales[ll]
            mx[k] = (xy[i, 0] + half) * scale - half
            my[k] = (xy[i, 1] + half) * scale - half
            slot[i, j] = k
    return mx, my, start, slot


@numba.njit(cache=True, nogil=True)
def _blend_levels(lev: np.ndarray, lo: np.ndarray, sample: np.ndarray, slot: np.ndarray, albedo: np.ndarray,
                  out: np.ndarray) -> None:  # pragma: no cover - compiled
    """``(1 - f) s_lo + f s_hi`` (``f = lev - lo`` in float64, each product added to a float32 sum starting
    at 0, as NumPy's ``acc += w * s`` does), times the float32 material albedo."""
    for i in range(lev.shape[0]):
        f = lev[i] - np.float64(lo[i])
        acc = np.float32(0.0 + (1.0 - f) * sample[slot[i, 0]])
        acc = np.float32(acc + f * sample[slot[i, 1]])
        out[i] = acc * albedo[i]


def _barycentric(corners: np.ndarray, triangle_id: ArrayLike, bary_uv: ArrayLike, dtype: type) -> np.ndarray:
    """``(1 - b1 - b2) c0 + b1 c1 + b2 c2`` of each triangle's corners (``corners`` ``(F, 3 d)``: c0, c1, c2
    side by side) at barycentric ``(..., 2)``: ``(..., d)`` of ``dtype``, the arithmetic of NumPy's
    ``w0[..., None] * c0 + b1[..., None] * c1 + b2[..., None] * c2`` in that order, in one compiled pass."""
    tid = np.asarray(triangle_id, dtype=np.int64)
    b = np.asarray(bary_uv, dtype=dtype)
    shape = np.broadcast_shapes(tid.shape, b.shape[:-1])
    tid = np.broadcast_to(tid, shape).reshape(-1)
    b = np.ascontiguousarray(np.broadcast_to(b, shape + (2,)).reshape(-1, 2))
    F = len(corners)
    lo, hi = (tid.min(), tid.max()) if tid.size else (0, 0)
    if hi >= F or lo < -F:
        raise IndexError(f"triangle ids must be in [-{F}, {F}), got {lo} .. {hi}")
    w0 = 1.0 - b[:, 0] - b[:, 1]
    out = np.empty((len(tid), corners.shape[1] // 3), dtype=dtype)
    _blend_corners(corners, np.where(tid < 0, tid + F, tid) if lo < 0 else tid, w0, b, out)
    return out.reshape(shape + out.shape[1:])


@numba.njit(cache=True, nogil=True)
def _blend_corners(corners: np.ndarray, tid: np.ndarray, w0: np.ndarray, b: np.ndarray,
                   out: np.ndarray) -> None:  # pragma: no cover - compiled
    d = out.shape[1]
    for i in range(tid.shape[0]):
        t = tid[i]
        for k in range(d):
            out[i, k] = w0[i] * corners[t, k] + b[i, 0] * corners[t, d + k] + b[i, 1] * corners[t, 2 * d + k]
