"""Symmetric n-view observation geometry (003 §3.1) and look-at camera poses.

n cameras sit at the same distance ``d`` from the target's centre, evenly spaced in azimuth on a
cone of half-angle φ about the geometry axis ``ẑ_G``, each looking at the target.  The angle between
two boresights ``k`` apart in azimuth is given by

    cos γ_k = cos²φ + sin²φ cos(2πk/n),

so requiring the *adjacent* pairs to be at the axis angle γ gives ``sin φ = sin(γ/2) / sin(π/n)``
(for n = 3 this is ``sin φ = (2/√3) sin(γ/2)``, i.e. ``cos γ = 1 − (3/2) sin² φ``; for n = 2 it is φ = γ/2, the two
cameras at azimuth ±γ/2 in one plane).  For n = 2 and 3 every pair is adjacent, so every pair of
optical axes is at γ.  For n >= 4 no arrangement of n lines through a point can have all pairwise
angles equal to an arbitrary γ (at most 6 equiangular lines exist in 3-D, and only at the
particular angle arccos(1/√5) for 6); coobs keeps the cone and makes the adjacent pairs equal to
γ, the others larger.  The geometry exists for ``γ <= 2π/n`` (φ <= 90°).

The geometry frame G is placed in H by ``orientation = q_HG``; by default G = H, so the cone axis is
the orbit normal z_H.  Camera frames follow OpenCV (z along the boresight, x right, y down), with
the image "up" (−y_C) towards the cone axis side ``ẑ_G`` (for the camera on the axis, n = 1, the
image up is ``x̂_G``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from attitude.quaternion import check_quat, check_vec3, matrix_from_quat

__all__ = ["ViewGeometry", "cone_half_angle", "look_at", "symmetric_views", "optical_axis_angles"]


@dataclass(frozen=True)
class ViewGeometry:
    """A set of cameras observing the target.

    Attributes
    ----------
    r_CT_H : (n, 3) ndarray
        Camera positions relative to the target's centre, H components, m.
    T_CW : (n, 4, 4) ndarray
        Camera-from-world poses (world W = H, origin at the target's centre).
    boresight_H : (n, 3) ndarray
        Unit optical axes (camera z) in H.
    cone_half_angle_rad : float
        φ, the half-angle of the cone about the geometry axis.
    axis_H : (3,) ndarray
        Geometry axis ``ẑ_G`` in H (the cameras' mean direction from the target).
    """

    r_CT_H: np.ndarray
    T_CW: np.ndarray
    boresight_H: np.ndarray
    cone_half_angle_rad: float
    axis_H: np.ndarray

    @property
    def n_views(self) -> int:
        return int(self.r_CT_H.shape[0])

    @property
    def baselines_m(self) -> np.ndarray:
        """(n, n) distances between cameras, m."""
        d = self.r_CT_H[:, None, :] - self.r_CT_H[None, :, :]
        return np.linalg.norm(d, axis=-1)


def cone_half_angle(n: int, axis_angle_rad: float) -> float:
    """φ with adjacent optical axes at ``axis_angle_rad``: ``sin φ = sin(γ/2) / sin(π/n)``.

    The geometry exists for ``0 < γ <= 2π/n`` (φ from 0 to 90°); a larger γ would fold back onto
    ``2π/n − γ`` through the sine (n = 2, γ = 190° would silently give 170°) and is refused.
    ``ValueError`` for ``n < 1`` or γ outside that domain (γ is ignored for n = 1).
    """
    if not isinstance(n, int | np.integer) or n < 1:
        raise ValueError(f"n: number of views must be an integer >= 1, got {n!r}")
    if n == 1:
        return 0.0
    if not np.isfinite(axis_angle_rad) or axis_angle_rad <= 0:
        raise ValueError(f"axis_angle_rad: must be positive and finite, got {axis_angle_rad!r}")
    if axis_angle_rad > 2 * np.pi / n * (1.0 + 1e-12):
        raise ValueError(
            f"axis_angle_rad: {axis_angle_rad:.6g} rad is impossible for {n} views on a cone "
            f"(at most 2π/{n} = {2 * np.pi / n:.6g} rad)"
        )
    s = np.sin(0.5 * axis_angle_rad) / np.sin(np.pi / n)
    return float(np.arcsin(min(s, 1.0)))


def look_at(r_CT_H: ArrayLike, target_H: ArrayLike, up_H: ArrayLike) -> np.ndarray:
    """Camera-from-world poses ``T_CW (..., 4, 4)`` of cameras at ``r_CT_H`` looking at ``target_H``.

    Camera z points at the target; camera −y (image up) is as close as possible to ``up_H``.
    Raises ``ValueError`` when an argument is not finite or not ``(..., 3)``, when ``up_H`` is
    parallel to the line of sight or the camera is at the target.
    """
    r = check_vec3(r_CT_H, name="r_CT_H")
    tgt = np.broadcast_to(check_vec3(target_H, name="target_H"), r.shape)
    up = np.broadcast_to(check_vec3(up_H, name="up_H"), r.shape)
    z = tgt - r
    dist = np.linalg.norm(z, axis=-1, keepdims=True)
    if np.any(dist == 0):
        raise ValueError("r_CT_H: camera position coincides with the look-at point")
    z = z / dist
    x = np.cross(z, up)  # camera x = forward × up points right when y is down
    nx = np.linalg.norm(x, axis=-1, keepdims=True)
    if np.any(nx < 1e-9):
        raise ValueError("up_H: parallel to the line of sight; choose another up direction")
    x = x / nx
    y = np.cross(z, x)
    R_WC = np.stack([x, y, z], -1)  # columns: camera axes in W
    T = np.zeros(r.shape[:-1] + (4, 4))
    R_CW = np.swapaxes(R_WC, -1, -2)
    T[..., :3, :3] = R_CW
    T[..., :3, 3] = -(R_CW @ r[..., None])[..., 0]
    T[..., 3, 3] = 1.0
    return T


def symmetric_views(
    n: int,
    distance_m: float,
    axis_angle_deg: float,
    *,
    orientation: ArrayLike = (1.0, 0.0, 0.0, 0.0),
    target_center_H: ArrayLike = (0.0, 0.0, 0.0),
    azimuth_offset_rad: float = 0.0,
) -> ViewGeometry:
    """The symmetric n-view configuration of 003 §3.1 (module docstring).

    Parameters
    ----------
    n : int
        Number of views, >= 1.
    distance_m : float
        Distance of every camera from the target's centre, m, > 0.
    axis_angle_deg : float
        Angle between adjacent optical axes γ, degrees, in (0, 360/n] (finite, otherwise ignored,
        for n = 1).  Beyond 360/n the cone would fold back (``sin φ = sin(γ/2)/sin(π/n)``): refused.
    orientation : (4,) array_like, keyword-only
        ``q_HG``, placing the geometry frame in H (default: G = H, cone axis = orbit normal).
    target_center_H : (3,) array_like, keyword-only
        Centre the cameras look at, H components, m (finite).
    azimuth_offset_rad : float, keyword-only
        Azimuth of camera 0 about the cone axis, rad (finite).

    Raises
    ------
    ValueError
        One line naming the argument and its value, for any argument outside its domain.
    """
    if not isinstance(n, int | np.integer) or n < 1:
        raise ValueError(f"n: number of views must be an integer >= 1, got {n!r}")
    if not np.isfinite(distance_m) or distance_m <= 0:
        raise ValueError(f"distance_m: must be positive, got {distance_m!r}")
    if not np.isfinite(axis_angle_deg) or (n > 1 and axis_angle_deg <= 0):
        raise ValueError(f"axis_angle_deg: must be positive and finite, got {axis_angle_deg!r}")
    if n > 1 and axis_angle_deg > 360.0 / n * (1.0 + 1e-12):
        raise ValueError(f"axis_angle_deg: {axis_angle_deg:.6g} deg is impossible for {n} views on a cone "
                         f"(at most 360/{n} = {360.0 / n:.6g} deg)")
    if not np.isfinite(azimuth_offset_rad):
        raise ValueError(f"azimuth_offset_rad: must be finite, got {azimuth_offset_rad!r}")
    q_HG = check_quat(orientation, name="orientation")
    R_HG = matrix_from_quat(q_HG)
    c = check_vec3(target_center_H, name="target_center_H")
    if c.shape != (3,):
        raise ValueError(f"target_center_H: expected shape (3,), got {c.shape}")
    phi = cone_half_angle(int(n), np.deg2rad(axis_angle_deg))
    az = azimuth_offset_rad + 2.0 * np.pi * np.arange(n) / n
    u_G = np.stack([np.sin(phi) * np.cos(az), np.sin(phi) * np.sin(az), np.full(n, np.cos(phi))], -1)
    u_H = u_G @ R_HG.T
    r = c + distance_m * u_H
    axis_H = R_HG[:, 2]
    up = np.broadcast_to(axis_H if n > 1 else R_HG[:, 0], r.shape)
    # image up towards the cone axis side: for cameras off the axis use ẑ_G (never parallel to the
    # line of sight when φ < 90°); at φ = 90° fall back to the axis-perpendicular tangent.
    if phi > np.pi / 2 - 1e-9:
        up = np.broadcast_to(axis_H, r.shape)
    T = look_at(r, c, up)
    return ViewGeometry(r_CT_H=r - c, T_CW=T, boresight_H=-u_H, cone_half_angle_rad=phi, axis_H=axis_H)


def optical_axis_angles(boresight_H: ArrayLike) -> np.ndarray:
    """Pairwise angles (rad) between optical axes ``(..., n, 3) → (..., n, n)``."""
    b = np.asarray(boresight_H, dtype=float)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    cross = np.linalg.norm(np.cross(b[..., :, None, :], b[..., None, :, :]), axis=-1)
    dot = np.einsum("...id,...jd->...ij", b, b)
    return np.arctan2(cross, dot)
