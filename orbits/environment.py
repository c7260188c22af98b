"""Sun direction and Earth shadow for lighting, eclipses and Sun-exclusion constraints.

Frames
------
``N`` is Earth-centred inertial, mean equator and equinox of J2000 (EME2000; within 0.02″ of
GCRF, far below this module's accuracy).  The almanac formula gives the Sun in the *equator and
equinox of date*; it is rotated to J2000 with the IAU 1976 precession (Lieske et al. 1977,
A&A 58:1; Vallado 4th ed. eq. 3-88).  ``of_date=True`` returns the of-date direction instead,
which is what almanacs tabulate.

Sun position
------------
The Astronomical Almanac's low-precision formula (AA 2015, p. C5; Vallado Algorithm 29),
stated to 0.01° for 1950–2050, with ``d = JD − 2451545.0``:

.. math::

    L = 280.460° + 0.9856474° d,\\quad g = 357.528° + 0.9856003° d,\\quad
    λ = L + 1.915° \\sin g + 0.020° \\sin 2g,

    ε = 23.439° − 4\\times10^{-7}° d,\\quad R = 1.00014 − 0.01671 \\cos g − 0.00014 \\cos 2g \\ \\mathrm{AU},

    \\mathbf s = R\\,(\\cos λ,\\; \\cos ε \\sin λ,\\; \\sin ε \\sin λ).

UTC is used for the formula's time argument (TT − UTC ≈ 69 s moves the Sun by 0.0008°).

Earth shadow
------------
Cylindrical: the spacecraft is dark when it is behind the Earth's terminator plane and within
R⊕ of the Earth–Sun line.  Conical: the fraction of the solar disc not hidden by the Earth disc,
from their apparent radii and separation (Montenbruck & Gill, *Satellite Orbits*, 2000,
§3.4.2, eqs. 3.85–3.87); 0 in the umbra, 1 in full sunlight, in between in the penumbra.
"""

from __future__ import annotations

import datetime as _dt

import numpy as np
from numpy.typing import ArrayLike

from attitude.quaternion import check_quat, matrix_from_quat
from orbits._checks import check_finite, check_last_axis
from orbits.hill import hill_frame
from orbits.two_body import R_EARTH_M

__all__ = [
    "AU_M",
    "R_SUN_M",
    "SUNLIT",
    "PENUMBRA",
    "UMBRA",
    "julian_date",
    "precession_matrix",
    "sun_position_N",
    "sun_direction_N",
    "sun_direction_H",
    "sun_direction_T",
    "illumination_fraction",
    "shadow_region",
]

#: Astronomical unit (IAU 2012), m.
AU_M = 149_597_870_700.0
#: Solar radius (IAU 2015 nominal), m.
R_SUN_M = 6.957e8
#: :func:`shadow_region` code: the Sun's disc wholly visible.
SUNLIT = 0
#: :func:`shadow_region` code: the Sun's disc partly hidden by the Earth.
PENUMBRA = 1
#: :func:`shadow_region` code: the Sun's disc wholly hidden by the Earth.
UMBRA = 2

_J2000 = np.datetime64("2000-01-01T12:00:00", "us")
_ARCSEC = np.pi / (180.0 * 3600.0)


def _epoch64(epoch_utc: object) -> np.datetime64:
    if isinstance(epoch_utc, _dt.datetime):
        if epoch_utc.tzinfo is not None:
            epoch_utc = epoch_utc.astimezone(_dt.UTC).replace(tzinfo=None)
        return np.datetime64(epoch_utc, "us")
    try:
        e = np.datetime64(epoch_utc, "us")
    except (ValueError, TypeError) as exc:
        raise ValueError(f"epoch_utc: not a UTC epoch (datetime, numpy.datetime64 or ISO-8601 "
                         f"string): {epoch_utc!r}") from exc
    if np.isnat(e):
        raise ValueError(f"epoch_utc: not a time: {epoch_utc!r}")
    return e


def julian_date(epoch_utc: object, t_s: ArrayLike = 0.0) -> np.ndarray:
    """Julian date of ``epoch_utc + t_s`` (UTC scale), as a float array of ``t_s``'s shape.

    Parameters
    ----------
    epoch_utc : datetime.datetime, numpy.datetime64 or str
        Scenario epoch in UTC (naive datetimes are taken as UTC; ISO-8601 strings such as
        ``"2006-04-02T00:00:00"``).
    t_s : array_like
        Seconds after the epoch.
    """
    e = _epoch64(epoch_utc)
    t = check_finite(t_s, name="t_s")
    days = (e - _J2000) / np.timedelta64(1, "us") / 86400e6
    return 2451545.0 + days + t / 86400.0


def _rot1(a):
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, s], -1), np.stack([z, -s, c], -1)], -2)


def _rot2(a):
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, z, -s], -1), np.stack([z, o, z], -1), np.stack([s, z, c], -1)], -2)


