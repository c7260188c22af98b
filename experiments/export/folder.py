"""``export_run``: one format of a stored run into a folder, all files together or none (``coobs export``)."""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from pathlib import Path

from experiments.export.ccsds import write_aem, write_oem
from experiments.export.points import write_colmap, write_ply
from experiments.export.run import DEFAULT_EPOCH, FORMATS, INERTIAL_FRAMES, check_epoch, open_run

__all__ = ["export_run"]


def _file_name(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("._") or "object"


def _write_all(ds, fmt: str, folder: Path, *, epoch: str, time_system: str, ref_frame: str,
               binary: bool) -> list[Path]:
    if fmt == "aem":
        return [write_aem(ds, folder / f"target_{a}.aem", attitude=a, epoch=epoch, time_system=time_system,
                          ref_frame=ref_frame) for a in ("true", "est")]
    if fmt == "oem":
        objs = ["target", *(str(s) for s in ds["spacecraft"].values)]
        files = [f"{_file_name(o)}.oem" for o in objs]
        if len(set(files)) != len(files):
            files = [f"{i:02d}_{f}" for i, f in enumerate(files)]
        return [write_oem(ds, folder / f, obj=o, epoch=epoch, time_system=time_system, ref_frame=ref_frame)
                for o, f in zip(objs, files, strict=True)]
    if fmt == "ply":
        return [write_ply(ds, folder / "snapshot_cloud.ply")]
    sparse = write_colmap(ds, folder, binary=binary)
    return [sparse, *((folder / "images",) if (folder / "images").exists() else ())]


def export_run(run: Path | str, fmt: str, out: Path | str, *, epoch: str = DEFAULT_EPOCH, time_system: str = "UTC",
               ref_frame: str = "EME2000", binary: bool = False) -> list[Path]:
    """Export a stored run in one format into a folder; all files appear together or none.

    Parameters
    ----------
    run : path
        A ``coobs run`` folder of a closed-loop config (or its ``result.nc``).
    fmt : {"aem", "oem", "ply", "colmap"}
        ``aem``: ``target_true.aem`` and ``target_est.aem``; ``oem``: ``target.oem`` and one
        ``<observer>.oem`` per spacecraft; ``ply``: ``snapshot_cloud.ply``; ``colmap``:
        ``sparse/`` and ``images/``.
    out : path
        Output folder (created; files of the same names are replaced).
    epoch, time_system, ref_frame : str, keyword-only
        Scenario epoch, CCSDS time system and inertial frame name of the CCSDS messages.
    binary : bool, keyword-only
        COLMAP binary files instead of text.

    Returns
    -------
    list of Path
        The files (or folders) written under ``out``.

    Raises
    ------
    ValueError
        One line naming the parameter (``fmt``, ``epoch``, ``time_system``, ``ref_frame``) or
        starting ``run:`` / ``out:``; nothing is written then.
    """
    if fmt not in FORMATS:
        raise ValueError(f"fmt: {str(fmt)[:40]!r} is not one of {', '.join(FORMATS)}")
    check_epoch(epoch, time_system)
    if ref_frame not in INERTIAL_FRAMES:
        raise ValueError(f"ref_frame: {str(ref_frame)[:40]!r} is not one of {', '.join(INERTIAL_FRAMES)}")
    ds = open_run(run)
    out = Path(os.path.abspath(out))
    if out.exists() and not out.is_dir():
        raise ValueError(f"out: {str(out)[:60]!r} is a file, not a folder")
    if out.is_dir() and (out / "result.nc").exists():
        raise ValueError(f"out: {str(out)[:60]!r} holds a run's result.nc; export into another folder")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.export-", dir=out.parent))
    except OSError as exc:
        raise ValueError(f"out: cannot write in {str(out.parent)[:60]!r} ({exc.strerror or type(exc).__name__})") from None
    try:
        written = _write_all(ds, fmt, tmp, epoch=epoch, time_system=time_system, ref_frame=ref_frame, binary=binary)
        out.mkdir(exist_ok=True)
        final = []
        for p in written:
            dst = out / p.relative_to(tmp)
            if dst.is_dir():
                shutil.rmtree(dst)
            os.replace(p, dst)
            final.append(dst)
        return final
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
