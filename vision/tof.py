"""Time-of-flight (TOF) camera model and a cooperative marker target (paper 000).

The camera is a continuous-wave phase-measuring TOF camera of the MESA SR4000 class: a pinhole
camera (``fx, fy, cx, cy`` in pixels, no distortion) that measures, per pixel, the *radial* range
along the pixel ray and the amplitude (grey value) of the modulated return.  The geometry is
000 eq (2)–(5) in the corrected form (flag P000-1, docs/papers.md#p000-1): ``u_r / f_x = x0 / z0`` with
``f_x = f / d_x`` in pixels, and eq (5) back-projects a radial range ``d``.

Physics of one pixel (:func:`render_tof_frame`):

* every pixel is sampled by ``supersample²`` sub-rays cast with Open3D's ``RaycastingScene``;
* a sub-ray that hits a surface of reflectivity ρ at range d and incidence angle θ returns the
  phasor ``a · exp(i 4π f_mod d / c)`` with ``a = A_ref (ρ / ρ_ref) (d_ref / d)² cos θ`` (active
  illumination co-located with the lens, Lambertian surfaces);
* the pixel phasor is the mean of its sub-ray phasors, so a pixel straddling a depth edge measures
  a range between the two surfaces (a *mixed* or "flying" pixel) and a pixel straddling a marker
  edge measures an intermediate amplitude; a sub-ray on a dot's edge is itself shaded by the
  fraction of its cell that the dot covers (:func:`box_edge_coverage`, default ``dot_edge="coverage"``),
  so the pixel integrates its area as a sensor pixel does and the image changes smoothly with the pose;
* noise is complex Gaussian on the phasor with per-component standard deviation
  ``σ = sqrt(κ (A + B) + σ_read²)`` (photon shot noise of signal and ambient ``B``, plus read
  noise), so the amplitude noise is ``σ`` and the range noise is ``c / (4π f_mod) · σ / A``: it
  falls with amplitude and, since ``A ∝ 1/d²``, grows with distance.  ``κ`` is calibrated so that
  the data-sheet repeatability (1σ at the reference range and reflectivity) is reproduced;
* the measured phase wraps at the unambiguous range ``c / (2 f_mod)``;
* pixels whose signal plus ambient exceeds the full-well amplitude are *saturated* and pixels
  whose amplitude is below ``amplitude_min_dn`` are *invalid* (no range), as the camera's
  confidence map would report.

Frames: ``S`` is the TOF camera frame (OpenCV convention: z along the boresight, x right, y down);
``C`` is the marker-plate frame (origin at the centre of the plate's front face, x and y in the
plate, z into the plate, so the front face looks along −z_C).  000 eq (1): ``p_S = R_SC q_C +
r_CS_S`` with ``R_SC`` the paper's ``T_S^C`` and ``r_CS_S`` its ``r``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "SPEED_OF_LIGHT_M_S",
    "TofCamera",
    "sr4000",
    "MarkerPlate",
    "default_marker_plate",
    "CooperativeTarget",
    "TofFrame",
    "render_tof_frame",
    "box_edge_coverage",
    "points_from_pixel_range",
    "pixel_range_from_points",
]

SPEED_OF_LIGHT_M_S = 299_792_458.0


@dataclass(frozen=True)
class TofCamera:
    """A continuous-wave TOF camera: pinhole intrinsics plus a radial-range sensor model.

    Attributes
    ----------
    fx_px, fy_px : float
        Focal lengths in pixels (``f / d_x``, ``f / d_y``; flag P000-1).
    cx_px, cy_px : float
        Principal point ``(u_0, v_0)`` in pixels (pixel centres at integer coordinates).
    width_px, height_px : int
        Image size.
    modulation_frequency_hz : float
        Modulation frequency ``f_mod``; the unambiguous range is ``c / (2 f_mod)``.
    amplitude_ref_dn : float
        Amplitude (digital numbers) returned by a target of reflectivity ``reflectivity_ref`` at
        ``range_ref_m`` on the optical axis at normal incidence.
    range_ref_m, reflectivity_ref : float
        The reference condition of the data-sheet repeatability.
    range_sigma_ref_m : float
        Data-sheet range repeatability (1σ) at the reference condition, without ambient light.
    read_noise_dn : float
        Signal-independent noise per phasor component (DN).
    amplitude_saturation_dn : float
        Full-well amplitude: a pixel whose signal plus ambient exceeds it is saturated.
    amplitude_min_dn : float
        Confidence threshold: pixels with a measured amplitude below it carry no range.
    name : str
        What is modelled.
    """

    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    width_px: int
    height_px: int
    modulation_frequency_hz: float = 30e6
    amplitude_ref_dn: float = 2000.0
    range_ref_m: float = 2.0
    reflectivity_ref: float = 0.99
    range_sigma_ref_m: float = 0.004
    read_noise_dn: float = 3.0
    amplitude_saturation_dn: float = 30000.0
    amplitude_min_dn: float = 60.0
    name: str = "TOF camera"

    def __post_init__(self) -> None:
        for key in ("fx_px", "fy_px", "modulation_frequency_hz", "amplitude_ref_dn", "range_ref_m",
                    "reflectivity_ref", "range_sigma_ref_m", "amplitude_saturation_dn"):
            v = getattr(self, key)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{key}: must be finite and > 0, got {v!r}")
        for key in ("width_px", "height_px"):
            v = getattr(self, key)
            if int(v) != v or v < 8:
                raise ValueError(f"{key}: must be an integer >= 8, got {v!r}")
        for key in ("read_noise_dn", "amplitude_min_dn"):
            v = getattr(self, key)
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"{key}: must be finite and >= 0, got {v!r}")
        if self.phase_sigma_ref_rad * self.amplitude_ref_dn <= self.read_noise_dn:
            raise ValueError(f"read_noise_dn: {self.read_noise_dn!r} exceeds the total noise implied "
                             f"by range_sigma_ref_m={self.range_sigma_ref_m!r}")

    @property
    def meters_per_radian(self) -> float:
        """Range per radian of measured phase, ``c / (4π f_mod)`` (m/rad)."""
        return SPEED_OF_LIGHT_M_S / (4.0 * np.pi * self.modulation_frequency_hz)

    @property
    def unambiguous_range_m(self) -> float:
        """Range at which the phase wraps, ``c / (2 f_mod)`` (m)."""
        return SPEED_OF_LIGHT_M_S / (2.0 * self.modulation_frequency_hz)

    @property
    def phase_sigma_ref_rad(self) -> float:
        """Phase noise (1σ, rad) at the reference condition."""
        return self.range_sigma_ref_m / self.meters_per_radian

    @property
    def shot_noise_gain(self) -> float:
        """``κ`` of ``σ² = κ (A + B) + σ_read²`` (DN), calibrated on the data-sheet repeatability."""
        sigma_ref = self.phase_sigma_ref_rad * self.amplitude_ref_dn
        return (sigma_ref**2 - self.read_noise_dn**2) / self.amplitude_ref_dn

    @property
    def K(self) -> np.ndarray:
        """3×3 intrinsic matrix (pixels)."""
        return np.array([[self.fx_px, 0.0, self.cx_px], [0.0, self.fy_px, self.cy_px], [0.0, 0.0, 1.0]])

    def phasor_sigma_dn(self, amplitude_dn: ArrayLike, ambient_dn: float = 0.0) -> np.ndarray:
        """Noise per phasor component (DN) at a given signal amplitude and ambient level."""
        a = np.asarray(amplitude_dn, dtype=float)
        return np.sqrt(self.shot_noise_gain * (np.maximum(a, 0.0) + ambient_dn) + self.read_noise_dn**2)

    def range_sigma_m(self, amplitude_dn: ArrayLike, ambient_dn: float = 0.0) -> np.ndarray:
        """Range noise (1σ, m) of a pixel with the given true amplitude: ``c/(4πf) σ / A``."""
        a = np.asarray(amplitude_dn, dtype=float)
        with np.errstate(divide="ignore"):
            return self.meters_per_radian * self.phasor_sigma_dn(a, ambient_dn) / a

    def signal_amplitude_dn(self, reflectivity: ArrayLike, range_m: ArrayLike,
                            cos_incidence: ArrayLike = 1.0) -> np.ndarray:
        """Noise-free return amplitude ``A_ref (ρ/ρ_ref) (d_ref/d)² cos θ`` (DN)."""
        r = np.asarray(range_m, dtype=float)
        return (self.amplitude_ref_dn * np.asarray(reflectivity, dtype=float) / self.reflectivity_ref
                * (self.range_ref_m / r) ** 2 * np.clip(cos_incidence, 0.0, 1.0))


def sr4000() -> TofCamera:
    """The MESA Imaging SR4000 (standard field of view, 30 MHz), from its data sheet.

    176 × 144 pixels of 40 µm pitch behind a 10 mm lens, so ``f_x = f_y = 250`` px (the data
    sheet's 43.6° × 34.6° field of view includes the lens distortion, which this undistorted model
    leaves out: the model's field of view is 38.8° × 32.1°).  30 MHz modulation (5.0 m unambiguous
    range), repeatability 4 mm (1σ, typical) at 2 m on a 99 % reflective target.  Amplitude units
    (DN) are scaled so that this reference returns 2000 DN; the full well (30000 DN) is then reached
    by a white target at about 0.5 m, and the confidence threshold (60 DN) by a black (5 %)
    marker at about 2.6 m.  See ``docs/tof.md``.
    """
    return TofCamera(fx_px=250.0, fy_px=250.0, cx_px=87.5, cy_px=71.5, width_px=176, height_px=144,
                     modulation_frequency_hz=30e6, amplitude_ref_dn=2000.0, range_ref_m=2.0,
                     reflectivity_ref=0.99, range_sigma_ref_m=0.004, read_noise_dn=3.0,
                     amplitude_saturation_dn=30000.0, amplitude_min_dn=60.0,
                     name="MESA SR4000 (176x144, 30 MHz)")


def _as_pairs(value, name: str) -> tuple[tuple[float, float], ...]:
    a = np.asarray(value, dtype=float)
    if a.size == 0:
        return ()
    if a.ndim != 2 or a.shape[1] != 2 or not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected a finite (N, 2) array, got shape {a.shape}")
    return tuple((float(x), float(y)) for x, y in a)


@dataclass(frozen=True)
class MarkerPlate:
    """A white plate with dark circular markers (000 §1: black dots on a white background).

    Attributes
    ----------
    markers_xy_m : tuple of (x, y)
        Marker centres in the plate frame C (m); the markers lie on the front face ``z_C = 0``.
    marker_radius_m : float
        Radius of every dot.
    width_m, height_m, thickness_m : float
        Plate size along x_C, y_C and z_C; the plate is centred on the C origin in x and y.
    plate_reflectivity, marker_reflectivity : float
        Lambertian reflectivities at the camera's wavelength (white paint, black paint).
    """

    markers_xy_m: tuple[tuple[float, float], ...]
    marker_radius_m: float = 0.015
    width_m: float = 0.30
    height_m: float = 0.24
    thickness_m: float = 0.005
    plate_reflectivity: float = 0.90
    marker_reflectivity: float = 0.05

    def __post_init__(self) -> None:
        object.__setattr__(self, "markers_xy_m", _as_pairs(self.markers_xy_m, "markers_xy_m"))
        if len(self.markers_xy_m) < 3:
            raise ValueError(f"markers_xy_m: need at least 3 markers, got {len(self.markers_xy_m)}")
        for key in ("marker_radius_m", "width_m", "height_m", "thickness_m"):
            v = getattr(self, key)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{key}: must be finite and > 0, got {v!r}")
        for key in ("plate_reflectivity", "marker_reflectivity"):
            v = getattr(self, key)
            if not 0 <= v <= 1:
                raise ValueError(f"{key}: must lie in [0, 1], got {v!r}")
        xy = np.asarray(self.markers_xy_m)
        half = np.array([self.width_m, self.height_m]) / 2 - self.marker_radius_m
        if np.any(np.abs(xy) > half):
            raise ValueError(f"markers_xy_m: a marker does not fit on the {self.width_m} x {self.height_m} m plate")

    @property
    def n_markers(self) -> int:
        return len(self.markers_xy_m)

    @property
    def markers_C(self) -> np.ndarray:
        """Marker centres ``(N, 3)`` in frame C (m): the model points ``q_i`` of 000 eq (1)."""
        xy = np.asarray(self.markers_xy_m, dtype=float)
        return np.column_stack([xy, np.zeros(len(xy))])


def default_marker_plate() -> MarkerPlate:
    """Six 30 mm black dots on a 300 × 240 mm white plate, in an asymmetric layout.

    The layout was chosen (seeded random search, minimum centre spacing 70 mm) to make the 15
    pairwise distances as distinct as possible (smallest gap 4.6 mm), so no relabelling of the dots
    preserves the distance matrix: the matcher of 000 §3 then has a unique answer.
    """
    xy_mm = [(-40.0, 60.0), (-120.0, 70.0), (65.0, -65.0), (90.0, 85.0), (-105.0, -50.0), (-10.0, -75.0)]
    return MarkerPlate(markers_xy_m=np.asarray(xy_mm) / 1000.0)


@dataclass(frozen=True)
class CooperativeTarget:
    """A marker plate mounted on a box-shaped target body.

    The body is a box of size ``body_size_m`` (x, y, z in frame C), centred on the plate in x and y,
    whose front face lies ``standoff_m`` behind the back of the plate; the plate's edges therefore
    show a depth step to the body (mixed pixels) or to empty space.

    Attributes
    ----------
    plate : MarkerPlate
    body_size_m : (3,) tuple
        Body extents along x_C, y_C, z_C (m); all zero for a free-floating plate.
    standoff_m : float
        Gap between the back of the plate and the front face of the body (m).
    body_reflectivity : float
        Lambertian reflectivity of the body (e.g. 0.3 for grey thermal blanket).
    hidden_markers : tuple of int
        Indices of model markers that are not printed (a covered or missing marker).
    spurious_xy_m : tuple of (x, y)
        Extra dark dots printed on the plate that are not in the model (spurious blobs).
    """

    plate: MarkerPlate = field(default_factory=default_marker_plate)
    body_size_m: tuple[float, float, float] = (0.50, 0.40, 0.40)
    standoff_m: float = 0.05
    body_reflectivity: float = 0.30
    hidden_markers: tuple[int, ...] = ()
    spurious_xy_m: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        size = tuple(float(s) for s in np.asarray(self.body_size_m, dtype=float).ravel())
        if len(size) != 3 or any(not np.isfinite(s) or s < 0 for s in size):
            raise ValueError(f"body_size_m: expected three finite sizes >= 0, got {self.body_size_m!r}")
        object.__setattr__(self, "body_size_m", size)
        if not np.isfinite(self.standoff_m) or self.standoff_m < 0:
            raise ValueError(f"standoff_m: must be finite and >= 0, got {self.standoff_m!r}")
        if not 0 <= self.body_reflectivity <= 1:
            raise ValueError(f"body_reflectivity: must lie in [0, 1], got {self.body_reflectivity!r}")
        hidden = tuple(int(i) for i in self.hidden_markers)
        if any(i < 0 or i >= self.plate.n_markers for i in hidden):
            raise ValueError(f"hidden_markers: indices must lie in [0, {self.plate.n_markers}), got {hidden}")
        object.__setattr__(self, "hidden_markers", hidden)
        object.__setattr__(self, "spurious_xy_m", _as_pairs(self.spurious_xy_m, "spurious_xy_m"))

    @property
    def printed_dots_xy_m(self) -> np.ndarray:
        """Centres ``(M, 2)`` of the dots actually printed: model markers not hidden, plus spurious."""
        keep = [xy for i, xy in enumerate(self.plate.markers_xy_m) if i not in self.hidden_markers]
        return np.asarray(keep + list(self.spurious_xy_m), dtype=float).reshape(-1, 2)


@functools.lru_cache(maxsize=16)
def _scene(target: CooperativeTarget):
    """Open3D raycasting scene of ``target`` in frame C; returns ``(scene, plate_geometry_id)``."""
    import open3d as o3d

    plate = target.plate
    scene = o3d.t.geometry.RaycastingScene()
    box = o3d.geometry.TriangleMesh.create_box(plate.width_m, plate.height_m, plate.thickness_m)
    box.translate((-plate.width_m / 2, -plate.height_m / 2, 0.0))
    plate_id = scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(box))
    bx, by, bz = target.body_size_m
    if min(bx, by, bz) > 0:
        body = o3d.geometry.TriangleMesh.create_box(bx, by, bz)
        body.translate((-bx / 2, -by / 2, plate.thickness_m + target.standoff_m))
        scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(body))
    return scene, plate_id


@dataclass(frozen=True)
class TofFrame:
    """One TOF frame.

    Attributes
    ----------
    amplitude_dn : (H, W) ndarray
        Measured amplitude (grey) image, clipped at the full well for saturated pixels.
    range_m : (H, W) ndarray
        Measured radial range along each pixel ray (m); NaN where ``valid`` is False.
    valid : (H, W) bool ndarray
        Pixels with a usable range (amplitude above the confidence threshold and not saturated).
    saturated : (H, W) bool ndarray
        Pixels whose signal plus ambient exceeded the full well.
    """

    amplitude_dn: np.ndarray
    range_m: np.ndarray
    valid: np.ndarray
    saturated: np.ndarray


@functools.lru_cache(maxsize=8)
def _pixel_rays_S(camera: TofCamera, supersample: int) -> np.ndarray:
    """Unit ray directions ``(H, W, s*s, 3)`` in frame S for a regular sub-pixel grid (read-only)."""
    s = supersample
    off = (np.arange(s) + 0.5) / s - 0.5
    v, u = np.meshgrid(np.arange(camera.height_px, dtype=float), np.arange(camera.width_px, dtype=float),
                       indexing="ij")
    du, dv = np.meshgrid(off, off, indexing="xy")
    uu = u[..., None] + du.ravel()
    vv = v[..., None] + dv.ravel()
    d = np.stack([(uu - camera.cx_px) / camera.fx_px, (vv - camera.cy_px) / camera.fy_px,
                  np.ones_like(uu)], axis=-1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    d.flags.writeable = False
    return d


def _check_pose(R_SC: ArrayLike, r_CS_S: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    R = np.asarray(R_SC, dtype=float)
    if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise ValueError(f"R_SC: expected a 3x3 rotation matrix, got shape {R.shape}")
    r = np.asarray(r_CS_S, dtype=float)
    if r.shape != (3,) or not np.all(np.isfinite(r)):
        raise ValueError(f"r_CS_S: expected a finite (3,) vector, got {r_CS_S!r}")
    return R, r


def box_edge_coverage(x: ArrayLike, a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """Fraction of a square cell on the inner side of a straight edge (the cell's area integration).

    The cell's footprint projected on the edge normal is distributed as the sum of two centred
    uniform variables of widths ``a`` and ``b`` (its two sides projected on the normal), so the
    covered fraction is their CDF at ``x``, the signed distance from the cell centre to the edge
    (positive: the centre is on the inner side): quadratic, linear, quadratic.  ``x``, ``a``, ``b``
    in one length unit, broadcastable.
    """
    x, a, b = (np.asarray(v, dtype=float) for v in (x, a, b))
    hi, lo = np.maximum(a, b), np.maximum(np.minimum(a, b), 1e-12)
    hi = np.maximum(hi, 1e-12)
    s, d = 0.5 * (hi + lo), 0.5 * (hi - lo)
    xc = np.clip(x, -s, s)
    lower = (xc + s) ** 2 / (2.0 * hi * lo)
    mid = (xc + 0.5 * hi) / hi
    upper = 1.0 - (s - xc) ** 2 / (2.0 * hi * lo)
    return np.where(xc <= -d, lower, np.where(xc < d, mid, upper))


def render_tof_frame(camera: TofCamera, target: CooperativeTarget, R_SC: ArrayLike, r_CS_S: ArrayLike,
                     *, rng: np.random.Generator | int | None = None, supersample: int = 3,
                     ambient_dn: float = 0.0, noise: bool = True, dot_edge: str = "coverage") -> TofFrame:
    """Render the amplitude and radial-range images of ``target`` seen by ``camera``.

    Parameters
    ----------
    camera : TofCamera
    target : CooperativeTarget
    R_SC : (3, 3) array_like
        Rotation from the plate frame C to the camera frame S (000's ``T_S^C``).
    r_CS_S : (3,) array_like
        Position of the C origin (centre of the plate's front face) in S (m); 000's ``r``.
    rng : Generator, int or None
        Source of the sensor noise.
    supersample : int
        Sub-rays per pixel along each axis (mixed pixels and anti-aliased marker edges).
    ambient_dn : float
        Ambient (unmodulated) light per pixel, in DN: adds shot noise and can saturate.
    noise : bool
        False gives the noise-free expected frame (phasor mean of the sub-rays).
    dot_edge : {"coverage", "point"}
        How a sub-ray that lands on a dot's edge is shaded.  ``"coverage"`` (default): by the
        fraction of its cell (``1/supersample`` px square) whose footprint on the plate the dot
        covers, with the edge taken as straight across the cell (:func:`box_edge_coverage` of the
        cell's sides projected on the edge normal): the pixel-area integration of a real sensor, so
        the image and a dot's centre change smoothly with the pose.  ``"point"`` (the renderer of
        the results published before issue 19): by the dot's reflectivity at the sub-ray's centre,
        which quantises the edge in steps of ``1/supersample²`` of a pixel and puts a pose-dependent
        staircase of about 0.016 px RMS (3 × 3 sub-rays, 1 m) on the dots' centroids, an artefact of
        the sampling that no sensor has.

    Returns
    -------
    TofFrame
    """
    R, r = _check_pose(R_SC, r_CS_S)
    if int(supersample) != supersample or supersample < 1:
        raise ValueError(f"supersample: must be an integer >= 1, got {supersample!r}")
    if dot_edge not in ("coverage", "point"):
        raise ValueError(f"dot_edge: must be 'coverage' or 'point', got {dot_edge!r}")
    if not np.isfinite(ambient_dn) or ambient_dn < 0:
        raise ValueError(f"ambient_dn: must be finite and >= 0, got {ambient_dn!r}")
    import open3d as o3d

    rng = np.random.default_rng(rng)
    scene, plate_id = _scene(target)
    dirs_S = _pixel_rays_S(camera, int(supersample))           # (H, W, s², 3)
    dirs_C = dirs_S @ R                                           # R_SCᵀ d_S, as rows
    origin_C = -R.T @ r
    rays = np.concatenate([np.broadcast_to(origin_C, dirs_C.shape), dirs_C], axis=-1).reshape(-1, 6)
    hit = scene.cast_rays(o3d.core.Tensor(rays.astype(np.float32)))
    t = hit["t_hit"].numpy().astype(float).reshape(dirs_C.shape[:-1])
    gid = hit["geometry_ids"].numpy().reshape(t.shape)
    normal_C = hit["primitive_normals"].numpy().astype(float).reshape(dirs_C.shape)
    hit_any = np.isfinite(t)
    t_safe = np.where(hit_any, t, 1.0)
    cos_inc = np.abs(np.einsum("...k,...k->...", normal_C, dirs_C))

    refl = np.full(t.shape, target.body_reflectivity)
    on_plate = hit_any & (gid == plate_id)
    refl[on_plate] = target.plate.plate_reflectivity
    dots = target.printed_dots_xy_m
    if len(dots):
        sel = np.flatnonzero(on_plate.ravel())
        p_C = origin_C + t_safe.ravel()[sel, None] * dirs_C.reshape(-1, 3)[sel]
        sel = sel[p_C[:, 2] < 0.5 * target.plate.thickness_m]
        p_C = origin_C[:2] + t_safe.ravel()[sel, None] * dirs_C.reshape(-1, 3)[sel, :2]
        d2 = ((p_C[:, None, :] - dots) ** 2).sum(-1).min(-1)
        if dot_edge == "coverage":
            # fraction of the sub-ray's cell (1/s px square) whose footprint on the plate lies inside the
            # dot: the dot's edge taken as straight across the cell, the cell's footprint projected on the
            # edge normal m is the sum of two uniform widths |m·∂p/∂u|/s and |m·∂p/∂v|/s (box_edge_coverage)
            nearest = ((p_C[:, None, :] - dots) ** 2).sum(-1).argmin(-1)
            dist = np.maximum(np.sqrt(d2), 1e-12)
            m_S = ((p_C - dots[nearest]) / dist[:, None]) @ R[:, :2].T          # in-plane radial direction in S
            e_S = dirs_S.reshape(-1, 3)[sel]
            d_S = e_S / e_S[:, 2:3]                                               # ray (x/z, y/z, 1)
            z_hit = t_safe.ravel()[sel] * e_S[:, 2]
            n_S = R[:, 2]
            nd, md = d_S @ n_S, (m_S * d_S).sum(-1)
            w_u = np.abs(z_hit / camera.fx_px * (m_S[:, 0] - md * n_S[0] / nd)) / supersample
            w_v = np.abs(z_hit / camera.fy_px * (m_S[:, 1] - md * n_S[1] / nd)) / supersample
            cover = box_edge_coverage(target.plate.marker_radius_m - dist, w_u, w_v)
            refl.ravel()[sel] = (cover * target.plate.marker_reflectivity
                                 + (1.0 - cover) * target.plate.plate_reflectivity)
        else:
            refl.ravel()[sel[d2 <= target.plate.marker_radius_m**2]] = target.plate.marker_reflectivity

    a = np.where(hit_any, camera.signal_amplitude_dn(refl, t_safe, cos_inc), 0.0)
    k = 1.0 / camera.meters_per_radian
    z = (a * np.exp(1j * k * t_safe)).mean(axis=-1)              # pixel phasor (H, W)
    signal = np.abs(z)
    saturated = signal + ambient_dn > camera.amplitude_saturation_dn
    if noise:
        sigma = camera.phasor_sigma_dn(signal, ambient_dn)
        z = z + sigma * (rng.standard_normal(z.shape) + 1j * rng.standard_normal(z.shape))
    amplitude = np.abs(z)
    amplitude[saturated] = camera.amplitude_saturation_dn
    range_m = np.mod(np.angle(z), 2 * np.pi) * camera.meters_per_radian
    valid = (amplitude >= camera.amplitude_min_dn) & ~saturated
    range_m = np.where(valid, range_m, np.nan)
    return TofFrame(amplitude_dn=amplitude, range_m=range_m, valid=valid, saturated=saturated)


def points_from_pixel_range(u_px: ArrayLike, v_px: ArrayLike, range_m: ArrayLike, camera: TofCamera) -> np.ndarray:
    """3-D points in frame S from pixel coordinates and radial range: 000 eq (5), flag P000-1.

    ``z0 = d / sqrt(1 + (u_r/f_x)² + (v_r/f_y)²)``, ``x0 = (u_r/f_x) z0``, ``y0 = (v_r/f_y) z0`` with
    ``u_r = u − u_0``, ``v_r = v − v_0`` (eq 2).  ``range_m`` must be the radial range along the ray
    (what the model and the SR4000 deliver), not a z-depth.

    Parameters
    ----------
    u_px, v_px, range_m : array_like, broadcastable
    camera : TofCamera

    Returns
    -------
    (..., 3) ndarray of points in S (m).
    """
    u = np.asarray(u_px, dtype=float)
    v = np.asarray(v_px, dtype=float)
    d = np.asarray(range_m, dtype=float)
    xn = (u - camera.cx_px) / camera.fx_px
    yn = (v - camera.cy_px) / camera.fy_px
    z0 = d / np.sqrt(1.0 + xn**2 + yn**2)
    return np.stack(np.broadcast_arrays(xn * z0, yn * z0, z0), axis=-1)


def pixel_range_from_points(p_S: ArrayLike, camera: TofCamera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of :func:`points_from_pixel_range`: ``(u_px, v_px, range_m)`` of points ``(..., 3)`` in S."""
    p = np.asarray(p_S, dtype=float)
    if p.shape[-1:] != (3,):
        raise ValueError(f"p_S: expected shape (..., 3), got {p.shape}")
    u = camera.fx_px * p[..., 0] / p[..., 2] + camera.cx_px
    v = camera.fy_px * p[..., 1] / p[..., 2] + camera.cy_px
    return u, v, np.linalg.norm(p, axis=-1)
