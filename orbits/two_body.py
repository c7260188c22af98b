"""Keplerian two-body truth: orbital elements, Kepler propagation, relative motion in H.

This is the nonlinear reference that :mod:`orbits.cw` is checked against.  Everything is SI
(m, m/s, rad) and vectorised over leading axes; the inertial frame N is Earth-centred.

Orbital elements follow Vallado, *Fundamentals of Astrodynamics and Applications* (4th ed., 2013),
Algorithms 9–10 (RV2COE / COE2RV), including his conventions for the special cases, so that
``state_from_elements(*elements_from_state(r, v).as_tuple())`` reproduces ``(r, v)`` for every
elliptic orbit:

* circular inclined (e < tol): ``argp_rad = 0`` and ``nu_rad`` is the argument of latitude u;
* elliptic equatorial (sin i < tol): ``raan_rad = 0`` and ``argp_rad`` is the longitude of
  periapsis ϖ (measured from x̂_N about the angular-momentum direction);
* circular equatorial: ``raan_rad = argp_rad = 0`` and ``nu_rad`` is the true longitude.

Kepler propagation uses Lagrange's f and g functions written with the change of eccentric anomaly
ΔE (Battin, *An Introduction to the Mathematics and Methods of Astrodynamics*, §4.3), so it has
no element singularity at e = 0 or i = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from orbits._checks import check_finite, check_last_axis, check_positive, check_times
from orbits.hill import hill_from_inertial

__all__ = [
    "MU_EARTH_M3_S2",
    "R_EARTH_M",
    "OrbitalElements",
    "eccentric_from_mean_anomaly",
    "true_from_eccentric_anomaly",
    "eccentric_from_true_anomaly",
    "true_from_mean_anomaly",
    "mean_from_true_anomaly",
    "orbital_period_s",
    "state_from_elements",
    "elements_from_state",
    "propagate_kepler",
    "relative_trajectory",
]

#: Earth's gravitational parameter (EGM-96 / WGS-84 value, the μ = 398600.4418 km³/s² of 001's scenario), m³/s².
MU_EARTH_M3_S2 = 3.986004418e14
#: Earth's equatorial radius (WGS-84), m.
R_EARTH_M = 6378137.0

_TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class OrbitalElements:
    """Classical orbital elements (arrays of a common broadcast shape, or scalars).

    Attributes
    ----------
    a_m : ndarray
        Semi-major axis (m).
    e : ndarray
        Eccentricity, 0 ≤ e < 1.
    i_rad : ndarray
        Inclination in [0, π] (rad).
    raan_rad : ndarray
        Right ascension of the ascending node in [0, 2π) (rad); 0 for equatorial orbits.
    argp_rad : ndarray
        Argument of periapsis in [0, 2π) (rad); the longitude of periapsis for elliptic
        equatorial orbits, 0 for circular orbits.
    nu_rad : ndarray
        True anomaly in [0, 2π) (rad); the argument of latitude for circular inclined orbits,
        the true longitude for circular equatorial ones.
    """

    a_m: np.ndarray
    e: np.ndarray
    i_rad: np.ndarray
    raan_rad: np.ndarray
    argp_rad: np.ndarray
    nu_rad: np.ndarray

    def as_tuple(self) -> tuple[np.ndarray, ...]:
        """``(a_m, e, i_rad, raan_rad, argp_rad, nu_rad)``, the argument order of
        :func:`state_from_elements`."""
        return (self.a_m, self.e, self.i_rad, self.raan_rad, self.argp_rad, self.nu_rad)

    @property
    def arglat_rad(self) -> np.ndarray:
        """Argument of latitude u = ω + ν, wrapped to [0, 2π) (rad)."""
        return np.mod(self.argp_rad + self.nu_rad, _TWO_PI)

    @property
    def mean_anomaly_rad(self) -> np.ndarray:
        """Mean anomaly M in [0, 2π) (rad)."""
        return mean_from_true_anomaly(self.nu_rad, self.e)


def _check_ecc(e: ArrayLike) -> np.ndarray:
    arr = check_finite(e, name="e")
    bad = (arr < 0.0) | (arr >= 1.0)
    if np.any(bad):
        raise ValueError(f"e: eccentricity must satisfy 0 <= e < 1 (ellipse), got {arr[bad].ravel()[0]!r}")
    return arr


def _scalarize(a: np.ndarray) -> np.ndarray:
    return a[()] if isinstance(a, np.ndarray) and a.ndim == 0 else a


def eccentric_from_mean_anomaly(M_rad: ArrayLike, e: ArrayLike, *, tol: float = 1e-15,
                                max_iter: int = 50) -> np.ndarray:
    """Solve Kepler's equation ``M = E − e sin E`` for E (vectorised Newton iteration).

    Parameters
    ----------
    M_rad : array_like
        Mean anomaly (rad), any real value.
    e : array_like
        Eccentricity, 0 ≤ e < 1; broadcast against ``M_rad``.

    Returns
    -------
    E_rad : ndarray
        Eccentric anomaly (rad) on the same revolution as ``M_rad`` (``E − M`` is in [−e, e]).

    Notes
    -----
    Start ``E₀ = M + e sin M`` for e < 0.8 and Danby's ``E₀ = M + 0.85 e sgn(sin M)`` above;
    convergence is declared when every |ΔE| < ``tol`` (rad).
    """
    M = check_finite(M_rad, name="M_rad")
    e = _check_ecc(e)
    M, e = np.broadcast_arrays(M, e)
    # Reduce M to [-π, π) and put the revolution count back at the end.
    k = np.floor((M + np.pi) / _TWO_PI)
    Mr = M - _TWO_PI * k
    # Small e: one fixed-point step; large e: Danby's start, robust for all e < 1.
    E = np.where(e < 0.8, Mr + e * np.sin(Mr), Mr + 0.85 * e * np.sign(np.sin(Mr)))
    for _ in range(max_iter):
        dE = (E - e * np.sin(E) - Mr) / (1.0 - e * np.cos(E))
        E = E - dE
        if np.all(np.abs(dE) < tol):
            break
    return _scalarize(E + _TWO_PI * k)


def true_from_eccentric_anomaly(E_rad: ArrayLike, e: ArrayLike) -> np.ndarray:
    """True anomaly ν from eccentric anomaly E, in [0, 2π) (rad): ``tan(ν/2) = √((1+e)/(1−e)) tan(E/2)``."""
    E = check_finite(E_rad, name="E_rad")
    e = _check_ecc(e)
    nu = 2.0 * np.arctan2(np.sqrt(1.0 + e) * np.sin(E / 2), np.sqrt(1.0 - e) * np.cos(E / 2))
    return _scalarize(np.mod(nu, _TWO_PI))


def eccentric_from_true_anomaly(nu_rad: ArrayLike, e: ArrayLike) -> np.ndarray:
    """Eccentric anomaly E from true anomaly ν, in [0, 2π) (rad)."""
    nu = check_finite(nu_rad, name="nu_rad")
    e = _check_ecc(e)
    E = 2.0 * np.arctan2(np.sqrt(1.0 - e) * np.sin(nu / 2), np.sqrt(1.0 + e) * np.cos(nu / 2))
    return _scalarize(np.mod(E, _TWO_PI))


def true_from_mean_anomaly(M_rad: ArrayLike, e: ArrayLike) -> np.ndarray:
    """True anomaly ν in [0, 2π) from mean anomaly M (rad), through Kepler's equation."""
    return true_from_eccentric_anomaly(eccentric_from_mean_anomaly(M_rad, e), e)


