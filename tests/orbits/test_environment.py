"""Tests of orbits.environment: Sun direction against published almanac values, Earth shadow."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from orbits import environment as env
from orbits.two_body import R_EARTH_M, state_from_elements

EPS_J2000_RAD = np.radians(23.4392911)


def _angle_deg(u, v):
    u = u / np.linalg.norm(u, axis=-1, keepdims=True)
    v = v / np.linalg.norm(v, axis=-1, keepdims=True)
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(u, v), axis=-1), np.sum(u * v, axis=-1)))


def _unit_radec(ra_deg, dec_deg):
    ra, dec = np.radians(ra_deg), np.radians(dec_deg)
    return np.array([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)])


def _unit_ecliptic(lon_deg, eps_rad=np.radians(23.4365)):
    lam = np.radians(lon_deg)
    return np.array([np.cos(lam), np.cos(eps_rad) * np.sin(lam), np.sin(eps_rad) * np.sin(lam)])


def test_sun_vallado_example_5_1():
    """Vallado, *Fundamentals of Astrodynamics and Applications* (4th ed. 2013 / 5th ed. 2022
    pp. 286–287), Example 5-1: at JD_UT1 2453827.4992 (2006-04-01 23:58:54.816) the Sun (MOD) is
    r = [146186375, 28788200, 12480727] km, α = 11.1406°, δ = 4.7883°."""
    r = env.sun_position_N("2006-04-01T23:58:54.816", of_date=True)
    published = np.array([146186375.0, 28788200.0, 12480727.0]) * 1e3
    assert _angle_deg(r, published) < 0.05
    assert _angle_deg(r, _unit_radec(11.1406, 4.7883)) < 0.05
    assert abs(np.linalg.norm(r) / np.linalg.norm(published) - 1.0) < 1e-4


def test_sun_meeus_example_25a():
    """Meeus, *Astronomical Algorithms* (2nd ed. 1998), Example 25.a: on 1992 October 13.0 TD
    (TD − UT ≈ 59 s) the Sun's apparent α = 13h13m31.4s = 198.38083°, δ = −7°47′06″ = −7.78507°."""
    s = env.sun_direction_N("1992-10-12T23:59:01", of_date=True)
    assert _angle_deg(s, _unit_radec(198.38083, -7.78507)) < 0.05


@pytest.mark.parametrize(
    ("epoch", "lon_deg"),
    [
        ("2020-03-20T03:50", 0.0),
        ("2020-06-20T21:43", 90.0),
        ("2024-09-22T12:44", 180.0),
        ("2024-12-21T09:20", 270.0),
    ],
)
def test_sun_at_published_equinoxes_and_solstices(epoch, lon_deg):
    """USNO *Earth's Seasons* (Astronomical Applications Dept., tabulated e.g. in Wikipedia's
    'March equinox' table): at these UTC minutes the Sun's apparent ecliptic longitude of date is
    0°, 90°, 180°, 270° (one minute of time is 0.0007°)."""
    s = env.sun_direction_N(epoch, of_date=True)
    assert _angle_deg(s, _unit_ecliptic(lon_deg)) < 0.05


def test_j2000_sun_differs_from_of_date_by_precession():
    """At the 2024 March equinox (of-date λ = 0) the Sun's J2000 ecliptic longitude is minus the
    accumulated general precession, p_A = 5029.0966″/century × 0.2421 cy = 0.3382°."""
    epoch = "2024-03-20T03:07"
    s = env.sun_direction_N(epoch)
    T = (env.julian_date(epoch) - 2451545.0) / 36525.0
    # Ecliptic longitude in the J2000 ecliptic frame.
    x, y, z = s
    lam = np.degrees(np.arctan2(y * np.cos(EPS_J2000_RAD) + z * np.sin(EPS_J2000_RAD), x))
    assert abs(lam - (-5029.0966 * T / 3600.0)) < 0.01


