"""``coobs export RUN --to aem|oem|ply|colmap --out DIR``: a stored run in a standard exchange format.

A folder without ``result.nc``, a sweep folder, a run of another study, an unknown format or a bad
epoch exit with code 2 and one line, and nothing is written (:func:`experiments.export.export_run`).
"""

from __future__ import annotations

from pathlib import Path

import typer

from coobs.cli._console import console, fail
from experiments.export.run import DEFAULT_EPOCH, FORMATS, INERTIAL_FRAMES, TIME_SYSTEMS

__all__ = ["export"]


def export(
    run: Path = typer.Argument(..., help="A folder written by 'coobs run' of a closed-loop config."),
    to: str = typer.Option(..., "--to", help=f"Format: {', '.join(FORMATS)} (CCSDS attitude / orbit ephemeris "
                           "messages, PLY point cloud, COLMAP sparse model)."),
    out: Path = typer.Option(..., "--out", help="Output folder (created; files of the same names are replaced)."),
    epoch: str = typer.Option(DEFAULT_EPOCH, "--epoch", help="Scenario epoch (t = 0) of the CCSDS messages, "
                              "YYYY-MM-DDThh:mm:ss[.fff] in --time-system."),
    time_system: str = typer.Option("UTC", "--time-system", help=f"CCSDS TIME_SYSTEM: {', '.join(TIME_SYSTEMS)}."),
    ref_frame: str = typer.Option("EME2000", "--ref-frame", help="Name the inertial frame N is written as: "
                                  f"{', '.join(INERTIAL_FRAMES)}."),
    binary: bool = typer.Option(False, "--binary", help="COLMAP: binary model files instead of text."),
) -> None:
    """Export a stored closed-loop run as CCSDS AEM/OEM (KVN), PLY or a COLMAP model."""
    options = {"fmt": "--to", "epoch": "--epoch", "time_system": "--time-system", "ref_frame": "--ref-frame",
               "run": "RUN", "out": "--out"}
    from experiments.export.folder import export_run

    try:
        written = export_run(run, to, out, epoch=epoch, time_system=time_system, ref_frame=ref_frame, binary=binary)
    except ValueError as exc:
        name, _, rest = str(exc).partition(":")
        raise fail(f"{options.get(name, name)}:{rest}" if rest else str(exc)) from None
    except OSError as exc:
        raise fail(f"--out: cannot write in {str(out)[:60]!r} ({exc.strerror or type(exc).__name__})") from None
    for p in written:
        console.print(f"wrote: {p}", markup=False, highlight=False)