def mean_from_true_anomaly(nu_rad: ArrayLike, e: ArrayLike) -> np.ndarray:
    """Mean anomaly ``M = E − e sin E`` in [0, 2π) from true anomaly ν (rad)."""
    E = eccentric_from_true_anomaly(nu_rad, e)
    e = np.asarray(e, dtype=float)
    return _scalarize(np.mod(E - e * np.sin(E), _TWO_PI))


def orbital_period_s(a_m: ArrayLike, *, mu_m3_s2: float = MU_EARTH_M3_S2) -> np.ndarray:
    """Keplerian period ``2π √(a³/μ)`` (s) of semi-major axis ``a_m`` (m, > 0)."""
    a = check_positive(a_m, name="a_m")
    return _scalarize(_TWO_PI * np.sqrt(a**3 / mu_m3_s2))


def state_from_elements(a_m: ArrayLike, e: ArrayLike, i_rad: ArrayLike, raan_rad: ArrayLike,
                        argp_rad: ArrayLike, nu_rad: ArrayLike, *,
                        mu_m3_s2: float = MU_EARTH_M3_S2) -> tuple[np.ndarray, np.ndarray]:
    """Inertial position and velocity from classical elements (Vallado Algorithm 10, COE2RV).

    Parameters
    ----------
    a_m : array_like
        Semi-major axis (m), > 0.
    e : array_like
        Eccentricity, 0 ≤ e < 1.
    i_rad, raan_rad, argp_rad, nu_rad : array_like
        Inclination, RAAN, argument of periapsis and true anomaly (rad).  All six arguments
        broadcast against each other (e.g. a ``(T,)`` array of ``nu_rad`` gives T states).
    mu_m3_s2 : float, keyword-only
        Gravitational parameter (m³/s²).

    Returns
    -------
    r_N, v_N : ndarray, shape (..., 3)
        Position (m) and velocity (m/s) in N.

    Notes
    -----
    With the argument of latitude ``u = ω + ν``, the semi-latus rectum ``p = a(1 − e²)`` and
    ``r = p / (1 + e cos ν)``:

    .. math::

        \\hat r = (\\cos Ω \\cos u − \\sin Ω \\sin u \\cos i,\\;
                  \\sin Ω \\cos u + \\cos Ω \\sin u \\cos i,\\; \\sin u \\sin i),\\qquad
        v = \\sqrt{μ/p}\\,(e \\sin ν\\, \\hat r + (1 + e \\cos ν)\\, \\hat θ),

    with ``θ̂ = ∂r̂/∂u``.  Only ``u`` enters the direction, so the special-case conventions of
    :func:`elements_from_state` round-trip exactly.
    """
    a = check_positive(a_m, name="a_m")
    e = _check_ecc(e)
    i = check_finite(i_rad, name="i_rad")
    raan = check_finite(raan_rad, name="raan_rad")
    argp = check_finite(argp_rad, name="argp_rad")
    nu = check_finite(nu_rad, name="nu_rad")
    mu = float(check_positive(mu_m3_s2, name="mu_m3_s2"))
    a, e, i, raan, argp, nu = np.broadcast_arrays(a, e, i, raan, argp, nu)
    p = a * (1.0 - e * e)
    r = p / (1.0 + e * np.cos(nu))
    u = argp + nu
    cO, sO, ci, si, cu, su = np.cos(raan), np.sin(raan), np.cos(i), np.sin(i), np.cos(u), np.sin(u)
    r_hat = np.stack([cO * cu - sO * su * ci, sO * cu + cO * su * ci, su * si], axis=-1)
    t_hat = np.stack([-cO * su - sO * cu * ci, -sO * su + cO * cu * ci, cu * si], axis=-1)
    vp = np.sqrt(mu / p)
    v_r = (vp * e * np.sin(nu))[..., None]
    v_t = (vp * (1.0 + e * np.cos(nu)))[..., None]
    return r[..., None] * r_hat, v_r * r_hat + v_t * t_hat


