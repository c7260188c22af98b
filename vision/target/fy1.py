"""The procedural FY-1-like target of paper 003: dimensions, materials and their sources.

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

from vision.target.builder import MeshBuilder
from vision.target.model import Material, Target

__all__ = [
    "fy1_target",
    "FY1_BUS_SIZE_M",
    "FY1_SPAN_M",
    "FY1_PANEL_LENGTH_M",
    "FY1_PANEL_WIDTH_M",
    "FY1_PANEL_THICKNESS_M",
    "FY1_PANEL_GAP_M",
]

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
    b = MeshBuilder()
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
