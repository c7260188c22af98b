"""Observation constraints of 003 §1.2 (eq (1) and the listed conditions), vectorised over epochs and spacecraft.

Per spacecraft (arrays ``(..., N)``; margins in the constraint's unit, positive = satisfied):

1. **range**: ``d_min <= |r| <= d_max`` with ``d_min = λ R / tan(FoV/2)`` (003 eq 1) or, for a
   spherical activity region, ``R / sin(FoV/2)`` (flag P003-1); margin in m.
2. **pointing**: angle between the camera boresight and the line of sight to the target region's
   centre below a threshold; margin in rad.
5. **sun**: no boresight within ``sun_exclusion`` of the Sun direction, and the target lit (not in
   eclipse); margin in rad (−inf in eclipse).
6. **keep_out**: outside a sphere of radius ``keep_out_radius_m`` about the target; margin in m.

Per pair (arrays ``(..., N, N)``):

3. **axis_angle**: pairwise optical-axis angles inside ``[γ_min, γ_max]``; margin in rad.
4. **comm**: inter-spacecraft distance below the communication range; margin in m.

Constraints 5–6 go beyond the paper.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from formation.geometry import optical_axis_angles

__all__ = ["ObservationConstraints", "ConstraintEvaluation", "evaluate", "SINGLE", "PAIRWISE"]

SINGLE = ("range", "pointing", "sun", "keep_out")
PAIRWISE = ("axis_angle", "comm")


@dataclass(frozen=True)
class ObservationConstraints:
    """Parameters of the observation constraints (SI units; angles in rad).

    Attributes
    ----------
    fov_rad : float
        Full field-of-view angle of the cameras.
    target_radius_m : float
        Radius R of the target's activity region.
    d_max_m : float
        Largest useful observation range (e.g. 150 m).
    d_min_form : {"tan", "sin"}
        003 eq (1) (flat disk, ``λ R / tan(FoV/2)``) or the spherical form of flag P003-1.
    d_min_lambda : float
        λ of 003 eq (1) (1.1 with the tan form covers a spherical region, flag P003-1,
        docs/papers.md#p003-1).
    pointing_max_rad : float
        Largest boresight–line-of-sight angle.
    axis_angle_min_rad, axis_angle_max_rad : float
        Window for pairwise optical-axis angles γ.
    comm_range_m : float
        Largest inter-spacecraft distance.
    sun_exclusion_rad : float
        Smallest boresight–Sun angle (0 disables).
    keep_out_radius_m : float
        Radius of the keep-out sphere about the target (0 disables).
    """

    fov_rad: float = np.deg2rad(20.0)
    target_radius_m: float = 5.0
    d_max_m: float = 150.0
    d_min_form: str = "sin"
    d_min_lambda: float = 1.0
    pointing_max_rad: float = np.deg2rad(5.0)
    axis_angle_min_rad: float = np.deg2rad(5.0)
    axis_angle_max_rad: float = np.deg2rad(30.0)
    comm_range_m: float = 1000.0
    sun_exclusion_rad: float = np.deg2rad(30.0)
    keep_out_radius_m: float = 20.0

    def __post_init__(self) -> None:
        for name in ("fov_rad", "target_radius_m", "d_max_m", "d_min_lambda", "pointing_max_rad", "comm_range_m"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name}: must be positive, got {v!r}")
        if not 0 < self.fov_rad < np.pi:
            raise ValueError(f"fov_rad: must be in (0, pi), got {self.fov_rad!r}")
        if self.d_min_form not in ("tan", "sin"):
            raise ValueError(f"d_min_form: must be 'tan' or 'sin', got {self.d_min_form!r}")
        if not 0 <= self.axis_angle_min_rad <= self.axis_angle_max_rad <= np.pi:
            raise ValueError(
                f"axis_angle_min_rad, axis_angle_max_rad: need 0 <= min <= max <= pi, got "
                f"{self.axis_angle_min_rad!r}, {self.axis_angle_max_rad!r}"
            )
        for name in ("sun_exclusion_rad", "keep_out_radius_m"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name}: must be >= 0, got {getattr(self, name)!r}")
        conflicts = []
        if self.d_min_m > self.d_max_m:
            conflicts.append(f"range window (d_min {self.d_min_m:.3g} m > d_max {self.d_max_m:.3g} m)")
        if self.keep_out_radius_m > self.d_max_m:
            conflicts.append(f"keep-out radius {self.keep_out_radius_m:.3g} m > d_max {self.d_max_m:.3g} m")
        if conflicts:
            raise ValueError("infeasible constraints: " + "; ".join(conflicts))

    @property
    def d_min_m(self) -> float:
        """Minimum observation distance: 003 eq (1), or the sine form of flag P003-1."""
        half = 0.5 * self.fov_rad
        if self.d_min_form == "tan":
            return float(self.d_min_lambda * self.target_radius_m / np.tan(half))
        return float(self.d_min_lambda * self.target_radius_m / np.sin(half))

    @property
    def range_window_m(self) -> tuple[float, float]:
        """Usable range ``[max(d_min, keep-out), d_max]``."""
        return max(self.d_min_m, self.keep_out_radius_m), self.d_max_m


@dataclass(frozen=True)
class ConstraintEvaluation:
    """Margins of every constraint.

    Attributes
    ----------
    margins : dict[str, ndarray]
        ``"range", "pointing", "sun", "keep_out"`` → ``(..., N)``; ``"axis_angle", "comm"`` →
        ``(..., N, N)`` (diagonal set to +inf).  Positive means satisfied.
    units : dict[str, str]
        Unit of each margin.
    """

    margins: dict[str, np.ndarray]
    units: dict[str, str] = field(default_factory=dict)

    @property
    def single_ok(self) -> np.ndarray:
        """(..., N) bool: every per-spacecraft constraint holds."""
        return np.all(np.stack([self.margins[k] >= 0 for k in SINGLE], 0), axis=0)

    @property
    def pair_ok(self) -> np.ndarray:
        """(..., N, N) bool: every pairwise constraint holds."""
        return np.all(np.stack([self.margins[k] >= 0 for k in PAIRWISE], 0), axis=0)

    def reasons(self, index: tuple[int, ...], spacecraft: int) -> list[str]:
        """Why spacecraft ``spacecraft`` fails its own constraints at epoch ``index`` (empty if it passes)."""
        out = []
        for k in SINGLE:
            m = float(self.margins[k][index + (spacecraft,)])
            if m < 0:
                out.append(f"{k} (margin {m:.3g} {self.units.get(k, '')})".replace(" )", ")"))
        return out

    def set_ok(self, members: ArrayLike) -> np.ndarray:
        """(...,) bool: the subset ``members`` satisfies every single and pairwise constraint."""
        idx = np.asarray(members, dtype=int)
        single = np.all(self.single_ok[..., idx], axis=-1)
        pair = np.all(self.pair_ok[..., idx[:, None], idx[None, :]], axis=(-1, -2))
        return single & pair


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def evaluate(
    constraints: ObservationConstraints,
    r_ST_H: ArrayLike,
    *,
    boresight_H: ArrayLike | None = None,
    sun_H: ArrayLike | None = None,
    target_lit: ArrayLike | bool = True,
) -> ConstraintEvaluation:
    """Evaluate all constraints for spacecraft at ``r_ST_H``.

    Parameters
    ----------
    constraints : ObservationConstraints
    r_ST_H : (..., N, 3) array_like
        Spacecraft positions relative to the target region's centre, H components, m.
    boresight_H : (..., N, 3) array_like, optional
        Camera optical axes in H; default: each camera points at the target centre.
    sun_H : (..., 3) array_like, optional
        Unit Sun direction in H at each epoch; default: no Sun-exclusion check (margin +inf).
    target_lit : (...,) bool array_like
        False where the target is in Earth's shadow (from ``orbits.environment``).
    """
    r = np.asarray(r_ST_H, dtype=float)
    if r.ndim < 2 or r.shape[-1] != 3:
        raise ValueError(f"r_ST_H: expected shape (..., N, 3), got {r.shape}")
    c = constraints
    dist = np.linalg.norm(r, axis=-1)
    los = -_unit(np.where(dist[..., None] > 0, r, np.array([0.0, 0.0, 1.0])))  # spacecraft → target
    b = los if boresight_H is None else _unit(np.asarray(boresight_H, dtype=float))
    d_lo = c.d_min_m
    m_range = np.minimum(dist - d_lo, c.d_max_m - dist)
    point_ang = np.arctan2(np.linalg.norm(np.cross(b, los), axis=-1), np.sum(b * los, -1))
    m_point = c.pointing_max_rad - point_ang
    m_keep = dist - c.keep_out_radius_m
    lit = np.asarray(target_lit, dtype=bool)
    if sun_H is None or c.sun_exclusion_rad == 0:
        m_sun = np.full(dist.shape, np.inf)
    else:
        s = _unit(np.asarray(sun_H, dtype=float))[..., None, :]
        sun_ang = np.arctan2(np.linalg.norm(np.cross(b, s), axis=-1), np.sum(b * s, -1))
        m_sun = sun_ang - c.sun_exclusion_rad
    m_sun = np.where(lit[..., None] if lit.ndim else lit, m_sun, -np.inf)

    gam = optical_axis_angles(b)
    m_axis = np.minimum(gam - c.axis_angle_min_rad, c.axis_angle_max_rad - gam)
    sep = np.linalg.norm(r[..., :, None, :] - r[..., None, :, :], axis=-1)
    m_comm = c.comm_range_m - sep
    n = r.shape[-2]
    eye = np.eye(n, dtype=bool)
    m_axis = np.where(eye, np.inf, m_axis)
    m_comm = np.where(eye, np.inf, m_comm)
    margins = {"range": m_range, "pointing": m_point, "sun": m_sun, "keep_out": m_keep,
               "axis_angle": m_axis, "comm": m_comm}
    units = {"range": "m", "pointing": "rad", "sun": "rad", "keep_out": "m", "axis_angle": "rad", "comm": "m"}
    return ConstraintEvaluation(margins=margins, units=units)