def _signed_angle(a: np.ndarray, b: np.ndarray, axis_hat: np.ndarray) -> np.ndarray:
    """Angle from ``a`` to ``b`` about ``axis_hat`` (both ⟂ axis), in [0, 2π)."""
    s = np.einsum("...i,...i->...", axis_hat, np.cross(a, b))
    c = np.einsum("...i,...i->...", a, b)
    return np.mod(np.arctan2(s, c), _TWO_PI)


def _elliptic_state(r_N: ArrayLike, v_N: ArrayLike, mu_m3_s2: float, r_name: str, v_name: str):
    """Checked, broadcast ``(r, v, μ, |r|, |v|², specific energy)`` of an elliptic state; errors name the arguments."""
    r = check_last_axis(r_N, 3, name=r_name)
    v = check_last_axis(v_N, 3, name=v_name)
    r, v = np.broadcast_arrays(r, v)
    mu = float(check_positive(mu_m3_s2, name="mu_m3_s2"))
    r_norm = np.linalg.norm(r, axis=-1)
    if np.any(r_norm == 0.0):
        raise ValueError(f"{r_name}: position of zero norm")
    v2 = np.einsum("...i,...i->...", v, v)
    energy = 0.5 * v2 - mu / r_norm
    if np.any(energy >= 0.0):
        raise ValueError(f"{v_name}: state is not elliptic (specific energy {energy[energy >= 0].ravel()[0]!r} J/kg >= 0)")
    return r, v, mu, r_norm, v2, energy


