"""Image sensor model: exposure, optical blur, shot and read noise, quantisation.

The renderer produces a noiseless *radiance* image in relative units: 1.0 is the radiance of a white
(albedo 1) Lambertian surface facing the full Sun. The sensor turns it into digital numbers:

1. optical blur: Gaussian point-spread function of ``psf_sigma_px`` (applied to radiance);
2. exposure: mean signal ``N_e = radiance · electrons_per_unit_radiance`` electrons, where
   ``electrons_per_unit_radiance = exposure_s · responsivity_e_per_s`` (responsivity folds the solar
   irradiance, aperture, pixel area and quantum efficiency into one number);
3. shot noise (variance ``N_e``) and read noise (``read_noise_e`` electrons), drawn together as one
   Gaussian of variance ``N_e + read_noise_e²`` (the Gaussian form of Poisson shot noise is exact to
   well under 1 % of σ above 20 e⁻, and read noise dominates below); clipping at the full well;
4. quantisation: ``DN = round(e · (2**bits - 1) / full_well_e)``, clipped to ``[0, 2**bits - 1]``.

Noise streams (``noise_stream``), both keyed by draws of ``rng`` and the pixel's position in the full
image, so a region of interest rendered at ``origin_px`` gets exactly the noise the same pixels get in
a full-frame image:

- ``"pixel"`` (default): one counter-based normal per pixel with signal, and on pixels whose mean
  signal is zero only the rare read-noise exceedances that reach one digital number, drawn directly
  (:mod:`vision.pixel_noise`); the same law as one normal per pixel, at the cost of the pixels with
  signal (issue 16 item 7);
- ``"tiles"``: one NumPy generator per 32 × 32 tile of the full image, keyed by the tile's position,
  a normal for every pixel (the stream before issue 16 item 7, kept for the benchmark's baseline).

With ``auto_exposure`` (the default) the exposure time is chosen per image, as a camera's
auto-exposure does: the ``auto_exposure_percentile`` of the non-zero radiance is placed at
``auto_exposure_level`` of the full well, within ``[min_exposure_s, max_exposure_s]``. A dark image
(target in Earth's shadow) gets ``max_exposure_s`` and stays dark.

Defaults (12 000 e⁻/ms at unit radiance, full well 20 000 e⁻, read noise 10 e⁻, 8 bits, PSF σ 0.6 px)
put a white surface facing the Sun at 60 % of full scale with the fixed 1 ms exposure; the sky is
below one DN of noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from vision.pixel_noise import dark_exceedances, pixel_normals

__all__ = ["NOISE_STREAMS", "SensorModel"]

#: ``SensorModel.noise_stream`` values (module docstring)
NOISE_STREAMS = ("pixel", "tiles")

#: above this exceedance probability per dark pixel, every pixel gets its own normal (no sparse draw)
_SPARSE_MAX_PROBABILITY = 0.05


@dataclass(frozen=True)
class SensorModel:
    """Seeded image sensor (see module docstring for the chain).

    Attributes
    ----------
    exposure_s : float
        Exposure time, seconds.
    responsivity_e_per_s : float
        Electrons per second collected by a pixel seeing unit radiance.
    full_well_e : float
        Full-well capacity, electrons (saturation).
    read_noise_e : float
        Read-noise standard deviation, electrons.
    psf_sigma_px : float
        Standard deviation of the Gaussian optical point-spread function, pixels (0: no blur).
    bits : int
        ADC resolution (8 gives ``uint8`` images, more gives ``uint16``).
    shot_noise : bool
        Draw photon (shot) noise (False: the mean signal only, plus read noise).
    auto_exposure : bool
        Choose the exposure per image (see module docstring) instead of ``exposure_s``.
    auto_exposure_percentile, auto_exposure_level : float
        Percentile (of non-zero radiance, in [0, 100]) placed at this fraction of the full well.
    min_exposure_s, max_exposure_s : float
        Limits of the automatic exposure, seconds.
    noise_stream : str
        ``"pixel"`` or ``"tiles"`` (module docstring): the same noise law, different draws.
    """

    exposure_s: float = 1.0e-3
    responsivity_e_per_s: float = 1.2e7
    full_well_e: float = 20_000.0
    read_noise_e: float = 10.0
    psf_sigma_px: float = 0.6
    bits: int = 8
    shot_noise: bool = True
    auto_exposure: bool = True
    auto_exposure_percentile: float = 99.0
    auto_exposure_level: float = 0.8
    min_exposure_s: float = 1.0e-5
    max_exposure_s: float = 2.0e-2
    noise_stream: str = "pixel"

    def __post_init__(self) -> None:
        if self.noise_stream not in NOISE_STREAMS:
            raise ValueError(f"noise_stream must be one of {NOISE_STREAMS}, got {self.noise_stream!r}")
        for name in ("exposure_s", "responsivity_e_per_s", "full_well_e"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("read_noise_e", "psf_sigma_px"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        if not (0 < self.auto_exposure_percentile <= 100 and 0 < self.auto_exposure_level <= 1):
            raise ValueError("auto_exposure_percentile must be in (0, 100] and auto_exposure_level in "
                             f"(0, 1], got {self.auto_exposure_percentile!r}, {self.auto_exposure_level!r}")
        if not 0 < self.min_exposure_s <= self.max_exposure_s:
            raise ValueError(f"need 0 < min_exposure_s <= max_exposure_s, got {self.min_exposure_s!r}, "
                             f"{self.max_exposure_s!r}")
        if int(self.bits) != self.bits or not 1 <= int(self.bits) <= 16:
            raise ValueError(f"bits must be an integer in [1, 16], got {self.bits!r}")

    @property
    def max_dn(self) -> int:
        """Largest digital number, ``2**bits - 1``."""
        return 2 ** int(self.bits) - 1

    @property
    def dtype(self) -> type:
        """``numpy.uint8`` for 8 bits or fewer, else ``numpy.uint16``."""
        return np.uint8 if self.bits <= 8 else np.uint16

    @property
    def electrons_per_unit_radiance(self) -> float:
        """Mean electrons collected at unit radiance in the fixed exposure ``exposure_s``."""
        return float(self.exposure_s * self.responsivity_e_per_s)

    def exposure_for(self, radiance: ArrayLike) -> float:
        """Exposure time (s) used for this radiance image: ``exposure_s``, or the automatic choice."""
        if not self.auto_exposure:
            return float(self.exposure_s)
        L = np.asarray(radiance, dtype=np.float32)
        pos = L[L > 0]
        if pos.size == 0:
            return float(self.max_exposure_s)
        ref = float(np.percentile(pos, self.auto_exposure_percentile))
        t = self.auto_exposure_level * self.full_well_e / (ref * self.responsivity_e_per_s)
        return float(np.clip(t, self.min_exposure_s, self.max_exposure_s))

    def expected_dn(self, radiance: ArrayLike, *, exposure_s: float | None = None) -> np.ndarray:
        """Noise-free, unquantised digital number of a radiance (without blur), clipped at saturation."""
        t = self.exposure_s if exposure_s is None else float(exposure_s)
        e = np.minimum(np.asarray(radiance, dtype=float) * t * self.responsivity_e_per_s,
                       self.full_well_e)
        return e * self.max_dn / self.full_well_e

    def apply(self, radiance: ArrayLike, *, rng: np.random.Generator | int | None = None,
              exposure_s: float | None = None, origin_px: tuple[int, int] = (0, 0)) -> np.ndarray:
        """Turn a radiance image into a digital image.

        Parameters
        ----------
        radiance : array_like, shape (H, W)
            Relative radiance (>= 0); NaN is treated as 0 (empty sky).
        rng : Generator, int or None
            Random source of the shot and read noise.
        exposure_s : float, optional
            Exposure time; default :meth:`exposure_for` of this image.
        origin_px : (int, int)
            Column and row of this image's top-left pixel in the full image (for a region of
            interest), so that the noise of a pixel does not depend on the crop.

        Returns
        -------
        ndarray, shape (H, W), uint8 or uint16
            Digital numbers.
        """
        import cv2

        rng = np.random.default_rng(rng)
        L = np.asarray(radiance, dtype=np.float32)
        if not np.isfinite(L).all():                    # (a full nan_to_num pass costs 100x this check)
            L = np.nan_to_num(L, nan=0.0)
        if L.ndim != 2:
            raise ValueError(f"radiance must be a 2-D image, got shape {L.shape}")
        if np.any(L < 0):
            raise ValueError("radiance must be >= 0")
        t = self.exposure_for(L) if exposure_s is None else float(exposure_s)
        if self.psf_sigma_px > 0:
            L = cv2.GaussianBlur(L, (0, 0), sigmaX=float(self.psf_sigma_px),
                                 borderType=cv2.BORDER_REPLICATE)
        if self.noise_stream == "pixel":
            return self._digitise_pixel_stream(L, t, rng, origin_px)
        e = L.astype(np.float64) * (t * self.responsivity_e_per_s)
        var = (e if self.shot_noise else 0.0) + self.read_noise_e ** 2
        if np.any(var > 0):
            key = int(rng.integers(2 ** 63))
            e = e + np.sqrt(var) * _tile_normals(key, e.shape, origin_px)
        return self._digitise(e)

    def _digitise(self, e: np.ndarray) -> np.ndarray:
        """Electrons to digital numbers: clip at 0 and the full well, quantise, clip to the ADC range."""
        e = np.clip(e, 0.0, self.full_well_e)
        dn = np.rint(e * (self.max_dn / self.full_well_e))
        return np.clip(dn, 0, self.max_dn).astype(self.dtype)

    def _digitise_pixel_stream(self, L: np.ndarray, t: float, rng: np.random.Generator,
                               origin_px: tuple[int, int]) -> np.ndarray:
        """:meth:`apply` with the ``"pixel"`` stream: the same arithmetic as ``"tiles"`` on every pixel
        with signal; on the others (mean 0 e⁻) only the read-noise draws that reach one digital number."""
        key_signal, key_dark = (int(k) for k in rng.integers(2 ** 63, size=2))
        x0, y0 = (int(v) for v in origin_px)
        dn_per_e = self.max_dn / self.full_well_e
        read = float(self.read_noise_e)
        # z above which read noise alone reaches half a digital number: DN >= 1 on a dark pixel
        z_dark = 0.5 / (read * dn_per_e) if read > 0 else np.inf
        sparse = read == 0 or _tail_probability(z_dark) <= _SPARSE_MAX_PROBABILITY
        signal = L > 0 if sparse else np.ones(L.shape, dtype=bool)
        # flat indices: np.nonzero of a 2-D mask costs 10x np.flatnonzero and a divmod (the same pixels)
        flat = np.flatnonzero(signal)
        rows, cols = np.divmod(flat, L.shape[1])
        out = np.zeros(L.shape, dtype=self.dtype)
        e = np.ravel(L)[flat].astype(np.float64) * (t * self.responsivity_e_per_s)
        var = (e if self.shot_noise else 0.0) + read ** 2
        if np.any(var > 0):
            e = e + np.sqrt(var) * pixel_normals(key_signal, rows + y0, cols + x0)
        out.reshape(-1)[flat] = self._digitise(e)
        if sparse and read > 0:
            r, c, z = dark_exceedances(key_dark, L.shape, (x0, y0), z_dark)
            dark = ~signal[r, c]
            out[r[dark], c[dark]] = self._digitise(read * z[dark])
        return out


def _tail_probability(z: float) -> float:
    """``Q(z) = P(Z > z)`` of a standard normal."""
    from scipy.special import ndtr

    return float(ndtr(-z))


_TILE_PX = 32


def _tile_normals(key: int, shape: tuple[int, int], origin_px: tuple[int, int]) -> np.ndarray:
    """Standard normals for an image crop, drawn per 32 × 32 tile of the full image from streams
    keyed by ``(key, tile_row, tile_col)``, so that they do not depend on the crop."""
    h, w = shape
    x0, y0 = (int(v) for v in origin_px)
    t = _TILE_PX
    out = np.empty((h, w))
    for ty in range(y0 // t, (y0 + h - 1) // t + 1):
        ya, yb = max(y0, ty * t), min(y0 + h, (ty + 1) * t)
        for tx in range(x0 // t, (x0 + w - 1) // t + 1):
            xa, xb = max(x0, tx * t), min(x0 + w, (tx + 1) * t)
            z = np.random.default_rng([key, ty, tx]).standard_normal((t, t))
            out[ya - y0:yb - y0, xa - x0:xb - x0] = z[ya - ty * t:yb - ty * t, xa - tx * t:xb - tx * t]
    return out
