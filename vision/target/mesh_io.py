"""Targets from triangle-mesh files, and the two NASA meshes shipped with the package.

:func:`load_mesh` reads a mesh file (OBJ, STL, PLY, glTF/GLB, OFF) with Open3D, or one of the
bundled meshes by name (:func:`available_meshes`): ``"topex"`` (TOPEX/Poseidon, assembled, file
units inches) and ``"hubble"`` (the Hubble 3D-printing kit, parts laid out flat, file units taken
as millimetres). The files and their provenance are described in ``vision/target/meshes/README.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path

import numpy as np

from vision.target.builder import Chart, pack_atlas
from vision.target.model import MIP_LEVELS, Material, Target

__all__ = ["BundledMesh", "BUNDLED_MESHES", "available_meshes", "bundled_mesh_path", "load_mesh"]

_MESH_SUFFIXES = (".obj", ".stl", ".ply", ".gltf", ".glb", ".off")


@dataclass(frozen=True)
class BundledMesh:
    """A mesh file shipped in ``vision/target/meshes``.

    Attributes
    ----------
    name : str
        Short name accepted by :func:`load_mesh` (``"topex"``).
    file : str
        File name in the package's ``meshes`` folder.
    unit_m : float
        Metres per file unit used when :func:`load_mesh` is given no ``unit_m``.
    description : str
        What the model is.
    """

    name: str
    file: str
    unit_m: float
    description: str


#: The bundled meshes by name.
BUNDLED_MESHES: dict[str, BundledMesh] = {
    "topex": BundledMesh("topex", "topex_poseidon.obj", 0.0254,
                         "NASA TOPEX/Poseidon, assembled flight configuration; file units inches"),
    "hubble": BundledMesh("hubble", "hubble_model_kit.obj", 1e-3,
                          "NASA Hubble 3D-printing kit, parts laid out side by side; file units "
                          "taken as millimetres"),
}


def available_meshes() -> tuple[str, ...]:
    """Names of the bundled meshes, sorted (``("hubble", "topex")``)."""
    return tuple(sorted(BUNDLED_MESHES))


def _unknown(parameter: str, value: object) -> ValueError:
    return ValueError(f"{parameter}: {value!r} is neither a bundled mesh {available_meshes()} "
                      "nor an existing mesh file")


def bundled_mesh_path(name: str) -> Path:
    """Path on disk of a bundled mesh file, found with :mod:`importlib.resources`.

    Parameters
    ----------
    name : str
        One of :func:`available_meshes`.

    Returns
    -------
    Path
        The ``.obj`` file inside the installed package.

    Raises
    ------
    ValueError
        ``name`` is not a bundled mesh.
    """
    if name not in BUNDLED_MESHES:
        raise ValueError(f"name: unknown bundled mesh {name!r}; known: {available_meshes()}")
    path = Path(str(files("vision.target").joinpath("meshes", BUNDLED_MESHES[name].file)))
    if not path.is_file():
        raise FileNotFoundError(f"bundled mesh {name!r} is missing from the installation: {path}")
    return path


def load_mesh(path: str | Path, *, unit_m: float | None = None, name: str | None = None,
              center: str = "bbox", texture: str = "auto", texel_m: float = 0.01,
              seed: int = 0, albedo_range: tuple[float, float] = (0.35, 0.85)) -> Target:
    """Load a bundled mesh or a triangle mesh file (OBJ, STL, PLY, glTF/GLB, OFF) as a :class:`Target`.

    Parameters
    ----------
    path : str or Path
        A bundled mesh name (one of :func:`available_meshes`: ``"topex"``, ``"hubble"``) or a mesh
        file, read by Open3D.
    unit_m : float, optional
        Length of one file unit in metres (e.g. 0.0254 for inches, 1e-3 for millimetres). Required
        for a file; a bundled mesh defaults to its :attr:`BundledMesh.unit_m`.
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

    if isinstance(path, str) and path in BUNDLED_MESHES:
        p = bundled_mesh_path(path)
        unit_m = BUNDLED_MESHES[path].unit_m if unit_m is None else unit_m
    else:
        p = Path(path)
        if not p.is_file():
            raise _unknown("path", str(p))
        if unit_m is None:
            raise ValueError(f"unit_m: required for the mesh file {str(p)!r} (metres per file unit)")
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
        step = 2 ** (MIP_LEVELS - 1)
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
        charts.append(Chart(float(ext[0]) + texel_m, float(ext[1]) + texel_m, "mli",
                             slice(int(b0), int(b1)), p2 - lo2))
    atlas, tri_uv = pack_atlas(charts, len(Fi), texel_m=texel_m, seed=seed, pad=8)
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