def elements_from_state(r_N: ArrayLike, v_N: ArrayLike, *, mu_m3_s2: float = MU_EARTH_M3_S2,
                        tol: float = 1e-11) -> OrbitalElements:
    """Classical elements from an inertial state (Vallado Algorithm 9, RV2COE), vectorised.

    Parameters
    ----------
    r_N, v_N : array_like, shape (..., 3)
        Position (m) and velocity (m/s) in N of elliptic orbits.
    mu_m3_s2 : float, keyword-only
        Gravitational parameter (m³/s²).
    tol : float, keyword-only
        An orbit with ``e < tol`` is treated as circular and one with ``sin i < tol`` as
        equatorial (see the module docstring for the conventions then used).

    Returns
    -------
    OrbitalElements
        Arrays of shape ``(...)`` (NumPy scalars for a single state).

    Raises
    ------
    ValueError
        If a state is not elliptic (specific energy ≥ 0) or is rectilinear (r × v = 0).
    """
    r, v, mu, r_norm, v2, energy = _elliptic_state(r_N, v_N, mu_m3_s2, "r_N", "v_N")
    h = np.cross(r, v)
    h_norm = np.linalg.norm(h, axis=-1)
    if np.any(h_norm <= 1e-12 * r_norm * np.sqrt(v2)):
        raise ValueError("v_N: rectilinear state (r × v = 0), elements undefined")
    h_hat = h / h_norm[..., None]
    rv = np.einsum("...i,...i->...", r, v)
    e_vec = ((v2 - mu / r_norm)[..., None] * r - rv[..., None] * v) / mu
    e = np.linalg.norm(e_vec, axis=-1)
    a = -mu / (2.0 * energy)
    i = np.arctan2(np.hypot(h_hat[..., 0], h_hat[..., 1]), h_hat[..., 2])  # exact near 0 and π
    node = np.stack([-h_hat[..., 1], h_hat[..., 0], np.zeros_like(h_norm)], axis=-1)
    node_norm = np.linalg.norm(node, axis=-1)
    equatorial = node_norm < tol
    circular = e < tol
    x_hat = np.broadcast_to(np.array([1.0, 0.0, 0.0]), node.shape)
    ref = np.where(equatorial[..., None], x_hat, node / np.where(equatorial, 1.0, node_norm)[..., None])
    raan = np.where(equatorial, 0.0, np.mod(np.arctan2(node[..., 1], node[..., 0]), _TWO_PI))
    e_dir = e_vec / np.where(circular, 1.0, e)[..., None]
    argp = np.where(circular, 0.0, _signed_angle(ref, e_dir, h_hat))
    nu = np.where(circular, _signed_angle(ref, r, h_hat), _signed_angle(e_dir, r, h_hat))
    return OrbitalElements(*(_scalarize(x) for x in (a, e, i, raan, argp, nu)))


