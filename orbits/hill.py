"""The Hill (LVLH) frame H of a chief, and relative states in it.

H is centred on the chief C (in coobs: the target's centre of mass), with (``docs/conventions.md``)

* x radial outward, ``x̂ = r_C / |r_C|``,
* z along the orbit normal, ``ẑ = h / |h|`` with ``h = r_C × v_C``,
* y completing the right-handed triad, ``ŷ = ẑ × x̂`` (along-track, the direction of motion for
  a circular orbit).

``R_NH = [x̂ ŷ ẑ]`` (columns in N) maps H-components to N-components.  H rotates relative to N
with ``ω_HN = (r_C × v_C) / |r_C|²``; this is exact for a chief whose acceleration is radial
(two-body motion), and it is what makes the relative *velocity as seen in H* (the CW state) differ
from the plain inertial velocity difference:

.. math::

    \\dot\\rho_H = R_{HN}\\,(v_D - v_C - \\omega_{HN} \\times (r_D - r_C)).

All functions are vectorised: chief arrays ``(..., 3)`` and deputy arrays ``(..., 3)`` broadcast
against each other (e.g. chief ``(T, 3)`` over T epochs with deputies ``(K, T, 3)``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from orbits._checks import check_last_axis

__all__ = ["hill_frame", "hill_angular_velocity", "hill_from_inertial", "inertial_from_hill"]


def _frame_and_rate(r_C_N: np.ndarray, v_C_N: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r_norm = np.linalg.norm(r_C_N, axis=-1)
    if np.any(r_norm == 0.0):
        raise ValueError("r_C_N: chief position has zero norm (no Hill frame)")
    h = np.cross(r_C_N, v_C_N)
    h_norm = np.linalg.norm(h, axis=-1)
    # A rectilinear chief (v parallel to r) has no orbit plane.
    bad = h_norm <= 1e-12 * r_norm * np.maximum(np.linalg.norm(v_C_N, axis=-1), 1e-300)
    if np.any(bad):
        raise ValueError("v_C_N: chief velocity is parallel to its position (no orbit normal)")
    x_hat = r_C_N / r_norm[..., None]
    z_hat = h / h_norm[..., None]
    y_hat = np.cross(z_hat, x_hat)
    R_NH = np.stack([x_hat, y_hat, z_hat], axis=-1)
    omega_HN_N = h / (r_norm**2)[..., None]
    return R_NH, omega_HN_N


def hill_frame(r_C_N: ArrayLike, v_C_N: ArrayLike) -> np.ndarray:
    """Rotation matrix ``R_NH`` of the chief's Hill frame (H → N components).

    Parameters
    ----------
    r_C_N, v_C_N : array_like, shape (..., 3)
        Chief position (m) and velocity (m/s) in the inertial frame N.

    Returns
    -------
    R_NH : ndarray, shape (..., 3, 3)
        Columns are x̂ (radial), ŷ (along-track), ẑ (orbit normal) in N components.
    """
    r = check_last_axis(r_C_N, 3, name="r_C_N")
    v = check_last_axis(v_C_N, 3, name="v_C_N")
    return _frame_and_rate(*np.broadcast_arrays(r, v))[0]


def hill_angular_velocity(r_C_N: ArrayLike, v_C_N: ArrayLike) -> np.ndarray:
    """Angular velocity ``ω_HN_N = (r × v)/|r|²`` of H relative to N, in N components (rad/s).

    Exact for a Keplerian chief (no out-of-plane acceleration).  Shapes ``(..., 3)``.
    """
    r = check_last_axis(r_C_N, 3, name="r_C_N")
    v = check_last_axis(v_C_N, 3, name="v_C_N")
    return _frame_and_rate(*np.broadcast_arrays(r, v))[1]


def hill_from_inertial(r_C_N: ArrayLike, v_C_N: ArrayLike, r_D_N: ArrayLike,
                       v_D_N: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Deputy state relative to the chief, in the chief's rotating Hill frame.

    Parameters
    ----------
    r_C_N, v_C_N : array_like, shape (..., 3)
        Chief inertial position (m) and velocity (m/s).
    r_D_N, v_D_N : array_like, shape (..., 3)
        Deputy inertial position (m) and velocity (m/s); broadcast against the chief's.

    Returns
    -------
    r_DC_H : ndarray, shape (..., 3)
        Deputy position relative to the chief, H components (m).
    v_DC_H : ndarray, shape (..., 3)
        Deputy velocity relative to the chief *as seen in the rotating frame H*, H components
        (m/s): ``R_HN (v_D − v_C − ω_HN × (r_D − r_C))``.  ``concatenate([r_DC_H, v_DC_H], -1)``
        is the state that :func:`orbits.cw.propagate` takes.
    """
    r_C = check_last_axis(r_C_N, 3, name="r_C_N")
    v_C = check_last_axis(v_C_N, 3, name="v_C_N")
    r_D = check_last_axis(r_D_N, 3, name="r_D_N")
    v_D = check_last_axis(v_D_N, 3, name="v_D_N")
    R_NH, omega = _frame_and_rate(*np.broadcast_arrays(r_C, v_C))
    dr = r_D - r_C
    dv = v_D - v_C - np.cross(omega, dr)
    r_DC_H = np.einsum("...ji,...j->...i", R_NH, dr)
    v_DC_H = np.einsum("...ji,...j->...i", R_NH, dv)
    return r_DC_H, v_DC_H


def inertial_from_hill(r_C_N: ArrayLike, v_C_N: ArrayLike, r_DC_H: ArrayLike,
                       v_DC_H: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`hill_from_inertial`: deputy inertial state from its Hill-frame state.

    Parameters
    ----------
    r_C_N, v_C_N : array_like, shape (..., 3)
        Chief inertial position (m) and velocity (m/s).
    r_DC_H, v_DC_H : array_like, shape (..., 3)
        Deputy position (m) and rotating-frame velocity (m/s) relative to the chief, in H.

    Returns
    -------
    r_D_N, v_D_N : ndarray, shape (..., 3)
        Deputy inertial position (m) and velocity (m/s):
        ``r_D = r_C + R_NH ρ``, ``v_D = v_C + R_NH ρ̇ + ω_HN × (R_NH ρ)``.
    """
    r_C = check_last_axis(r_C_N, 3, name="r_C_N")
    v_C = check_last_axis(v_C_N, 3, name="v_C_N")
    rho = check_last_axis(r_DC_H, 3, name="r_DC_H")
    rho_dot = check_last_axis(v_DC_H, 3, name="v_DC_H")
    R_NH, omega = _frame_and_rate(*np.broadcast_arrays(r_C, v_C))
    dr = np.einsum("...ij,...j->...i", R_NH, rho)
    dv = np.einsum("...ij,...j->...i", R_NH, rho_dot) + np.cross(omega, dr)
    return r_C + dr, v_C + dv