def _rot3(a):
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, s, z], -1), np.stack([-s, c, z], -1), np.stack([z, z, o], -1)], -2)


def precession_matrix(jd: ArrayLike) -> np.ndarray:
    """IAU 1976 precession ``R_MOD_J2000`` (maps J2000 components to mean-of-date ones).

    ``R = R3(−z) R2(θ) R3(−ζ)`` (coordinate rotations) with, in arcseconds and Julian centuries
    T of TT from J2000 (UTC used here), ζ = 2306.2181T + 0.30188T² + 0.017998T³,
    θ = 2004.3109T − 0.42665T² − 0.041833T³, z = 2306.2181T + 1.09468T² + 0.018203T³.
    Shape ``(...) → (..., 3, 3)``.
    """
    T = (check_finite(jd, name="jd") - 2451545.0) / 36525.0
    zeta = (2306.2181 * T + 0.30188 * T**2 + 0.017998 * T**3) * _ARCSEC
    theta = (2004.3109 * T - 0.42665 * T**2 - 0.041833 * T**3) * _ARCSEC
    z = (2306.2181 * T + 1.09468 * T**2 + 0.018203 * T**3) * _ARCSEC
    return _rot3(-z) @ _rot2(theta) @ _rot3(-zeta)


def sun_position_N(epoch_utc: object, t_s: ArrayLike = 0.0, *, of_date: bool = False) -> np.ndarray:
    """Geocentric position of the Sun (m), low-precision almanac formula (~0.01°).

    Parameters
    ----------
    epoch_utc : datetime.datetime, numpy.datetime64 or str
        Scenario epoch (UTC).
    t_s : array_like, shape (...)
        Seconds after the epoch.
    of_date : bool, keyword-only
        False (default): N = mean equator and equinox of J2000.  True: equator and equinox of
        date (the almanac's frame).

    Returns
    -------
    r_sun_N : ndarray, shape (..., 3)
        Earth-to-Sun vector (m).
    """
    jd = julian_date(epoch_utc, t_s)
    d = jd - 2451545.0
    L = np.radians(280.460 + 0.9856474 * d)
    g = np.radians(357.528 + 0.9856003 * d)
    lam = L + np.radians(1.915) * np.sin(g) + np.radians(0.020) * np.sin(2 * g)
    eps = np.radians(23.439 - 4.0e-7 * d)
    R = (1.00014 - 0.01671 * np.cos(g) - 0.00014 * np.cos(2 * g)) * AU_M
    r = R[..., None] * np.stack([np.cos(lam), np.cos(eps) * np.sin(lam), np.sin(eps) * np.sin(lam)], -1)
    if of_date:
        return r
    return np.einsum("...ji,...j->...i", precession_matrix(jd), r)


def sun_direction_N(epoch_utc: object, t_s: ArrayLike = 0.0, *, of_date: bool = False) -> np.ndarray:
    """Unit vector from the Earth's centre to the Sun, shape ``t_s.shape + (3,)``.

    See :func:`sun_position_N` for the arguments and the frame.
    """
    r = sun_position_N(epoch_utc, t_s, of_date=of_date)
    return r / np.linalg.norm(r, axis=-1, keepdims=True)


def _sun_from(r_N: np.ndarray, epoch_utc: object, t_s: ArrayLike) -> np.ndarray:
    s = sun_position_N(epoch_utc, t_s)
    d = s - r_N
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def sun_direction_H(epoch_utc: object, t_s: ArrayLike, r_C_N: ArrayLike,
                    v_C_N: ArrayLike) -> np.ndarray:
    """Sun direction seen from the chief, in the chief's Hill frame H.

    Parameters
    ----------
    epoch_utc : datetime.datetime, numpy.datetime64 or str
        Scenario epoch (UTC).
    t_s : array_like, shape (T,) or ()
        Epochs (s after ``epoch_utc``) at which the chief states are given.
    r_C_N, v_C_N : array_like, shape (..., T, 3) or (..., 3)
        Chief position (m) and velocity (m/s) in N at those epochs (broadcast with ``t_s``).

    Returns
    -------
    s_H : ndarray, shape (..., T, 3)
        Unit vector from the chief to the Sun (parallax-corrected), H components.
    """
    r = check_last_axis(r_C_N, 3, name="r_C_N")
    v = check_last_axis(v_C_N, 3, name="v_C_N")
    s_N = _sun_from(r, epoch_utc, t_s)
    R_NH = hill_frame(r, v)
    return np.einsum("...ji,...j->...i", R_NH, s_N)


