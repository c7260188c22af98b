"""Standard exchange formats of a stored closed-loop run: CCSDS AEM and OEM, PLY, COLMAP.

Plain functions over the dataset of a ``coobs run`` folder (``result.nc``), for notebooks and
for ``coobs export RUN --to aem|oem|ply|colmap --out DIR``::

    from experiments.export import open_run, write_aem, write_oem, write_ply, write_colmap

    ds = open_run("runs/quickstart")
    write_aem(ds, "out/target_true.aem", attitude="true", epoch="2026-01-01T00:00:00")
    write_oem(ds, "out/view_0.oem", obj="view 0")
    write_ply(ds, "out/snapshot_cloud.ply")
    write_colmap(ds, "out/colmap")          # out/colmap/sparse + out/colmap/images

Conventions (frames, quaternion order, pixel origin) are in each writer's module and in
``docs/export.md``.  The names load on first use, so ``coobs --help`` stays fast.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader as lazy

if TYPE_CHECKING:
    from experiments.export.ccsds import inertial_states, write_aem, write_oem
    from experiments.export.folder import export_run
    from experiments.export.points import image_names, snapshot_poses, write_colmap, write_ply
    from experiments.export.run import (
        DEFAULT_EPOCH,
        FORMATS,
        INERTIAL_FRAMES,
        TIME_SYSTEMS,
        open_run,
    )

__all__ = [
    "FORMATS",
    "DEFAULT_EPOCH",
    "TIME_SYSTEMS",
    "INERTIAL_FRAMES",
    "open_run",
    "write_aem",
    "write_oem",
    "write_ply",
    "write_colmap",
    "inertial_states",
    "snapshot_poses",
    "image_names",
    "export_run",
]

__getattr__, __dir__, _ = lazy.attach(__name__, submod_attrs={
    "run": ["DEFAULT_EPOCH", "FORMATS", "INERTIAL_FRAMES", "TIME_SYSTEMS", "open_run"],
    "ccsds": ["inertial_states", "write_aem", "write_oem"],
    "points": ["image_names", "snapshot_poses", "write_colmap", "write_ply"],
    "folder": ["export_run"],
})
