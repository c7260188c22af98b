"""CCSDS attitude and orbit ephemeris messages (KVN) of a stored closed-loop run.

``write_aem``
    CCSDS AEM 2.0 (ADM, CCSDS 504.0-B-2): the target's true or estimated attitude as
    ``QUATERNION/ANGVEL``.  ADM 2.0 fixes what AEM 1.0 left to ``ATTITUDE_DIR`` and
    ``QUATERNION_TYPE``: every line is ``epoch Q1 Q2 Q3 QC ωx ωy ωz`` (scalar last) and the
    quaternion transforms ``REF_FRAME_A`` (the inertial frame N, written ``EME2000`` by default)
    into ``REF_FRAME_B = SC_BODY_1`` (the target body T): ``v_B = A(q) v_A`` with
    ``A(q) = (qc² − |e|²) I + 2 e eᵀ − 2 qc [e×]``.  Our ``q_NT`` (Hamilton, scalar first, maps T
    components to N) has exactly these four numbers, reordered: ``(Q1, Q2, Q3, QC) = (q1, q2, q3,
    q0)``.  The rate ``ω_TN_T`` (T relative to N, T components) is written in deg/s with
    ``ANGVEL_FRAME = SC_BODY_1``.  The true and estimated attitudes go to two files: two segments
    of one object would overlap in time, which the standard does not allow.
``write_oem``
    CCSDS OEM 2.0 (ODM, CCSDS 502.0-B-2): one object per file (the standard and its readers keep
    one object per message), the target or one observer, position (km) and velocity (km/s) in an
    Earth-centred inertial frame.  The run's N is inertial with the target on a circular
    equatorial orbit (``R_NH = R_z(n t)``, :func:`closed_loop.tumbling_target`); it is written as
    ``EME2000`` by default.  The target's state comes from :func:`orbits.two_body.state_from_elements`
    (``a`` = the stored config's orbit radius, ``ν = n t``), an observer's from its stored Hill
    state (``r_H_m``, ``v_H_m_s``) through :func:`orbits.hill.inertial_from_hill`.

Epochs are ``epoch + time_s`` in ``time_system``.  Nothing is written unless the whole message
could be built: the text goes to a temporary file that replaces ``path`` at the end.
"""

from __future__ import annotations

import os
import tempfile
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import xarray as xr

from experiments.export.run import (
    DEFAULT_EPOCH,
    INERTIAL_FRAMES,
    epoch_strings,
    orbit_radius_of,
    require,
)
from orbits.cw import mean_motion
from orbits.hill import inertial_from_hill
from orbits.two_body import state_from_elements

__all__ = ["INERTIAL_FRAMES", "ORIGINATOR", "write_aem", "write_oem", "inertial_states", "write_text_atomic"]

#: ``ORIGINATOR`` of the messages
ORIGINATOR = "COOBS"
_ATTITUDES = {"true": ("q_NT_true", "omega_true_deg_s", "true attitude (simulation truth)"),
              "est": ("q_NT_est", "omega_est_deg_s", "estimated attitude")}