def test_precession_moves_equinox_by_general_precession():
    """IAU 1976: the mean equinox of date, seen in J2000 ecliptic coordinates, sits at longitude
    −p_A with p_A = 5029.0966″T + 1.11113″T² (Lieske et al. 1977), latitude |β| < 10″T."""
    for T in (0.25, 1.0, -0.5):
        R = env.precession_matrix(2451545.0 + 36525.0 * T)
        x_mod_in_j2000 = R.T @ np.array([1.0, 0.0, 0.0])
        x, y, z = x_mod_in_j2000
        ye = y * np.cos(EPS_J2000_RAD) + z * np.sin(EPS_J2000_RAD)
        ze = -y * np.sin(EPS_J2000_RAD) + z * np.cos(EPS_J2000_RAD)
        lam_arcsec = np.degrees(np.arctan2(ye, x)) * 3600
        beta_arcsec = np.degrees(np.arcsin(ze)) * 3600
        assert abs(lam_arcsec + 5029.0966 * T + 1.11113 * T**2) < 0.5
        assert abs(beta_arcsec) < 10 * abs(T)


def test_epoch_forms_agree_and_t_s_vectorises():
    s1 = env.sun_direction_N("2006-04-02T00:00:00", np.array([0.0, 86400.0]))
    s2 = env.sun_direction_N(dt.datetime(2006, 4, 3, tzinfo=dt.UTC))
    s3 = env.sun_direction_N(np.datetime64("2006-04-02T00:00"))
    assert s1.shape == (2, 3)
    np.testing.assert_allclose(s1[1], s2, atol=1e-12)
    np.testing.assert_allclose(s1[0], s3, atol=1e-15)
    # The Sun moves ~0.9856°/day in longitude.
    assert 0.9 < _angle_deg(s1[0], s1[1]) < 1.05


def test_cylindrical_eclipse_fraction_of_circular_orbit():
    """β = 0 circular orbit of radius r: the cylinder shadow spans 2·arcsin(R⊕/r) of the orbit."""
    a = 6721.2e3
    u = np.linspace(0, 2 * np.pi, 200_001)[:-1]
    r, _ = state_from_elements(a, 0.0, 0.0, 0.0, 0.0, u)
    sun = np.array([env.AU_M, 0.0, 0.0])
    f = env.illumination_fraction(r, sun, model="cylindrical")
    expected = 2 * np.arcsin(R_EARTH_M / a) / (2 * np.pi)
    assert abs(np.mean(f == 0.0) - expected) < 1e-4
    assert set(np.unique(f)) == {0.0, 1.0}


