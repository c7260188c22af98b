"""``coobs version``: the installed coobs version and those of the libraries it relies on."""

from __future__ import annotations

from coobs.cli._console import console

__all__ = ["version"]


def version() -> None:
    """Print the installed coobs version and the versions of the libraries it relies on."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as dist_version

    lines = []
    for dist in ("coobs", "numpy", "scipy", "open3d", "opencv-contrib-python-headless", "pycolmap",
                 "casadi", "filterpy", "xarray", "zarr", "dask"):
        try:
            lines.append(f"{dist} {dist_version(dist)}")
        except PackageNotFoundError:
            lines.append(f"{dist} (not installed)")
    console.print("\n".join(lines), markup=False, highlight=False)