def sun_direction_T(epoch_utc: object, t_s: ArrayLike, q_NT: ArrayLike, *,
                    r_T_N: ArrayLike | None = None) -> np.ndarray:
    """Sun direction in the target body frame T.

    Parameters
    ----------
    epoch_utc : datetime.datetime, numpy.datetime64 or str
        Scenario epoch (UTC).
    t_s : array_like, shape (T,) or ()
        Epochs (s after ``epoch_utc``).
    q_NT : array_like, shape (..., T, 4) or (..., 4)
        Target attitude (Hamilton, scalar first; ``R_NT = matrix_from_quat(q_NT)``).
    r_T_N : array_like, shape (..., T, 3), optional, keyword-only
        Target position in N (m) for the parallax correction (≤ 0.003° in LEO); geocentric
        direction when omitted.

    Returns
    -------
    s_T : ndarray, shape (..., T, 3)
        Unit vector towards the Sun in T components, ``R_NTᵀ s_N``.
    """
    q = check_quat(q_NT, name="q_NT")
    if r_T_N is None:
        s_N = sun_direction_N(epoch_utc, t_s)
    else:
        s_N = _sun_from(check_last_axis(r_T_N, 3, name="r_T_N"), epoch_utc, t_s)
    return np.einsum("...ji,...j->...i", matrix_from_quat(q), s_N)


def _check_model(model: str) -> str:
    if model not in ("conical", "cylindrical"):
        raise ValueError(f"model: expected 'conical' or 'cylindrical', got {model!r}")
    return model


def illumination_fraction(r_N: ArrayLike, r_sun_N: ArrayLike, *, model: str = "conical",
                          r_earth_m: float = R_EARTH_M, r_sun_m: float = R_SUN_M) -> np.ndarray:
    """Fraction of the solar disc visible from ``r_N`` past the Earth (1 sunlit, 0 umbra).

    Parameters
    ----------
    r_N : array_like, shape (..., 3)
        Spacecraft position (m), geocentric.
    r_sun_N : array_like, shape (..., 3)
        Sun position (m), geocentric, e.g. :func:`sun_position_N`; broadcast against ``r_N``.
    model : {"conical", "cylindrical"}, keyword-only
        Conical (umbra + penumbra, fraction in [0, 1]) or cylindrical (0 or 1).
    r_earth_m, r_sun_m : float, keyword-only
        Occulting and source radii (m).

    Returns
    -------
    fraction : ndarray, shape (...)
    """
    r = check_last_axis(r_N, 3, name="r_N")
    rs = check_last_axis(r_sun_N, 3, name="r_sun_N")
    _check_model(model)
    r_norm = np.linalg.norm(r, axis=-1)
    if np.any(r_norm <= r_earth_m):
        raise ValueError(f"r_N: position inside the Earth (|r| = {r_norm[r_norm <= r_earth_m].ravel()[0]!r} m)")
    if model == "cylindrical":
        s_hat = rs / np.linalg.norm(rs, axis=-1, keepdims=True)
        along = np.einsum("...i,...i->...", r, s_hat)
        perp = np.linalg.norm(r - along[..., None] * s_hat, axis=-1)
        return np.where((along < 0.0) & (perp < r_earth_m), 0.0, 1.0)
    d = rs - r  # spacecraft → Sun
    d_norm = np.linalg.norm(d, axis=-1)
    a = np.arcsin(np.minimum(r_sun_m / d_norm, 1.0))  # apparent Sun radius
    b = np.arcsin(r_earth_m / r_norm)  # apparent Earth radius
    cos_c = -np.einsum("...i,...i->...", r, d) / (r_norm * d_norm)
    c = np.arccos(np.clip(cos_c, -1.0, 1.0))  # Sun–Earth apparent separation
    with np.errstate(invalid="ignore", divide="ignore"):
        x = (c * c + a * a - b * b) / (2.0 * c)
        y = np.sqrt(np.maximum(a * a - x * x, 0.0))
        area = (a * a * np.arccos(np.clip(x / a, -1.0, 1.0))
                + b * b * np.arccos(np.clip((c - x) / b, -1.0, 1.0)) - c * y)
        partial = 1.0 - area / (np.pi * a * a)
    frac = np.where(c >= a + b, 1.0,
                    np.where(c <= b - a, 0.0,
                             np.where(c <= a - b, 1.0 - (b * b) / (a * a), partial)))
    return np.clip(frac, 0.0, 1.0)


def shadow_region(r_N: ArrayLike, r_sun_N: ArrayLike, *, model: str = "conical",
                  r_earth_m: float = R_EARTH_M, r_sun_m: float = R_SUN_M) -> np.ndarray:
    """Shadow region code: :data:`SUNLIT` (0), :data:`PENUMBRA` (1) or :data:`UMBRA` (2).

    Same arguments as :func:`illumination_fraction`; the cylindrical model has no penumbra.
    """
    f = illumination_fraction(r_N, r_sun_N, model=model, r_earth_m=r_earth_m, r_sun_m=r_sun_m)
    return np.where(f >= 1.0, SUNLIT, np.where(f <= 0.0, UMBRA, PENUMBRA)).astype(np.int8)