def propagate_kepler(r0_N: ArrayLike, v0_N: ArrayLike, t_s: ArrayLike, *,
                     mu_m3_s2: float = MU_EARTH_M3_S2) -> tuple[np.ndarray, np.ndarray]:
    """Propagate elliptic two-body states to many epochs (Lagrange f and g in ΔE).

    Parameters
    ----------
    r0_N, v0_N : array_like, shape (..., 3)
        Initial positions (m) and velocities (m/s) in N at t = 0.
    t_s : array_like, shape (T,)
        Epochs (s) relative to the initial state; any order, negative allowed.
    mu_m3_s2 : float, keyword-only
        Gravitational parameter (m³/s²).

    Returns
    -------
    r_N, v_N : ndarray, shape (..., T, 3)
        Positions (m) and velocities (m/s) at each epoch.

    Notes
    -----
    With ``σ₀ = r₀·v₀/√μ``, ``e cos E₀ = 1 − r₀/a``, ``e sin E₀ = σ₀/√a``, Kepler's equation is
    solved for E at ``M = M₀ + n t``, ``ΔE = E − E₀``, and (Battin §4.3)

    .. math::

        f = 1 − \\frac{a}{r_0}(1 − \\cos ΔE),\\quad g = \\frac{\\sin ΔE − e(\\sin E − \\sin E_0)}{n},\\quad
        \\dot f = −\\frac{\\sqrt{μ a}\\,\\sin ΔE}{r\\,r_0},\\quad \\dot g = 1 − \\frac{a}{r}(1 − \\cos ΔE),

    ``r(t) = f r₀ + g v₀``, ``v(t) = ḟ r₀ + ġ v₀``.  The Newton iteration converges to 1e-15 rad,
    i.e. ~1e-9 m along-track for a 6700 km orbit.
    """
    r0, v0, mu, r0n, v2, energy = _elliptic_state(r0_N, v0_N, mu_m3_s2, "r0_N", "v0_N")
    t = check_times(t_s)
    a = -mu / (2.0 * energy)
    n = np.sqrt(mu / a**3)
    sigma0 = np.einsum("...i,...i->...", r0, v0) / np.sqrt(mu)
    ecosE0 = 1.0 - r0n / a
    esinE0 = sigma0 / np.sqrt(a)
    e = np.hypot(ecosE0, esinE0)
    E0 = np.arctan2(esinE0, ecosE0)
    M0 = E0 - esinE0
    # Epoch axis: (..., T).
    M = M0[..., None] + n[..., None] * t
    ee = np.broadcast_to(e[..., None], M.shape)
    E = eccentric_from_mean_anomaly(M, np.minimum(ee, 1.0 - 1e-15))
    E = np.asarray(E)
    dE = E - E0[..., None]
    a_ = a[..., None]
    r0_ = r0n[..., None]
    cdE, sdE = np.cos(dE), np.sin(dE)
    r = a_ * (1.0 - ee * np.cos(E))
    f = 1.0 - a_ / r0_ * (1.0 - cdE)
    g = (sdE - (ee * np.sin(E) - esinE0[..., None])) / n[..., None]
    fdot = -np.sqrt(mu * a_) * sdE / (r * r0_)
    gdot = 1.0 - a_ / r * (1.0 - cdE)
    r_N = f[..., None] * r0[..., None, :] + g[..., None] * v0[..., None, :]
    v_N = fdot[..., None] * r0[..., None, :] + gdot[..., None] * v0[..., None, :]
    return r_N, v_N


def relative_trajectory(r_C0_N: ArrayLike, v_C0_N: ArrayLike, r_D0_N: ArrayLike,
                        v_D0_N: ArrayLike, t_s: ArrayLike, *,
                        mu_m3_s2: float = MU_EARTH_M3_S2) -> np.ndarray:
    """Nonlinear (two-body) relative trajectory of deputies about a chief, in the chief's H.

    Both spacecraft are propagated with :func:`propagate_kepler` and the deputy's state is
    expressed with :func:`orbits.hill.hill_from_inertial` at every epoch.  Comparing the result
    with :func:`orbits.cw.propagate` of the initial relative state shows where CW stops being valid.

    Parameters
    ----------
    r_C0_N, v_C0_N : array_like, shape (3,) or (..., 3)
        Chief initial position (m) and velocity (m/s) in N.
    r_D0_N, v_D0_N : array_like, shape (..., 3)
        Deputy initial position (m) and velocity (m/s) in N; broadcast against the chief's.
    t_s : array_like, shape (T,)
        Epochs (s).

    Returns
    -------
    x_DC_H : ndarray, shape (..., T, 6)
        ``[r_DC_H, v_DC_H]`` at each epoch (m, m/s), the same layout as :func:`orbits.cw.propagate`.
    """
    r_C, v_C = propagate_kepler(r_C0_N, v_C0_N, t_s, mu_m3_s2=mu_m3_s2)
    r_D, v_D = propagate_kepler(r_D0_N, v_D0_N, t_s, mu_m3_s2=mu_m3_s2)
    rho, rho_dot = hill_from_inertial(r_C, v_C, r_D, v_D)
    return np.concatenate([rho, rho_dot], axis=-1)