def write_text_atomic(path: Path | str, text: str) -> Path:
    """Write ``text`` to ``path`` through a temporary file in the same folder (all or nothing)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", dir=p.parent)
    try:
        with os.fdopen(fd, "w", encoding="ascii", newline="\n") as f:
            f.write(text)
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p


def _kvn_value(name: str, value: str) -> str:
    text = str(value)
    if not text.isascii() or "\n" in text or len(text) > 200:
        raise ValueError(f"{name}: {text[:40]!r} must be one line of printable ASCII, at most 200 characters")
    return text


def _check_frame(ref_frame: str) -> str:
    if ref_frame not in INERTIAL_FRAMES:
        raise ValueError(f"ref_frame: {ref_frame!r} is not one of {', '.join(INERTIAL_FRAMES)}")
    return ref_frame


def _creation_date() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%S")


def _finite(ds: xr.Dataset, name: str) -> np.ndarray:
    a = np.asarray(ds[name].values, dtype=float)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"run: {name!r} has non-finite values; the message would not be valid")
    return a


def write_aem(ds: xr.Dataset, path: Path | str, *, attitude: str = "true", epoch: str = DEFAULT_EPOCH,
              time_system: str = "UTC", ref_frame: str = "EME2000", object_name: str = "TARGET",
              object_id: str = "UNKNOWN") -> Path:
    """Write the target's attitude history as a CCSDS AEM 2.0 KVN file.

    Parameters
    ----------
    ds : xarray.Dataset
        A stored closed-loop run (:func:`experiments.export.open_run`).
    path : path
        The ``.aem`` file to write (replaced if it exists; its folder is created).
    attitude : {"true", "est"}, keyword-only
        The simulated truth (``q_NT_true``, ``omega_true_deg_s``) or the filter's estimate
        (``q_NT_est``, ``omega_est_deg_s``).
    epoch : str, keyword-only
        Scenario epoch (``t = 0``), ISO ``YYYY-MM-DDThh:mm:ss[.fff]`` in ``time_system``.
    time_system : str, keyword-only
        ``TIME_SYSTEM`` of the message (UTC, TAI, TT, GPS, TDB).
    ref_frame : str, keyword-only
        ``REF_FRAME_A``: the name N is written as (EME2000, GCRF, ICRF).
    object_name, object_id : str, keyword-only
        ``OBJECT_NAME`` and ``OBJECT_ID`` of the target.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    ValueError
        One line naming the parameter (or ``run:`` for the dataset) when anything is wrong;
        nothing is written then.
    """
    if attitude not in _ATTITUDES:
        raise ValueError(f"attitude: {attitude!r} is not one of {', '.join(_ATTITUDES)}")
    q_name, w_name, what = _ATTITUDES[attitude]
    require(ds, (q_name, w_name), "the AEM")
    q_NT = _finite(ds, q_name)
    w_T_deg_s = _finite(ds, w_name)
    t = epoch_strings(ds["time_s"].values, epoch, time_system)
    frame = _check_frame(ref_frame)
    name, oid = _kvn_value("object_name", object_name), _kvn_value("object_id", object_id)
    q = q_NT / np.linalg.norm(q_NT, axis=1, keepdims=True)
    lines = [
        "CCSDS_AEM_VERS = 2.0",
        f"COMMENT coobs closed-loop run: {what} of the tumbling target",
        f"CREATION_DATE = {_creation_date()}",
        f"ORIGINATOR = {ORIGINATOR}",
        "",
        "META_START",
        f"COMMENT {frame} stands for the simulation's inertial frame N; SC_BODY_1 is the target body frame T",
        "COMMENT Q1 Q2 Q3 QC transform REF_FRAME_A to REF_FRAME_B: the components (q1, q2, q3, q0) of coobs q_NT",
        f"OBJECT_NAME = {name}",
        f"OBJECT_ID = {oid}",
        "CENTER_NAME = EARTH",
        f"REF_FRAME_A = {frame}",
        "REF_FRAME_B = SC_BODY_1",
        f"TIME_SYSTEM = {time_system}",
        f"START_TIME = {t[0]}",
        f"STOP_TIME = {t[-1]}",
        "ATTITUDE_TYPE = QUATERNION/ANGVEL",
        "ANGVEL_FRAME = SC_BODY_1",
        "META_STOP",
        "",
        "DATA_START",
        "COMMENT epoch Q1 Q2 Q3 QC ANGVEL_X ANGVEL_Y ANGVEL_Z [deg/s], body rate of SC_BODY_1 relative to REF_FRAME_A",
    ]
    for tk, qk, wk in zip(t, q, w_T_deg_s, strict=True):
        lines.append(" ".join([tk, *(f"{v:.16e}" for v in (qk[1], qk[2], qk[3], qk[0])),
                               *(f"{v:.16e}" for v in wk)]))
    lines += ["DATA_STOP", ""]
    return write_text_atomic(path, "\n".join(lines))


def inertial_states(ds: xr.Dataset, obj: str) -> tuple[np.ndarray, np.ndarray]:
    """Inertial position (m) and velocity (m/s) ``(T, 3)`` of the target or of one observer.

    Parameters
    ----------
    ds : xarray.Dataset
        A stored closed-loop run.
    obj : str
        ``"target"`` or a name of the ``spacecraft`` coordinate.

    Returns
    -------
    r_N_m, v_N_m_s : ndarray (T, 3)
        The state in N (target on its circular equatorial orbit, ``R_NH = R_z(n t)``).
    """
    names = [str(s) for s in ds["spacecraft"].values]
    if obj != "target" and obj not in names:
        raise ValueError(f"obj: {obj!r} is neither 'target' nor one of the run's spacecraft ({', '.join(names)})")
    t_s = np.asarray(ds["time_s"].values, dtype=float)
    a_m = orbit_radius_of(ds)
    n_rad_s = float(mean_motion(a_m))
    r_C_N, v_C_N = state_from_elements(a_m, 0.0, 0.0, 0.0, 0.0, n_rad_s * t_s)
    if obj == "target":
        return r_C_N, v_C_N
    require(ds, ("r_H_m", "v_H_m_s"), "the OEM of an observer")
    i = names.index(obj)
    r_H = _finite(ds, "r_H_m")[i]
    v_H = _finite(ds, "v_H_m_s")[i]
    return inertial_from_hill(r_C_N, v_C_N, r_H, v_H)


def write_oem(ds: xr.Dataset, path: Path | str, *, obj: str = "target", epoch: str = DEFAULT_EPOCH,
              time_system: str = "UTC", ref_frame: str = "EME2000", object_id: str = "UNKNOWN") -> Path:
    """Write the trajectory of the target or of one observer as a CCSDS OEM 2.0 KVN file.

    Parameters
    ----------
    ds : xarray.Dataset
        A stored closed-loop run (:func:`experiments.export.open_run`).
    path : path
        The ``.oem`` file to write (replaced if it exists; its folder is created).
    obj : str, keyword-only
        ``"target"`` or the name of one observer (the ``spacecraft`` coordinate); it is the
        ``OBJECT_NAME``.
    epoch, time_system : str, keyword-only
        As in :func:`write_aem`.
    ref_frame : str, keyword-only
        ``REF_FRAME``: the name N is written as (EME2000, GCRF, ICRF).
    object_id : str, keyword-only
        ``OBJECT_ID``.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    ValueError
        One line naming the parameter (or ``run:``); nothing is written then.
    """
    t = epoch_strings(ds["time_s"].values, epoch, time_system)
    frame = _check_frame(ref_frame)
    name = _kvn_value("obj", "TARGET" if obj == "target" else obj)
    oid = _kvn_value("object_id", object_id)
    r_N_m, v_N_m_s = inertial_states(ds, obj)
    role = "the observed target" if obj == "target" else "an observer of the formation"
    lines = [
        "CCSDS_OEM_VERS = 2.0",
        f"COMMENT coobs closed-loop run: {role}, two-body circular orbit about the Earth",
        f"CREATION_DATE = {_creation_date()}",
        f"ORIGINATOR = {ORIGINATOR}",
        "",
        "META_START",
        f"COMMENT {frame} stands for the simulation's inertial frame N (target orbit in its x-y plane)",
        f"OBJECT_NAME = {name}",
        f"OBJECT_ID = {oid}",
        "CENTER_NAME = EARTH",
        f"REF_FRAME = {frame}",
        f"TIME_SYSTEM = {time_system}",
        f"START_TIME = {t[0]}",
        f"STOP_TIME = {t[-1]}",
        "META_STOP",
        "",
        "COMMENT epoch X Y Z [km] X_DOT Y_DOT Z_DOT [km/s]",
    ]
    for tk, rk, vk in zip(t, r_N_m / 1e3, v_N_m_s / 1e3, strict=True):
        lines.append(" ".join([tk, *(f"{x:.16e}" for x in (*rk, *vk))]))
    lines.append("")
    return write_text_atomic(path, "\n".join(lines))
