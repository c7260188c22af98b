"""The Earth behind the target as a low-orbit observer sees it, and the Earth's albedo light on the target.

Geometry
    The target's centre of mass is the origin of the Hill frame H (x radial outward, y along-track,
    z orbit normal), so the Earth's centre is at ``r_E_H = (-orbit_radius_m, 0, 0)``.  A camera ray
    ``c_H + t d_H`` sees the Earth where it meets the sphere of radius ``earth_radius_m`` (the first
    root of the ray–sphere quadratic), black sky elsewhere (no stars, no atmosphere).  From the
    target the Earth fills the cone of half-angle ``ρ = asin(R_E / r)`` about nadir (61.6° at
    870 km altitude: it subtends ≈ 123°), so a camera looking at the target from above, or along
    the track, has the Earth behind it.  The ground does not move under the H frame here: between
    two epochs the background changes through the cameras' motion only (the ≈ 7 km/s ground drift
    of a real orbit turns the background by ≈ 0.04° in 0.1 s).

Radiance (the renderer's units: 1 = a white Lambertian surface facing the full Sun)
    A Lambertian ground lit by parallel sunlight, ``L = a(p) · max(0, m·s)``, ``m`` the outward
    normal at the hit point and ``s`` the direction to the Sun: a day/night terminator at
    ``m·s = 0``, a black night side (no city lights).  The surface albedo ``a(p)`` is procedural
    and seeded (:meth:`EarthScene.surface_albedo`): oceans (0.06), land (0.10–0.30) and clouds
    (0.35–0.85) whose cover and brightness are fractional Brownian motion of 2-D value noise on a
    gnomonic map about the sub-target point, with octaves from 1600 km down to 100 m (clouds carry
    the fine structure: they are what a feature detector finds in the background).  Octaves finer
    than a pixel's ground footprint fade to their mean (anti-aliasing, as a mip map does).  With
    the default ``albedo = 0.3`` these are the values; another ``albedo`` scales them by
    ``albedo / 0.3``.

Albedo light on the target (:meth:`EarthScene.albedo_irradiance`)
    The irradiance of a target surface of normal ``n`` from the visible Earth cap, in units of the
    direct solar irradiance,

        ``E(n) / E_sun = (1/π) ∫_cap L(ω) max(0, n·ω) dω``,   ``L(ω) = A · max(0, m(ω)·s)``,

    the radiance of a Lambertian Earth of uniform albedo ``A`` (``albedo``), integrated over the
    cap by a fixed midpoint rule in ``(cos θ, φ)`` (equal solid angles).  A target point of
    diffuse albedo ``a_T`` then has radiance ``a_T · E(n) / E_sun``.  This is the albedo load of
    spacecraft thermal analysis (Gilmore, *Spacecraft Thermal Control Handbook*, vol. 1, 2nd ed.,
    2002, ch. 2, "Spacecraft thermal environments"): for a plate facing nadir under a uniformly lit
    Earth it is ``A (R_E/r)²``, ``(R_E/r)² = sin²ρ`` being the configuration factor from a plate
    facing a sphere's centre to the sphere.  Not modelled: the target's occlusion of
    its own Earth light (every surface facing the cap gets all of it), the texture's albedo
    variations in the light, the atmosphere.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from vision.camera import PinholeCamera

__all__ = ["EARTH_RADIUS_M", "EarthScene"]

#: equatorial radius of the Earth (WGS-84), metres
EARTH_RADIUS_M = 6_378_137.0
#: the albedo the procedural texture's values are designed for (scaled by ``albedo / 0.3``)
_DESIGN_ALBEDO = 0.3
#: noise lattice size (per octave the lattice repeats after this many cells)
_TABLE = 8192
#: cell size of the coarsest octave, metres, and the number of octaves (finest 1.6e6 / 2**14 ≈ 98 m)
_CELL0_M = 1.6e6
_OCTAVES = 15
_LAND_OCTAVES = range(0, 8)
_CLOUD_OCTAVES = range(2, _OCTAVES)


def _smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


@dataclass(frozen=True, eq=False)
class EarthScene:
    """The Earth below a target on a circular orbit (see the module docstring for the models).

    Attributes
    ----------
    orbit_radius_m : float
        Distance of the target from the Earth's centre, metres (``R_E`` + altitude).
    rng : numpy.random.Generator
        Draws the texture's noise tables once, at construction (the same Earth for every view).
    albedo : float
        Mean albedo ``A`` of the Earth (Bond albedo ≈ 0.3), in [0, 1]: the albedo light's
        uniform albedo and the texture's scale.
    earth_radius_m : float
        Radius of the Earth sphere, metres.
    quadrature : tuple of int
        ``(n_cos_theta, n_phi)`` directions of the albedo-light integral over the cap.
    """

    orbit_radius_m: float
    rng: np.random.Generator = field(repr=False)
    albedo: float = 0.3
    earth_radius_m: float = EARTH_RADIUS_M
    quadrature: tuple[int, int] = (32, 64)

    def __post_init__(self) -> None:
        r, R = float(self.orbit_radius_m), float(self.earth_radius_m)
        if not (np.isfinite(R) and R > 0):
            raise ValueError(f"earth_radius_m must be > 0, got {self.earth_radius_m!r}")
        if not (np.isfinite(r) and r > R):
            raise ValueError(f"orbit_radius_m must exceed the Earth's radius {R:g} m, got {self.orbit_radius_m!r}")
        if not (np.isfinite(self.albedo) and 0.0 <= float(self.albedo) <= 1.0):
            raise ValueError(f"albedo must be in [0, 1], got {self.albedo!r}")
        if len(self.quadrature) != 2 or min(int(q) for q in self.quadrature) < 1:
            raise ValueError(f"quadrature must be two positive counts, got {self.quadrature!r}")
        rng = np.random.default_rng(self.rng)
        object.__setattr__(self, "orbit_radius_m", r)
        object.__setattr__(self, "earth_radius_m", R)
        object.__setattr__(self, "albedo", float(self.albedo))
        object.__setattr__(self, "_perm", rng.permutation(_TABLE).astype(np.int64))
        object.__setattr__(self, "_values", rng.random(_TABLE).astype(np.float32))
        # lattice offsets per field (land, clouds) and octave, so no two octaves share a pattern
        object.__setattr__(self, "_offsets", rng.integers(0, _TABLE, size=(2, _OCTAVES, 2)))

    # --- geometry ------------------------------------------------------------------------------

    @property
    def r_E_H(self) -> np.ndarray:
        """Position of the Earth's centre relative to the target, Hill components, metres."""
        return np.array([-self.orbit_radius_m, 0.0, 0.0])

    @property
    def limb_half_angle_rad(self) -> float:
        """Angle from nadir to the Earth's limb seen from the target, ``asin(R_E / r)``."""
        return float(np.arcsin(self.earth_radius_m / self.orbit_radius_m))

    def intersect(self, origin_H: ArrayLike, d_H: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where rays ``origin_H + t d_H`` first meet the Earth.

        Parameters
        ----------
        origin_H : array_like, shape (3,)
            Ray origin relative to the target, Hill components, metres.
        d_H : array_like, shape (N, 3)
            Ray directions (any length; normalised here).

        Returns
        -------
        hit : ndarray (N,), bool
        m_H : ndarray (N, 3)
            Outward unit normal of the Earth at the hit point (NaN where ``hit`` is False).
        range_m : ndarray (N,)
            Distance from the origin to the hit point (inf where ``hit`` is False).
        """
        o = np.asarray(origin_H, dtype=float).reshape(3) - self.r_E_H
        d = np.asarray(d_H, dtype=float).reshape(-1, 3)
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        b = d @ o
        c = o @ o - self.earth_radius_m ** 2
        disc = b * b - c
        with np.errstate(invalid="ignore"):
            t = -b - np.sqrt(disc)
        hit = (disc >= 0) & (t > 0)
        t = np.where(hit, t, np.inf)
        m = np.full_like(d, np.nan)
        m[hit] = (o + t[hit, None] * d[hit]) / self.earth_radius_m
        return hit, m, t

    # --- texture and radiance ------------------------------------------------------------------

    def _noise(self, x: np.ndarray, y: np.ndarray, which: int, k: int) -> np.ndarray:
        """2-D value noise of octave ``k`` of field ``which`` at lattice coordinates ``(x, y)``, in [0, 1]."""
        xf, yf = np.floor(x), np.floor(y)
        tx, ty = (x - xf).astype(np.float32), (y - yf).astype(np.float32)
        tx = tx * tx * (3 - 2 * tx)
        ty = ty * ty * (3 - 2 * ty)
        ox, oy = self._offsets[which, k]
        i = xf.astype(np.int64) + ox
        j = yf.astype(np.int64) + oy
        P, V, M = self._perm, self._values, _TABLE - 1
        pi0, pi1 = P[i & M], P[(i + 1) & M]
        v00, v01 = V[P[(pi0 + j) & M]], V[P[(pi0 + j + 1) & M]]
        v10, v11 = V[P[(pi1 + j) & M]], V[P[(pi1 + j + 1) & M]]
        a = v00 + tx * (v10 - v00)
        b = v01 + tx * (v11 - v01)
        return a + ty * (b - a)

    def _fbm(self, x_m: np.ndarray, y_m: np.ndarray, footprint_m: np.ndarray, which: int, octaves: range,
             persistence: float) -> np.ndarray:
        """Fractional Brownian motion in [0, 1]; octaves finer than the footprint fade to their mean 0.5."""
        total = np.zeros(x_m.shape, dtype=np.float32)
        amp, norm = 1.0, 0.0
        fp_min = float(np.min(footprint_m)) if footprint_m.size else np.inf
        for k in octaves:
            cell = _CELL0_M / 2.0 ** k
            if cell > fp_min:   # some pixel resolves this octave
                w = np.clip(np.log2(cell / footprint_m), 0.0, 1.0).astype(np.float32)
                n = self._noise(x_m / cell, y_m / cell, which, k)
                total += amp * (w * n + (1 - w) * 0.5)
            else:
                total += amp * 0.5
            norm += amp
            amp *= persistence
        return total / np.float32(norm)

    def surface_albedo(self, m_H: ArrayLike, footprint_m: ArrayLike) -> np.ndarray:
        """Procedural albedo at Earth points of outward normal ``m_H`` (``(N, 3)``), seen with a pixel
        footprint of ``footprint_m`` metres (``(N,)``); float32 ``(N,)``.

        Points on the hemisphere away from the target (never visible from it) get the ocean's albedo.
        """
        m = np.asarray(m_H, dtype=float).reshape(-1, 3)
        fp = np.broadcast_to(np.asarray(footprint_m, dtype=float), (len(m),))
        front = m[:, 0] > 1e-3
        R = self.earth_radius_m
        mx = np.where(front, m[:, 0], 1.0)
        x_m, y_m = R * m[:, 1] / mx, R * m[:, 2] / mx          # gnomonic map about the sub-target point
        land_f = self._fbm(x_m, y_m, fp, 0, _LAND_OCTAVES, 0.55)
        cloud_f = self._fbm(x_m, y_m, fp, 1, _CLOUD_OCTAVES, 0.70)
        land = _smoothstep(0.545, 0.555, land_f)
        ground = 0.06 + land * (0.10 + 0.20 * _smoothstep(0.40, 0.60, cloud_f))
        cover = _smoothstep(0.50, 0.53, cloud_f)
        cloud = 0.35 + 0.5 * _smoothstep(0.50, 0.62, cloud_f)
        a = (1 - cover) * ground + cover * cloud
        a = np.where(front, a, 0.06) * np.float32(self.albedo / _DESIGN_ALBEDO)
        return a.astype(np.float32)

    def radiance(self, origin_H: ArrayLike, d_H: ArrayLike, sun_H: ArrayLike, *,
                 pixel_angle_rad: float = 0.0) -> np.ndarray:
        """Radiance seen along rays ``origin_H + t d_H`` (``(N, 3)``): the sunlit Earth, 0 on its night
        side and on the sky; float32 ``(N,)``.  ``pixel_angle_rad``: angular size of a pixel, for the
        ground footprint (0: every octave at full weight)."""
        hit, m, t = self.intersect(origin_H, d_H)
        out = np.zeros(len(hit), dtype=np.float32)
        if not hit.any():
            return out
        s = np.asarray(sun_H, dtype=float)
        s = s / np.linalg.norm(s)
        mh = m[hit]
        d = np.asarray(d_H, dtype=float).reshape(-1, 3)[hit]
        cos_view = np.abs(np.sum(mh * d, axis=1)) / np.linalg.norm(d, axis=1)
        fp = t[hit] * float(pixel_angle_rad) / np.maximum(cos_view, 0.05)
        out[hit] = self.surface_albedo(mh, fp) * np.maximum(mh @ s, 0.0).astype(np.float32)
        return out

    def background(self, camera: PinholeCamera, T_CW: ArrayLike, box: tuple[int, int, int, int],
                   sun_H: ArrayLike) -> np.ndarray:
        """Radiance of the Earth (or black sky) behind every pixel of ``box`` = ``(x0, y0, x1, y1)``,
        float32 ``(y1 - y0, x1 - x0)``, for a camera of pose ``T_CW`` (world = H)."""
        T = np.asarray(T_CW, dtype=float)
        R_CW = T[:3, :3]
        c_H = -R_CW.T @ T[:3, 3]
        x0, y0, x1, y1 = box
        uu, vv = np.meshgrid(np.arange(x0, x1, dtype=float), np.arange(y0, y1, dtype=float))
        d_C = np.stack([(uu - camera.cx) / camera.fx, (vv - camera.cy) / camera.fy, np.ones_like(uu)], -1)
        d_H = d_C.reshape(-1, 3) @ R_CW
        rad = self.radiance(c_H, d_H, sun_H, pixel_angle_rad=1.0 / np.sqrt(camera.fx * camera.fy))
        return rad.reshape(y1 - y0, x1 - x0)

    # --- albedo light ----------------------------------------------------------------------------

    def _cap_directions(self) -> tuple[np.ndarray, float]:
        """Unit directions ``(K, 3)`` (H) from the target into the Earth's cap, and the solid angle of each."""
        n_t, n_p = (int(q) for q in self.quadrature)
        cos_rho = np.cos(self.limb_half_angle_rad)
        ct = 1.0 - (np.arange(n_t) + 0.5) / n_t * (1.0 - cos_rho)
        ph = (np.arange(n_p) + 0.5) / n_p * 2 * np.pi
        ct, ph = np.meshgrid(ct, ph, indexing="ij")
        st = np.sqrt(1 - ct ** 2)
        w = np.stack([-ct, st * np.cos(ph), st * np.sin(ph)], -1).reshape(-1, 3)   # about nadir −x_H
        return w, 2 * np.pi * (1.0 - cos_rho) / (n_t * n_p)

    def albedo_irradiance(self, n_H: ArrayLike, sun_H: ArrayLike) -> np.ndarray:
        """Earth-albedo irradiance ``E(n)/E_sun`` on surfaces of unit normal ``n_H`` (``(N, 3)``) at the
        target (see the module docstring); float64 ``(N,)``."""
        n = np.asarray(n_H, dtype=float).reshape(-1, 3)
        out = np.zeros(len(n))
        if len(n) == 0 or self.albedo == 0.0:
            return out
        s = np.asarray(sun_H, dtype=float)
        s = s / np.linalg.norm(s)
        w, d_omega = self._cap_directions()
        hit, m, _ = self.intersect(np.zeros(3), w)
        L = np.where(hit, self.albedo * np.maximum(np.nan_to_num(m) @ s, 0.0), 0.0)
        keep = L > 0
        if not keep.any():
            return out
        w, L = w[keep], L[keep] * d_omega / np.pi
        # flat faces share normals: integrate once per distinct normal
        u, inv = np.unique(np.round(n, 9), axis=0, return_inverse=True)
        E = np.empty(len(u))
        for a in range(0, len(u), 4096):
            E[a:a + 4096] = np.maximum(u[a:a + 4096] @ w.T, 0.0) @ L
        return E[inv.reshape(-1)]
