"""A stored closed-loop run as the exporters see it: its dataset, checked, and what its config sets.

:func:`open_run` reads ``result.nc`` of a ``coobs run`` folder (refusing a missing folder, a sweep
folder, another study); :func:`camera_of` and :func:`orbit_radius_of` rebuild the camera and the
target's orbit radius from the config stored in the dataset (``attrs["config_toml"]``) with the
formation kind's own functions, so an export uses exactly what the run used; :func:`epoch_strings`
turns ``time_s`` into CCSDS epochs from a scenario epoch.
"""

from __future__ import annotations

import tomllib
from collections.abc import Sequence
from pathlib import Path
from types import SimpleNamespace
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from experiments.sweep import STORE_NAME

if TYPE_CHECKING:
    from vision.camera import PinholeCamera

__all__ = [
    "FORMATS",
    "INERTIAL_FRAMES",
    "DEFAULT_EPOCH",
    "TIME_SYSTEMS",
    "open_run",
    "require",
    "camera_of",
    "orbit_radius_of",
    "snapshot_epoch_index",
    "epoch_strings",
    "check_epoch",
]

#: formats of :func:`experiments.export.export_run` (and ``coobs export --to``)
FORMATS = ("aem", "oem", "ply", "colmap")
#: CCSDS inertial frame names N may be written as (Earth-centred; N is an idealised inertial frame)
INERTIAL_FRAMES = ("EME2000", "GCRF", "ICRF")
#: scenario epoch (t = 0) written when none is given: 2026-01-01 00:00:00 in TIME_SYSTEM
DEFAULT_EPOCH = "2026-01-01T00:00:00"
#: CCSDS time systems the exporters accept (uniform seconds are added to the epoch in that system)
TIME_SYSTEMS = ("UTC", "TAI", "TT", "GPS", "TDB")


def _shown(path: Path | str) -> str:
    text = repr(str(path))
    return text if len(text) <= 60 else text[:57] + "..."


def open_run(run: Path | str) -> xr.Dataset:
    """Load the ``result.nc`` of a stored closed-loop run into memory.

    Parameters
    ----------
    run : path
        A folder written by ``coobs run`` (or its ``result.nc``) of a ``kind = "formation"``,
        ``study = "closed_loop"`` config.

    Returns
    -------
    xarray.Dataset
        The stored dataset (loaded; the file is closed).

    Raises
    ------
    ValueError
        One line starting ``run:``: no such folder, no ``result.nc`` (a sweep folder is named as
        such), an unreadable file, or results of another kind or study.
    """
    p = Path(run)
    nc = p if p.suffix == ".nc" else p / "result.nc"
    try:
        if not p.exists():
            raise ValueError(f"run: no such folder {_shown(p)}")
        if not nc.is_file():
            if p.is_dir() and (p / STORE_NAME).exists():
                raise ValueError(f"run: {_shown(p)} is a sweep folder ({STORE_NAME}); export reads the result.nc "
                                 "of one 'coobs run'")
            raise ValueError(f"run: no result.nc in {_shown(p)}")
        with xr.open_dataset(nc, engine="h5netcdf") as f:
            ds = f.load()
    except OSError as exc:
        raise ValueError(f"run: {_shown(nc)} cannot be read ({exc.strerror or type(exc).__name__})") from None
    kind, study = ds.attrs.get("kind"), ds.attrs.get("study")
    if kind != "formation" or study != "closed_loop":
        what = f"{kind!r} {study!r}" if study is not None else repr(kind)
        raise ValueError(f"run: {_shown(nc)} holds a {what} result; export needs a closed-loop run "
                         "(kind = 'formation', study = 'closed_loop')")
    return ds


def require(ds: xr.Dataset, names: Sequence[str], what: str) -> None:
    """``ValueError`` naming the first of ``names`` missing from ``ds`` (``what`` says who needs it)."""
    for name in names:
        if name not in ds.variables:
            raise ValueError(f"run: the result has no {name!r}, which {what} needs (re-run it with this coobs)")


def _config_table(ds: xr.Dataset, table: str) -> dict:
    text = ds.attrs.get("config_toml")
    if not isinstance(text, str):
        raise ValueError("run: the result stores no config_toml (not written by 'coobs run')")
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"run: its stored config_toml is not valid TOML ({exc})") from None
    value = raw.get(table, {})
    if not isinstance(value, dict):
        raise ValueError(f"run: its stored config's {table!r} is not a table")
    return value


def camera_of(ds: xr.Dataset) -> PinholeCamera:
    """The run's pinhole camera, rebuilt from the ``[camera]`` table of its stored config.

    Only that table is validated (:class:`~experiments.scenarios.formation.config.CameraConfig`),
    so a run whose target mesh file is not on this machine still exports.
    """
    from experiments.scenarios.formation.config import CameraConfig
    from vision.camera import PinholeCamera

    c = CameraConfig.model_validate(_config_table(ds, "camera"))
    return PinholeCamera.from_fov(c.width_px, c.height_px, fov_x_deg=c.fov_deg)


def orbit_radius_of(ds: xr.Dataset) -> float:
    """Radius of the target's circular orbit, m (``formation.orbit_altitude_km`` of the stored config)."""
    from experiments.scenarios.formation.config import FormationConfig
    from experiments.scenarios.formation.parts import orbit_radius_m

    f = FormationConfig.model_validate(_config_table(ds, "formation"))
    return float(orbit_radius_m(SimpleNamespace(formation=f)))


def snapshot_epoch_index(ds: xr.Dataset) -> int:
    """Index in ``time_s`` of the snapshot epoch (``attrs["snapshot_time_s"]``)."""
    t_snap = ds.attrs.get("snapshot_time_s")
    if t_snap is None:
        raise ValueError("run: the result has no snapshot (attrs['snapshot_time_s'])")
    t = np.asarray(ds["time_s"].values, dtype=float)
    return int(np.argmin(np.abs(t - float(t_snap))))


def check_epoch(epoch: str, time_system: str) -> np.datetime64:
    """The scenario epoch as ``datetime64[ns]``; ``ValueError`` naming ``epoch`` or ``time_system``."""
    if time_system not in TIME_SYSTEMS:
        raise ValueError(f"time_system: {time_system!r} is not one of {', '.join(TIME_SYSTEMS)}")
    if not isinstance(epoch, str) or "T" not in epoch or len(epoch) > 40:
        raise ValueError(f"epoch: {str(epoch)[:40]!r} is not an ISO date and time YYYY-MM-DDThh:mm:ss[.fff]")
    try:
        t0 = np.datetime64(epoch, "ns")
    except ValueError:
        raise ValueError(f"epoch: {epoch!r} is not an ISO date and time YYYY-MM-DDThh:mm:ss[.fff]") from None
    if not np.datetime64("1900-01-01") <= t0 <= np.datetime64("2200-01-01"):
        raise ValueError(f"epoch: {epoch!r} is outside 1900-2200")
    return t0


def epoch_strings(time_s: np.ndarray, epoch: str, time_system: str) -> list[str]:
    """CCSDS epochs ``YYYY-MM-DDThh:mm:ss.fffffffff`` of ``epoch + time_s`` (uniform seconds, to 1 ns).

    Seconds are added without leap seconds: in UTC, a run that spans a leap second is off by it
    after that instant (none has been inserted since 2017).
    """
    t0 = check_epoch(epoch, time_system)
    ns = np.round(np.asarray(time_s, dtype=float) * 1e9).astype(np.int64).astype("timedelta64[ns]")
    return [str(s) for s in (t0 + ns)]