def test_conical_shadow_umbra_penumbra_sunlit():
    a = 6721.2e3
    u = np.linspace(0, 2 * np.pi, 200_001)[:-1]
    r, _ = state_from_elements(a, 0.0, 0.0, 0.0, 0.0, u)
    sun = np.array([env.AU_M, 0.0, 0.0])
    f = env.illumination_fraction(r, sun)
    region = env.shadow_region(r, sun)
    cyl = env.illumination_fraction(r, sun, model="cylindrical")
    assert f[0] == 1.0 and f[len(u) // 2] == 0.0  # sub-solar point lit, anti-solar point dark
    n_umbra, n_pen = np.sum(region == env.UMBRA), np.sum(region == env.PENUMBRA)
    # Umbra shorter than the cylinder shadow, umbra + penumbra longer.
    assert n_umbra < np.sum(cyl == 0.0) < n_umbra + n_pen
    # Penumbra: the Sun's 0.53° disc crosses the limb; seen from 343 km altitude the limb moves
    # at ~n·(1 + ...) so each penumbra lasts some seconds, two of them per orbit.
    period_s = 5483.8
    pen_s = n_pen / len(u) * period_s
    assert 10.0 < pen_s < 40.0
    # Monotonic across the entry terminator (u from 90° to 180°).
    seg = f[len(u) // 4: len(u) // 2]
    assert np.all(np.diff(seg) <= 1e-12)


def test_conical_partial_fraction_matches_disc_sampling():
    """Independent check of the overlapping-discs formula: sample the solar disc and count the
    directions not hidden by the Earth's disc (exact spherical angles)."""
    rng = np.random.default_rng(3)
    sun = np.array([env.AU_M, 0.0, 0.0])
    r0 = 6721.2e3
    a_sun = np.arcsin(env.R_SUN_M / env.AU_M)
    b_earth = np.arcsin(R_EARTH_M / r0)
    # Spacecraft positions whose Sun–Earth apparent separation c spans the penumbra.
    for frac_target in (0.1, 0.5, 0.9):
        c = b_earth - a_sun + 2 * a_sun * frac_target
        # Place the spacecraft at radius r0 so that the angle between −r and the Sun is c.
        theta = np.pi - c  # angle of r from +x (Sun at infinity approx; exact d used below)
        r = r0 * np.array([np.cos(theta), np.sin(theta), 0.0])
        f = env.illumination_fraction(r, sun)
        d = sun - r
        d_hat = d / np.linalg.norm(d)
        # Sample the disc uniformly in angle around d_hat.
        e1 = np.cross(d_hat, [0, 0, 1.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(d_hat, e1)
        rho = np.arcsin(env.R_SUN_M / np.linalg.norm(d)) * np.sqrt(rng.uniform(0, 1, 400_000))
        phi = rng.uniform(0, 2 * np.pi, 400_000)
        dirs = (np.cos(rho)[:, None] * d_hat + np.sin(rho)[:, None]
                * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2))
        ang_to_earth = np.arccos(np.clip(dirs @ (-r / r0), -1, 1))
        visible = np.mean(ang_to_earth > b_earth)
        assert abs(f - visible) < 0.01


def test_sun_direction_in_hill_frame_matches_element_rotation():
    """R_NH of a circular orbit is R3(Ω) R1(i) R3(u) (columns radial, along-track, normal)."""
    a, i, raan, u = 6721.2e3, 0.7, 1.2, np.array([0.1, 2.0, 4.0])
    r, v = state_from_elements(a, 0.0, i, raan, 0.0, u)
    t = np.array([0.0, 100.0, 200.0])
    s_H = env.sun_direction_H("2024-06-01T00:00", t, r, v)

    def rz(x):
        return np.array([[np.cos(x), -np.sin(x), 0], [np.sin(x), np.cos(x), 0], [0, 0, 1]])

    def rx(x):
        return np.array([[1, 0, 0], [0, np.cos(x), -np.sin(x)], [0, np.sin(x), np.cos(x)]])

    s_geo = env.sun_direction_N("2024-06-01T00:00", t)
    for k in range(3):
        R_NH = rz(raan) @ rx(i) @ rz(u[k])
        assert _angle_deg(s_H[k], R_NH.T @ s_geo[k]) < 0.003  # LEO parallax ≤ 0.003°
    np.testing.assert_allclose(np.linalg.norm(s_H, axis=-1), 1.0, atol=1e-15)


def test_sun_direction_in_body_frame():
    """q_NT = 90° about z: s_T = R_z(90°)ᵀ s_N = [s_y, −s_x, s_z]."""
    q = np.array([np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)])
    s_N = env.sun_direction_N("2024-06-01T00:00")
    s_T = env.sun_direction_T("2024-06-01T00:00", 0.0, q)
    np.testing.assert_allclose(s_T, [s_N[1], -s_N[0], s_N[2]], atol=1e-15)


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: env.sun_direction_N("not a date"), "epoch_utc"),
        (lambda: env.sun_direction_N("2024-01-01", np.nan), "t_s"),
        (lambda: env.illumination_fraction(np.zeros(3) + 1e3, np.ones(3)), "r_N"),
        (lambda: env.illumination_fraction(np.ones(2), np.ones(3)), "r_N"),
        (lambda: env.illumination_fraction([7e6, 0, 0], [1e11, 0, 0], model="flat"), "model"),
        (lambda: env.sun_direction_T("2024-01-01", 0.0, np.ones(3)), "q_NT"),
    ],
)
def test_environment_bad_input_names_argument(call, name):
    with pytest.raises(ValueError, match=name):
        call()
