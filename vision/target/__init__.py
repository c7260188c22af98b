"""Target models: the procedural FY-1-like satellite and triangle meshes, textured in the body frame T."""

from vision.target.fy1 import (
    FY1_BUS_SIZE_M,
    FY1_PANEL_GAP_M,
    FY1_PANEL_LENGTH_M,
    FY1_PANEL_THICKNESS_M,
    FY1_PANEL_WIDTH_M,
    FY1_SPAN_M,
    fy1_target,
)
from vision.target.mesh_io import (
    BUNDLED_MESHES,
    BundledMesh,
    available_meshes,
    bundled_mesh_path,
    load_mesh,
)
from vision.target.model import Material, Target
from vision.target.textures import TEXTURE_KINDS, procedural_texture

__all__ = [
    "Material",
    "Target",
    "fy1_target",
    "load_mesh",
    "available_meshes",
    "bundled_mesh_path",
    "BundledMesh",
    "BUNDLED_MESHES",
    "procedural_texture",
    "TEXTURE_KINDS",
    "FY1_BUS_SIZE_M",
    "FY1_SPAN_M",
    "FY1_PANEL_LENGTH_M",
    "FY1_PANEL_WIDTH_M",
    "FY1_PANEL_THICKNESS_M",
    "FY1_PANEL_GAP_M",
]
