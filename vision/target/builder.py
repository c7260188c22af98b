"""Mesh builder of procedural targets: boxes and cylinders, one texture chart each, packed into an atlas.

Every chart (box face, cylinder side, cap) gets its own region of the atlas, so no texture patch
repeats on the target (repeats cause false matches). Chart textures are drawn from one child
generator per chart (``SeedSequence(seed).spawn``), in chart order.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from vision.target.model import MIP_LEVELS, Material, Target
from vision.target.textures import _GENERATORS

__all__ = ["MeshBuilder", "Chart", "pack_atlas"]

#: Texels of reflected padding around each chart in the atlas.
CHART_PAD = 2 ** MIP_LEVELS


@dataclass
class Chart:
    """One planar texture chart: a rectangle of the atlas and the triangles mapped onto it.

    Attributes
    ----------
    width_m, height_m : float
        Chart size, metres (texture columns along the width).
    kind : str
        Procedural texture family (one of :data:`vision.target.textures.TEXTURE_KINDS`).
    tri_slice : slice
        The chart's triangles in the target's triangle order.
    uv_m : ndarray, shape (n_tri, 3, 2)
        Chart-local coordinates of each triangle corner, metres.
    image : ndarray, shape (h, w), optional
        Explicit texture in texels; None draws a procedural one of ``kind``.
    """

    width_m: float
    height_m: float
    kind: str
    tri_slice: slice
    uv_m: np.ndarray
    image: np.ndarray | None = None


class MeshBuilder:
    """Accumulates triangle pieces (body frame, metres), one :class:`Chart` per piece, into a Target."""

    def __init__(self) -> None:
        self.vertices: list[np.ndarray] = []
        self.triangles: list[np.ndarray] = []
        self.material: list[np.ndarray] = []
        self.charts: list[Chart] = []
        self.nv = 0
        self.nf = 0

    def add(self, verts: ArrayLike, tris: ArrayLike, uv_m: ArrayLike, material: int, kind: str,
            width_m: float, height_m: float) -> None:
        """Append a piece: vertices ``(n, 3)``, triangles ``(m, 3)`` local indices, corner chart
        coordinates ``uv_m (m, 3, 2)`` in metres on a ``width_m × height_m`` chart of ``kind``."""
        verts = np.asarray(verts, float)
        tris = np.asarray(tris, np.int64)
        self.vertices.append(verts)
        self.triangles.append(tris + self.nv)
        self.material.append(np.full(len(tris), material, np.int32))
        self.charts.append(Chart(width_m, height_m, kind, slice(self.nf, self.nf + len(tris)),
                                  np.asarray(uv_m, float)))
        self.nv += len(verts)
        self.nf += len(tris)

    def add_box(self, center: ArrayLike, size: ArrayLike, materials: int | Sequence[int],
                kinds: str | Sequence[str], R: ArrayLike | None = None) -> None:
        """Box of ``size`` (m) at ``center`` (m), rotated by ``R`` (3×3, default identity).

        Faces are ordered +x, -x, +y, -y, +z, -z; ``materials`` and ``kinds`` are one material index
        and texture kind for all faces, or one per face.
        """
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

    def add_cylinder(self, p0: ArrayLike, p1: ArrayLike, radius: float, material: int, kind: str,
                     n_seg: int = 24, caps: bool = True) -> None:
        """Cylinder of ``radius`` (m) from ``p0`` to ``p1`` (m), ``n_seg`` sides, optional end caps."""
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

    def build(self, *, name: str, materials: Sequence[Material], texel_m: float, seed: int,
              description: str) -> Target:
        """The :class:`Target` of the pieces added so far, textures drawn from ``seed``."""
        V = np.concatenate(self.vertices)
        Fi = np.concatenate(self.triangles)
        mat = np.concatenate(self.material)
        atlas, tri_uv = pack_atlas(self.charts, self.nf, texel_m=texel_m, seed=seed)
        return Target(name=name, vertices_T=V, triangles=Fi, triangle_uv=tri_uv,
                      triangle_material=mat, materials=tuple(materials), texture=atlas,
                      texel_m=texel_m, seed=seed, description=description)


def pack_atlas(charts: list[Chart], n_tri: int, *, texel_m: float, seed: int,
               pad: int = CHART_PAD) -> tuple[np.ndarray, np.ndarray]:
    """Shelf-pack charts into one atlas, generate their textures, and map chart UVs to texels.

    Parameters
    ----------
    charts : list of Chart
        The charts; chart ``i`` draws its texture from child ``i`` of ``SeedSequence(seed)``.
    n_tri : int
        Number of triangles F covered by the charts' slices.
    texel_m : float
        Procedural texel size, metres.
    seed : int
        Texture seed.
    pad : int, optional
        Texels of reflected padding around each chart.

    Returns
    -------
    atlas : ndarray, shape (Ht, Wt), float32
        Albedo atlas, sides multiples of 2**(MIP_LEVELS-1).
    triangle_uv : ndarray, shape (F, 3, 2), float32
        Atlas texel coordinates of each triangle corner.
    """
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
    step = 2 ** (MIP_LEVELS - 1)
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
