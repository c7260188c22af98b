"""Clohessy–Wiltshire (Hill) relative motion about a circular chief orbit.

State ``x_H = [x, y, z, ẋ, ẏ, ż]`` of a deputy relative to the chief, in the chief's Hill frame H
(x radial outward, y along-track, z orbit normal; ``docs/conventions.md``), metres and metres per second,
with velocities as seen in the rotating frame (what :func:`orbits.hill.hill_from_inertial` returns).
The linearised equations (Clohessy & Wiltshire 1960, J. Aerospace Sci. 27(9):653–658) are

.. math::

    \\ddot x - 3n^2 x - 2n\\dot y = 0,\\qquad \\ddot y + 2n\\dot x = 0,\\qquad \\ddot z + n^2 z = 0,

with the chief's mean motion ``n = √(μ/a³)``.  Their solution is the state transition matrix
Φ(t) of :func:`stm` (Vallado 4th ed. eq. 6-17/6-18, re-ordered to x radial, y along-track).

Bounded ("natural") relative orbits satisfy the drift condition ``ẏ₀ = −2n x₀``; they are the
2:1 ellipses

.. math::

    x = b\\cos θ,\\quad y = y_c - 2b\\sin θ,\\quad z = c\\cos(θ + ψ),\\qquad θ = nt + α,

built by :func:`bounded_orbit_state`, :func:`natural_motion_circumnavigation` and
:func:`passive_safety_ellipse`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from orbits._checks import check_finite, check_last_axis, check_positive, check_times
from orbits.hill import inertial_from_hill
from orbits.two_body import MU_EARTH_M3_S2, relative_trajectory, state_from_elements

__all__ = [
    "mean_motion",
    "system_matrix",
    "stm",
    "propagate",
    "apply_impulse",
    "TwoImpulseTransfer",
    "two_impulse_transfer",
    "drift_condition",
    "along_track_drift_rate",
    "along_track_drift_per_orbit",
    "bounded_orbit_state",
    "natural_motion_circumnavigation",
    "passive_safety_ellipse",
    "min_radial_cross_track_separation",
    "CwError",
    "cw_error",
]


def _check_n(n: float) -> float:
    arr = check_positive(n, name="n")
    if arr.ndim != 0:
        raise ValueError(f"n: expected a scalar mean motion (rad/s), got shape {arr.shape}")
    return float(arr)


def _check_state(x: ArrayLike, name: str) -> np.ndarray:
    return check_last_axis(x, 6, name=name)


def mean_motion(a_m: ArrayLike, *, mu_m3_s2: float = MU_EARTH_M3_S2) -> np.ndarray:
    """Mean motion ``n = √(μ/a³)`` (rad/s) of a chief orbit of semi-major axis ``a_m`` (m, > 0)."""
    a = check_positive(a_m, name="a_m")
    mu = float(check_positive(mu_m3_s2, name="mu_m3_s2"))
    n = np.sqrt(mu / a**3)
    return n[()] if n.ndim == 0 else n


def system_matrix(n: float) -> np.ndarray:
    """The CW dynamics matrix A, ``ẋ_H = A x_H`` (6×6), for mean motion ``n`` (rad/s)."""
    n = _check_n(n)
    A = np.zeros((6, 6))
    A[0:3, 3:6] = np.eye(3)
    A[3, 0] = 3.0 * n * n
    A[3, 4] = 2.0 * n
    A[4, 3] = -2.0 * n
    A[5, 2] = -n * n
    return A


def stm(t_s: ArrayLike, n: float) -> np.ndarray:
    """Closed-form CW state transition matrix Φ(t), ``x_H(t) = Φ(t) x_H(0)``.

    Parameters
    ----------
    t_s : array_like, any shape (...)
        Time since the initial state (s); negative values propagate backwards.
    n : float
        Chief mean motion (rad/s), > 0.

    Returns
    -------
    Phi : ndarray, shape (..., 6, 6)
        With ``s = sin nt``, ``c = cos nt``::

            x  = (4−3c) x₀ + s/n ẋ₀ + 2(1−c)/n ẏ₀
            y  = 6(s−nt) x₀ + y₀ − 2(1−c)/n ẋ₀ + (4s−3nt)/n ẏ₀
            z  = c z₀ + s/n ż₀
            ẋ  = 3n s x₀ + c ẋ₀ + 2s ẏ₀
            ẏ  = −6n(1−c) x₀ − 2s ẋ₀ + (4c−3) ẏ₀
            ż  = −n s z₀ + c ż₀

        It satisfies Φ(0) = I, Φ(t₁+t₂) = Φ(t₁)Φ(t₂) and dΦ/dt = AΦ (:func:`system_matrix`).
    """
    t = check_finite(t_s, name="t_s")
    n = _check_n(n)
    nt = n * t
    s, c = np.sin(nt), np.cos(nt)
    # 1 − cos(nt) = 2 sin²(nt/2) avoids cancellation for small nt.
    omc = 2.0 * np.sin(0.5 * nt) ** 2
    Phi = np.zeros(t.shape + (6, 6))
    Phi[..., 0, 0] = 4.0 - 3.0 * c
    Phi[..., 0, 3] = s / n
    Phi[..., 0, 4] = 2.0 * omc / n
    Phi[..., 1, 0] = 6.0 * (s - nt)
    Phi[..., 1, 1] = 1.0
    Phi[..., 1, 3] = -2.0 * omc / n
    Phi[..., 1, 4] = (4.0 * s - 3.0 * nt) / n
    Phi[..., 2, 2] = c
    Phi[..., 2, 5] = s / n
    Phi[..., 3, 0] = 3.0 * n * s
    Phi[..., 3, 3] = c
    Phi[..., 3, 4] = 2.0 * s
    Phi[..., 4, 0] = -6.0 * n * omc
    Phi[..., 4, 3] = -2.0 * s
    Phi[..., 4, 4] = 4.0 * c - 3.0
    Phi[..., 5, 2] = -n * s
    Phi[..., 5, 5] = c
    return Phi


def propagate(x0_H: ArrayLike, t_s: ArrayLike, n: float) -> np.ndarray:
    """Propagate CW states to many epochs at once (one matrix product, no Python loop).

    Parameters
    ----------
    x0_H : array_like, shape (..., 6)
        Initial relative states ``[x, y, z, ẋ, ẏ, ż]`` in H (m, m/s), at t = 0.
    t_s : array_like, shape (T,)
        Epochs (s) since the initial state (a scalar is treated as ``(1,)``).
    n : float
        Chief mean motion (rad/s).

    Returns
    -------
    x_H : ndarray, shape (..., T, 6)
        States at each epoch.
    """
    x0 = _check_state(x0_H, "x0_H")
    t = check_times(t_s)
    Phi = stm(t, n)  # (T, 6, 6)
    T = t.shape[0]
    # M[j, t*6 + i] = Phi[t, i, j]  →  out[k, t*6 + i] = Σ_j x0[k, j] Phi[t, i, j]
    M = Phi.transpose(2, 0, 1).reshape(6, T * 6)
    out = x0.reshape(-1, 6) @ M
    return out.reshape(x0.shape[:-1] + (T, 6))


def apply_impulse(x_H: ArrayLike, dv_H: ArrayLike) -> np.ndarray:
    """State just after an impulsive velocity change ``dv_H`` (m/s, H components).

    Shapes ``x_H (..., 6)`` and ``dv_H (..., 3)`` broadcast; the position is unchanged.
    """
    x = _check_state(x_H, "x_H")
    dv = check_last_axis(dv_H, 3, name="dv_H")
    x, dv6 = np.broadcast_arrays(x, np.concatenate([np.zeros_like(dv), dv], axis=-1))
    return x + dv6


@dataclass(frozen=True)
class TwoImpulseTransfer:
    """Result of :func:`two_impulse_transfer`.

    Attributes
    ----------
    dv0_H : ndarray, shape (..., 3)
        First impulse at t = 0 (m/s, H); NaN where ``ok`` is False.
    dvf_H : ndarray, shape (..., 3)
        Second impulse at arrival, matching the target velocity (m/s, H); NaN where not ``ok``.
    total_dv_m_s : ndarray, shape (...)
        ``|dv0| + |dvf|`` (m/s); NaN where not ``ok``.
    ok : ndarray of bool, shape (...)
        False where the transfer time makes the position-from-velocity block Φ_rv singular
        (e.g. whole periods), so no unique transfer exists.
    failure_reason : str
        Empty when every transfer is ``ok``, else what went wrong.
    """

    dv0_H: np.ndarray
    dvf_H: np.ndarray
    total_dv_m_s: np.ndarray
    ok: np.ndarray
    failure_reason: str = ""


def two_impulse_transfer(x0_H: ArrayLike, xf_H: ArrayLike, tof_s: ArrayLike, n: float, *,
                         cond_max: float = 1e10) -> TwoImpulseTransfer:
    """Two-impulse CW transfer from state ``x0_H`` to state ``xf_H`` in time ``tof_s``.

    The first impulse solves ``Φ_rr r₀ + Φ_rv (v₀ + Δv₀) = r_f`` (Vallado 4th ed. §6.8,
    eq. 6-24 in this frame ordering); the second cancels the velocity mismatch at arrival.

    Parameters
    ----------
    x0_H, xf_H : array_like, shape (..., 6)
        Initial and wanted final states in H (m, m/s); broadcast against each other.
    tof_s : array_like, shape (...)
        Time of flight (s), > 0; broadcast against the states' batch shape.
    n : float
        Chief mean motion (rad/s).
    cond_max : float, keyword-only
        Transfers whose Φ_rv has a condition number above this are reported as not ``ok``.
    """
    x0 = _check_state(x0_H, "x0_H")
    xf = _check_state(xf_H, "xf_H")
    tof = check_positive(tof_s, name="tof_s")
    batch = np.broadcast_shapes(x0.shape[:-1], xf.shape[:-1], tof.shape)
    x0 = np.broadcast_to(x0, batch + (6,))
    xf = np.broadcast_to(xf, batch + (6,))
    Phi = stm(np.broadcast_to(tof, batch), n)
    Prr, Prv, Pvr, Pvv = Phi[..., :3, :3], Phi[..., :3, 3:], Phi[..., 3:, :3], Phi[..., 3:, 3:]
    cond = np.linalg.cond(Prv)
    ok = np.isfinite(cond) & (cond < cond_max)
    Prv_safe = np.where(ok[..., None, None], Prv, np.eye(3))
    rhs = xf[..., :3] - np.einsum("...ij,...j->...i", Prr, x0[..., :3])
    v0_req = np.linalg.solve(Prv_safe, rhs[..., None])[..., 0]
    dv0 = v0_req - x0[..., 3:]
    v_arr = np.einsum("...ij,...j->...i", Pvr, x0[..., :3]) + np.einsum("...ij,...j->...i", Pvv, v0_req)
    dvf = xf[..., 3:] - v_arr
    nan = np.where(ok, 1.0, np.nan)
    total = (np.linalg.norm(dv0, axis=-1) + np.linalg.norm(dvf, axis=-1)) * nan
    reason = "" if np.all(ok) else "transfer time makes Phi_rv singular (no unique transfer)"
    return TwoImpulseTransfer(dv0 * nan[..., None], dvf * nan[..., None], total, ok, reason)


def drift_condition(x_H: ArrayLike, n: float) -> np.ndarray:
    """Drift-condition residual ``ẏ + 2n x`` (m/s); zero iff the in-plane motion is bounded.

    Shape ``(..., 6) → (...)``.
    """
    x = _check_state(x_H, "x_H")
    n = _check_n(n)
    return x[..., 4] + 2.0 * n * x[..., 0]


def along_track_drift_rate(x_H: ArrayLike, n: float) -> np.ndarray:
    """Secular along-track drift rate ``−3(ẏ + 2n x)`` (m/s) of a CW state, the coefficient of
    ``t`` in y(t) (from Φ: y ∋ −(6n x₀ + 3ẏ₀) t).  Shape ``(..., 6) → (...)``."""
    return -3.0 * drift_condition(x_H, n)


def along_track_drift_per_orbit(x_H: ArrayLike, n: float) -> np.ndarray:
    """Along-track displacement per chief orbit, ``2π/n`` × :func:`along_track_drift_rate` (m)."""
    return along_track_drift_rate(x_H, n) * (2.0 * np.pi / _check_n(n))


def bounded_orbit_state(*, n: float, radial_amplitude_m: ArrayLike, phase_rad: ArrayLike = 0.0,
                        cross_track_amplitude_m: ArrayLike = 0.0,
                        cross_track_phase_rad: ArrayLike = 0.0,
                        along_track_offset_m: ArrayLike = 0.0) -> np.ndarray:
    """Initial state of a drift-free (bounded) CW relative orbit.

    ``x = b cos θ``, ``y = y_c − 2b sin θ``, ``z = c cos(θ + ψ)`` with ``θ = nt + α``: a 2:1
    ellipse in the orbit plane (radial semi-axis b, along-track semi-axis 2b) centred ``y_c``
    along-track, plus a cross-track oscillation.

    Parameters
    ----------
    n : float
        Chief mean motion (rad/s).
    radial_amplitude_m : array_like
        b (m), ≥ 0.
    phase_rad : array_like
        α, the in-plane phase at t = 0 (rad); α = 0 starts at the radial maximum.
    cross_track_amplitude_m : array_like
        c (m), ≥ 0.
    cross_track_phase_rad : array_like
        ψ, the cross-track phase relative to the in-plane one (rad).
    along_track_offset_m : array_like
        y_c (m), the along-track centre of the ellipse.

    Returns
    -------
    x0_H : ndarray, shape (..., 6)
        All arguments broadcast; the state satisfies :func:`drift_condition` = 0.
    """
    n = _check_n(n)
    b = check_finite(radial_amplitude_m, name="radial_amplitude_m")
    c = check_finite(cross_track_amplitude_m, name="cross_track_amplitude_m")
    if np.any(b < 0):
        raise ValueError(f"radial_amplitude_m: must be >= 0, got {b[b < 0].ravel()[0]!r}")
    if np.any(c < 0):
        raise ValueError(f"cross_track_amplitude_m: must be >= 0, got {c[c < 0].ravel()[0]!r}")
    alpha = check_finite(phase_rad, name="phase_rad")
    psi = check_finite(cross_track_phase_rad, name="cross_track_phase_rad")
    yc = check_finite(along_track_offset_m, name="along_track_offset_m")
    b, c, alpha, psi, yc = np.broadcast_arrays(b, c, alpha, psi, yc)
    ca, sa = np.cos(alpha), np.sin(alpha)
    cz, sz = np.cos(alpha + psi), np.sin(alpha + psi)
    return np.stack([b * ca, yc - 2.0 * b * sa, c * cz,
                     -b * n * sa, -2.0 * b * n * ca, -c * n * sz], axis=-1)


def natural_motion_circumnavigation(semi_major_m: ArrayLike, *, n: float,
                                    phase_rad: ArrayLike = 0.0,
                                    cross_track_amplitude_m: ArrayLike = 0.0,
                                    cross_track_phase_rad: ArrayLike = 0.0) -> np.ndarray:
    """Natural-motion circumnavigation: a bounded relative orbit centred on the chief.

    Parameters
    ----------
    semi_major_m : array_like
        Along-track semi-axis 2b of the 2:1 in-plane ellipse (m); the radial semi-axis is half.
    n : float
        Chief mean motion (rad/s).
    phase_rad, cross_track_amplitude_m, cross_track_phase_rad : array_like
        As in :func:`bounded_orbit_state`.

    Returns
    -------
    x0_H : ndarray, shape (..., 6)
    """
    a = check_finite(semi_major_m, name="semi_major_m")
    if np.any(a < 0):
        raise ValueError(f"semi_major_m: must be >= 0, got {a[a < 0].ravel()[0]!r}")
    return bounded_orbit_state(n=n, radial_amplitude_m=0.5 * a, phase_rad=phase_rad,
                               cross_track_amplitude_m=cross_track_amplitude_m,
                               cross_track_phase_rad=cross_track_phase_rad)


def passive_safety_ellipse(radial_amplitude_m: ArrayLike, cross_track_amplitude_m: ArrayLike, *,
                           n: float, phase_rad: ArrayLike = 0.0,
                           along_track_offset_m: ArrayLike = 0.0) -> np.ndarray:
    """Passive-safety ellipse: radial and cross-track motions a quarter period apart.

    With ``z = c sin θ`` against ``x = b cos θ`` (ψ = −π/2, parallel relative e/i vectors) the
    deputy never crosses the along-track axis: its distance from it in the radial/cross-track
    plane stays ≥ min(b, c), so an along-track drift (e.g. a missed burn) cannot bring it into
    the chief.  See D'Amico & Montenbruck (2006), J. Guid. Control Dyn. 29(3):554–563.

    Parameters
    ----------
    radial_amplitude_m, cross_track_amplitude_m : array_like
        b and c (m), ≥ 0.
    n : float
        Chief mean motion (rad/s).
    phase_rad, along_track_offset_m : array_like
        α and y_c as in :func:`bounded_orbit_state`.

    Returns
    -------
    x0_H : ndarray, shape (..., 6)
    """
    return bounded_orbit_state(n=n, radial_amplitude_m=radial_amplitude_m, phase_rad=phase_rad,
                               cross_track_amplitude_m=cross_track_amplitude_m,
                               cross_track_phase_rad=-0.5 * np.pi,
                               along_track_offset_m=along_track_offset_m)


def min_radial_cross_track_separation(x_H: ArrayLike, n: float, *, samples: int = 2048) -> np.ndarray:
    """Smallest distance from the along-track axis, ``min_t √(x² + z²)`` over one orbit (m).

    Uses the CW solution (including any radial offset of a drifting state) sampled at
    ``samples`` points of one period, then refined by a parabola through the best sample;
    relative accuracy ~1e-9.  Shape ``(..., 6) → (...)``.
    """
    x = _check_state(x_H, "x_H")
    n = _check_n(n)
    t = np.linspace(0.0, 2 * np.pi / n, samples, endpoint=False)
    Phi = stm(t, n)
    xz = np.einsum("tij,...j->...ti", Phi[:, [0, 2], :], x)
    d2 = np.einsum("...ti,...ti->...t", xz, xz)
    k = np.argmin(d2, axis=-1)
    km, kp = (k - 1) % samples, (k + 1) % samples
    f0 = np.take_along_axis(d2, k[..., None], -1)[..., 0]
    fm = np.take_along_axis(d2, km[..., None], -1)[..., 0]
    fp = np.take_along_axis(d2, kp[..., None], -1)[..., 0]
    curv = fm - 2 * f0 + fp
    with np.errstate(invalid="ignore", divide="ignore"):
        fmin = np.where(curv > 0, f0 - (fp - fm) ** 2 / (8 * curv), f0)
    return np.sqrt(np.maximum(fmin, 0.0))


@dataclass(frozen=True)
class CwError:
    """CW prediction against two-body truth, from :func:`cw_error`.

    Attributes
    ----------
    t_s : ndarray, shape (T,)
        Epochs (s).
    x_cw_H : ndarray, shape (..., T, 6)
        CW prediction of the relative state (m, m/s).
    x_true_H : ndarray, shape (..., T, 6)
        Two-body truth: both spacecraft propagated by Kepler, differenced in the chief's H.
    position_error_m : ndarray, shape (..., T)
        ``|r_cw − r_true|`` (m).
    velocity_error_m_s : ndarray, shape (..., T)
        ``|v_cw − v_true|`` (m/s).
    """

    t_s: np.ndarray
    x_cw_H: np.ndarray
    x_true_H: np.ndarray
    position_error_m: np.ndarray
    velocity_error_m_s: np.ndarray

    @property
    def max_position_error_m(self) -> np.ndarray:
        """Largest position error over the epochs, shape (...)."""
        return self.position_error_m.max(axis=-1)


def cw_error(x0_H: ArrayLike, t_s: ArrayLike, *, a_m: float | None = None,
             r_C0_N: ArrayLike | None = None, v_C0_N: ArrayLike | None = None,
             mu_m3_s2: float = MU_EARTH_M3_S2) -> CwError:
    """Error of the CW prediction of relative states against nonlinear two-body motion.

    The deputy's initial inertial state is built from ``x0_H`` exactly
    (:func:`orbits.hill.inertial_from_hill`), both spacecraft are propagated with Kepler's
    equation, and the truth is differenced in the chief's Hill frame at every epoch.  CW uses the
    chief's mean motion ``n = √(μ/a)/a``.  The difference is the linearisation error (terms of
    order ρ²/a) plus, for an eccentric chief, the eccentricity the CW model ignores.

    Parameters
    ----------
    x0_H : array_like, shape (..., 6)
        Initial relative states (m, m/s).
    t_s : array_like, shape (T,)
        Epochs (s).
    a_m : float, keyword-only
        Radius (m) of a circular equatorial chief orbit.  Give either this or the chief state.
    r_C0_N, v_C0_N : array_like, shape (3,), keyword-only
        Chief initial inertial state (m, m/s).
    mu_m3_s2 : float, keyword-only
        Gravitational parameter (m³/s²).

    Returns
    -------
    CwError
    """
    x0 = _check_state(x0_H, "x0_H")
    t = check_times(t_s)
    if (a_m is None) == (r_C0_N is None or v_C0_N is None):
        raise ValueError("a_m: give either a_m (circular chief) or both r_C0_N and v_C0_N")
    if a_m is not None:
        r_C0, v_C0 = state_from_elements(a_m, 0.0, 0.0, 0.0, 0.0, 0.0, mu_m3_s2=mu_m3_s2)
    else:
        r_C0 = check_last_axis(r_C0_N, 3, name="r_C0_N")
        v_C0 = check_last_axis(v_C0_N, 3, name="v_C0_N")
        if r_C0.shape != (3,) or v_C0.shape != (3,):
            raise ValueError(f"r_C0_N: expected one chief state of shape (3,), got {r_C0.shape}")
    r0n = float(np.linalg.norm(r_C0))
    energy = 0.5 * float(v_C0 @ v_C0) - mu_m3_s2 / r0n
    if energy >= 0.0:
        raise ValueError(f"v_C0_N: chief orbit is not elliptic (energy {energy!r} J/kg)")
    n = float(mean_motion(-mu_m3_s2 / (2.0 * energy), mu_m3_s2=mu_m3_s2))
    r_D0, v_D0 = inertial_from_hill(r_C0, v_C0, x0[..., :3], x0[..., 3:])
    x_true = relative_trajectory(r_C0, v_C0, r_D0, v_D0, t, mu_m3_s2=mu_m3_s2)
    x_cw = propagate(x0, t, n)
    d = x_cw - x_true
    return CwError(t, x_cw, x_true, np.linalg.norm(d[..., :3], axis=-1),
                   np.linalg.norm(d[..., 3:], axis=-1))
