"""Counter-based pixel noise: standard normals keyed by a pixel's position in the full image.

The sensor (:class:`vision.sensor.SensorModel`, ``noise_stream="pixel"``) draws its shot and read
noise here.  Every draw is a pure function of a 64-bit key (one draw of the caller's ``rng``) and the
pixel's full-image row and column, so a region of interest rendered at any origin gets exactly the
noise the same pixels get in the full frame, and the draws are vectorised over any set of pixels.

- :func:`pixel_normals`: one N(0, 1) per pixel: the SplitMix64 output of the pixel's counter
  ``row · 2³² + col`` in the stream of the key (Steele, Lea & Flood 2014; the generator passes
  BigCrush), split into two 32-bit uniforms and turned into a normal by the Box–Muller transform
  (|z| ≤ 6.8: the tail beyond has probability 10⁻¹¹).
- :func:`dark_exceedances`: on pixels whose mean signal is zero the sensor's output is non-zero only
  where the read noise exceeds half a digital number, a rare event (4.4 × 10⁻⁵ per pixel for the
  default sensor).  Instead of one normal per dark pixel, the pixels whose draw exceeds a threshold
  ``z₀`` are drawn directly, per 32 × 32 tile of the full image: the gaps between them in the tile's
  raster order are geometric with success probability ``p = Q(z₀)`` (a Bernoulli(p) process, the
  law of independent normals thresholded at ``z₀``) and each one's value is a normal conditioned on
  ``z > z₀`` (inverse tail function).  The dark pixels' output then has exactly the law of one
  normal per pixel, at the cost of the few exceedances.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import ArrayLike

__all__ = ["TILE_PX", "dark_exceedances", "pixel_normals"]

#: side of the full-image tiles the dark-pixel exceedances are drawn in, pixels
TILE_PX = 32

_GAMMA = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_TWO_PI = 2.0 * np.pi


def _key_word(key: int) -> np.uint64:
    """A stream key as the uint64 word SplitMix64 adds (its low 64 bits)."""
    return np.uint64(int(key) & 0xFFFF_FFFF_FFFF_FFFF)


def _splitmix64(key: int, counter: np.ndarray) -> np.ndarray:
    """SplitMix64 output number ``counter + 1`` of the stream seeded with ``key`` (uint64, wrapping)."""
    c = np.ascontiguousarray(counter, dtype=np.uint64)
    z = np.empty_like(c)
    _splitmix64_into(_key_word(key), c.reshape(-1), z.reshape(-1))
    return z


@numba.njit(cache=True, nogil=True)
def _splitmix64_into(key: np.uint64, counter: np.ndarray, z: np.ndarray) -> None:  # pragma: no cover - compiled
    """:func:`_splitmix64` of each counter, in one compiled pass."""
    for i in range(counter.shape[0]):
        z[i] = _mix(key, counter[i])


@numba.njit(cache=True, nogil=True, inline="always")
def _mix(key: np.uint64, counter: np.uint64) -> np.uint64:  # pragma: no cover - compiled
    """SplitMix64 of one counter (uint64 arithmetic, wrapping)."""
    x = (counter + np.uint64(1)) * _GAMMA + key
    x ^= x >> np.uint64(30)
    x *= _MIX1
    x ^= x >> np.uint64(27)
    x *= _MIX2
    x ^= x >> np.uint64(31)
    return x


@numba.njit(cache=True, nogil=True)
def _box_muller_uniforms(key: np.uint64, rows: np.ndarray, cols: np.ndarray, u1: np.ndarray,
                         u2: np.ndarray) -> None:  # pragma: no cover - compiled
    """:func:`pixel_normals`' two uniforms of each pixel from its counter ``row · 2³² + col``, in one pass:
    ``u1`` in (0, 1] from the high 32 bits of the SplitMix64 word, ``u2`` in [0, 1) from the low 32."""
    for i in range(rows.shape[0]):
        h = _mix(key, (np.uint64(rows[i]) << np.uint64(32)) | np.uint64(cols[i]))
        u1[i] = (np.float64(h >> np.uint64(32)) + 0.5) * 2.0 ** -32
        u2[i] = np.float64(h & np.uint64(0xFFFF_FFFF)) * 2.0 ** -32


def _uniform_open(bits: np.ndarray) -> np.ndarray:
    """Uniforms in (0, 1) from the top 53 bits of uint64 words."""
    return ((bits >> np.uint64(11)).astype(np.float64) + 0.5) * 2.0 ** -53


def pixel_normals(key: int, rows: ArrayLike, cols: ArrayLike) -> np.ndarray:
    """Standard normals of the pixels at full-image ``rows`` and ``cols`` (equal-shape integer arrays, >= 0).

    The value of a pixel depends only on ``key`` and its position (see the module docstring).
    """
    r, c = (np.ascontiguousarray(a) for a in np.broadcast_arrays(np.asarray(rows, dtype=np.int64),
                                                                  np.asarray(cols, dtype=np.int64)))
    if np.any(r < 0) or np.any(c < 0) or np.any(c >= 2 ** 32):
        raise ValueError("rows and cols must be non-negative pixel indices (cols < 2**32)")
    u1, u2 = np.empty(r.shape), np.empty(r.shape)
    _box_muller_uniforms(_key_word(key), r.reshape(-1), c.reshape(-1),
                         u1.reshape(-1), u2.reshape(-1))
    # sqrt(-2 log u1) cos(2 pi u2), in place (the same operations without four temporaries)
    z = np.log(u1, out=u1)
    z *= -2.0
    np.sqrt(z, out=z)
    u2 *= _TWO_PI
    z *= np.cos(u2, out=u2)
    return z


def dark_exceedances(key: int, shape: tuple[int, int], origin_px: tuple[int, int],
                     z_threshold: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pixels of a crop whose standard normal draw exceeds ``z_threshold``, and their draws.

    Parameters
    ----------
    key : int
        Stream key.
    shape : (int, int)
        ``(h, w)`` of the crop.
    origin_px : (int, int)
        Column and row of the crop's top-left pixel in the full image.
    z_threshold : float
        ``z₀``; each pixel exceeds it with probability ``Q(z₀)``, independently of the others.

    Returns
    -------
    rows, cols : ndarray of int64
        Positions in the crop, sorted by tile and then raster order within the tile.
    z : ndarray of float64
        The draws, all ``> z_threshold``.
    """
    from scipy.special import ndtr, ndtri

    h, w = (int(s) for s in shape)
    x0, y0 = (int(o) for o in origin_px)
    p = float(ndtr(-float(z_threshold)))
    empty = np.zeros(0, dtype=np.int64)
    if h <= 0 or w <= 0 or p < 1e-300:                  # none expected in any image
        return empty, empty, np.zeros(0)
    t = TILE_PX
    ty, tx = np.meshgrid(np.arange(y0 // t, (y0 + h - 1) // t + 1, dtype=np.int64),
                         np.arange(x0 // t, (x0 + w - 1) // t + 1, dtype=np.int64), indexing="ij")
    ty, tx = ty.ravel(), tx.ravel()
    tile_counter = (ty.astype(np.uint64) << np.uint64(40)) | (tx.astype(np.uint64) << np.uint64(20))
    log_q = np.log1p(-p)
    pos = np.full(len(ty), -1, dtype=np.int64)
    active = np.arange(len(ty))
    found_tile, found_pos, found_u = [], [], []
    j = 0
    while len(active):
        base = tile_counter[active] | (np.uint64(j) << np.uint64(1))
        u_gap = _uniform_open(_splitmix64(key, base))
        gap = np.floor(np.log(u_gap) / log_q) if p < 1.0 else np.zeros(len(active))
        nxt = pos[active] + 1 + np.minimum(gap, t * t).astype(np.int64)
        inside = nxt < t * t
        active, nxt, base = active[inside], nxt[inside], base[inside]
        pos[active] = nxt
        found_tile.append(active)
        found_pos.append(nxt)
        found_u.append(_uniform_open(_splitmix64(key, base | np.uint64(1))))
        j += 1
        if j >= 2 ** 19:
            raise ValueError(f"z_threshold {z_threshold!r} is too low for sparse exceedances (p = {p:.3g})")
    tile = np.concatenate(found_tile)
    k = np.concatenate(found_pos)
    u = np.concatenate(found_u)
    rows = ty[tile] * t + k // t - y0
    cols = tx[tile] * t + k % t - x0
    keep = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    order = np.lexsort((k[keep], tile[keep]))
    z = -ndtri(u[keep] * p)
    return rows[keep][order], cols[keep][order], z[order]
