"""Procedural albedo textures of spacecraft surfaces, drawn from a seeded random generator.

The textures imitate what a feature detector finds on a real spacecraft: multi-layer insulation
(MLI) with wrinkles, creases, tape seams and labels; solar-cell grids with per-cell reflectance
scatter, string gaps and interconnects; painted panel backs with ribs, harness and stains; bolted
structure; striped radiators. Every generator draws from the generator it is given in a fixed
order, so a seed reproduces a texture exactly.
"""

from __future__ import annotations

import numpy as np

__all__ = ["TEXTURE_KINDS", "procedural_texture"]

#: Procedural texture families, one generator each.
TEXTURE_KINDS = ("mli", "solar_cells", "panel_back", "structure", "radiator")

Shape = tuple[int, int]


def _noise(rng: np.random.Generator, shape: Shape, sigma_tx: float) -> np.ndarray:
    """White noise low-passed with a Gaussian of ``sigma_tx`` texels, normalised to unit std.

    Wide kernels are applied on a coarser grid (at most 2 texels of sigma there) and resized up, so
    the cost does not grow with the kernel and the border reflection does not mirror the pattern.
    """
    import cv2

    h, w = shape
    if sigma_tx <= 0.3:
        n = rng.standard_normal(shape).astype(np.float32)
    else:
        f = max(1.0, sigma_tx / 2.0)
        m = 4  # margin cells on the coarse grid, cropped after resizing
        sh, sw = int(np.ceil(h / f)) + 2 * m, int(np.ceil(w / f)) + 2 * m
        n = rng.standard_normal((sh, sw)).astype(np.float32)
        n = cv2.GaussianBlur(n, (0, 0), sigmaX=float(sigma_tx / f), borderType=cv2.BORDER_REFLECT)
        if f > 1.0:
            n = cv2.resize(n, (int(round(sw * f)), int(round(sh * f))), interpolation=cv2.INTER_CUBIC)
        o = int(round(m * f)) if f > 1.0 else m
        n = np.ascontiguousarray(n[o:o + h, o:o + w])
    s = float(n.std())
    return n / s if s > 0 else n


def _fractal(rng: np.random.Generator, shape: Shape, texel_m: float, scales_m: tuple[float, ...],
             amps: tuple[float, ...]) -> np.ndarray:
    """Sum of :func:`_noise` layers of correlation lengths ``scales_m`` (metres) and amplitudes ``amps``."""
    out = np.zeros(shape, dtype=np.float32)
    for s, a in zip(scales_m, amps, strict=True):
        out += a * _noise(rng, shape, s / texel_m)
    return out


def _labels(rng: np.random.Generator, img: np.ndarray, texel_m: float, count: int) -> None:
    """Draw ``count`` label-like rectangles with random glyph blocks into ``img`` (in place)."""
    h, w = img.shape
    for _ in range(count):
        lw = int(rng.uniform(0.10, 0.28) / texel_m)
        lh = int(rng.uniform(0.06, 0.16) / texel_m)
        if lw >= w - 4 or lh >= h - 4 or lw < 6 or lh < 6:
            continue
        x0 = int(rng.integers(2, w - lw - 2))
        y0 = int(rng.integers(2, h - lh - 2))
        bg = rng.uniform(0.85, 1.0)
        img[y0:y0 + lh, x0:x0 + lw] = bg
        gw, gh = max(2, int(0.015 / texel_m)), max(2, int(0.025 / texel_m))
        for gy in range(y0 + 2, y0 + lh - gh - 1, gh + 1):
            for gx in range(x0 + 2, x0 + lw - gw - 1, gw + 1):
                if rng.random() < 0.55:
                    img[gy:gy + gh, gx:gx + gw] = rng.uniform(0.05, 0.3)


def _tex_mli(rng: np.random.Generator, shape: Shape, texel_m: float) -> np.ndarray:
    h, w = shape
    base = _fractal(rng, shape, texel_m, (0.008, 0.02, 0.05, 0.12, 0.3), (0.2, 0.3, 0.4, 0.4, 0.3))
    # wrinkles and creases: thin ridges along zero crossings of band-passed noise
    ridges = np.zeros(shape, dtype=np.float32)
    for s, a in ((0.03, 0.5), (0.07, 0.6), (0.15, 0.4)):
        n = _noise(rng, shape, s / texel_m)
        ridges += a * np.exp(-(n / 0.18) ** 2)
    img = 0.62 + 0.07 * base + 0.35 * (ridges - ridges.mean())
    # tape seams
    for axis, size in ((0, h), (1, w)):
        pos = rng.uniform(0.25, 0.6) / texel_m * rng.uniform(0.5, 1.0)
        width = max(2, int(0.025 / texel_m))
        step = max(int(rng.uniform(0.35, 0.7) / texel_m), 4 * width)
        p = int(pos) % step
        while p < size - width:
            if axis == 0:
                img[p:p + width, :] = 0.92 + 0.04 * _noise(rng, (width, w), 1.0)
            else:
                img[:, p:p + width] = 0.92 + 0.04 * _noise(rng, (h, width), 1.0)
            p += step
    _labels(rng, img, texel_m, count=int(rng.integers(1, 3)) * max(1, int(h * w * texel_m ** 2 / 0.8)))
    return np.clip(img, 0.03, 1.0)


def _tex_solar(rng: np.random.Generator, shape: Shape, texel_m: float) -> np.ndarray:
    h, w = shape
    cw, ch = max(3, round(0.04 / texel_m)), max(3, round(0.06 / texel_m))
    ny, nx = h // ch + 1, w // cw + 1
    # cell reflectance: per-module (6 x 10 cells) and per-cell scatter, a few odd cells
    mod = 0.2 * rng.standard_normal((ny // 10 + 1, nx // 6 + 1))
    cell = 0.5 + np.repeat(np.repeat(mod, 10, axis=0), 6, axis=1)[:ny, :nx] \
        + 0.15 * rng.standard_normal((ny, nx))
    u = rng.random((ny, nx))
    cell[u < 0.04] = rng.uniform(0.85, 1.0, int((u < 0.04).sum()))
    cell[(u >= 0.04) & (u < 0.07)] = 0.08
    cell = np.clip(cell, 0.05, 1.0).astype(np.float32)
    img = np.repeat(np.repeat(cell, ch, axis=0), cw, axis=1)[:h, :w].copy()
    img[::ch, :] = 0.08            # inter-cell gaps
    img[:, ::cw] = 0.08
    # strings: every 6 cells across, a wider gap with a bright interconnect beside it
    for x in range(0, w, 6 * cw):
        img[:, x:x + 2] = 0.05
        img[:, x + 2:x + 3] = 0.9
    for y in range(0, h, 10 * ch):
        img[y:y + 2, :] = 0.05
    img += 0.12 * _noise(rng, shape, 0.08 / texel_m) + 0.04 * _noise(rng, shape, 0.6)
    _labels(rng, img, texel_m, count=max(1, int(h * w * texel_m ** 2 / 0.4)))
    return np.clip(img, 0.02, 1.0)


def _tex_panel_back(rng: np.random.Generator, shape: Shape, texel_m: float) -> np.ndarray:
    h, w = shape
    img = 0.78 + 0.05 * _fractal(rng, shape, texel_m, (0.01, 0.05, 0.2), (0.5, 0.7, 0.6))
    rib = max(1, int(0.012 / texel_m))
    step = int(0.25 / texel_m)
    img[:, ::step] -= 0.25
    img[::step, :] -= 0.25
    for _ in range(rib - 1):
        img[:, 1::step] -= 0.2
        img[1::step, :] -= 0.2
    # harness cables: a few dark polylines; stains: soft dark blobs
    import cv2

    for _ in range(max(2, int(h * w * texel_m ** 2 / 0.3))):
        pts = np.stack([rng.uniform(0, w, 4), rng.uniform(0, h, 4)], axis=1).astype(np.int32)
        cv2.polylines(img, [pts], False, float(rng.uniform(0.1, 0.3)),
                      thickness=max(1, int(0.01 / texel_m)))
    stains = np.exp(-(np.maximum(_noise(rng, shape, 0.08 / texel_m) - 1.2, 0) * 3.0))
    img = img * (0.6 + 0.4 * stains)
    _labels(rng, img, texel_m, count=max(1, int(h * w * texel_m ** 2 / 1.0)))
    return np.clip(img, 0.03, 1.0)


def _tex_structure(rng: np.random.Generator, shape: Shape, texel_m: float) -> np.ndarray:
    h, w = shape
    img = 0.6 + 0.12 * _fractal(rng, shape, texel_m, (0.01, 0.04, 0.15), (0.4, 0.6, 0.5))
    step = max(3, int(0.06 / texel_m))
    yy, xx = np.mgrid[0:h, 0:w]
    bolts = ((xx % step == step // 2) & ((yy % step == step // 2) | (yy < 2) | (yy > h - 3)))
    img[bolts] = 0.15
    return np.clip(img, 0.03, 1.0)


def _tex_radiator(rng: np.random.Generator, shape: Shape, texel_m: float) -> np.ndarray:
    h, w = shape
    stripe = max(2, int(0.04 / texel_m))
    xx = np.arange(w)[None, :]
    img = np.where((xx // stripe) % 2 == 0, 0.9, 0.25).astype(np.float32) * np.ones((h, 1), np.float32)
    img += 0.06 * _fractal(rng, shape, texel_m, (0.01, 0.05), (0.6, 0.6))
    _labels(rng, img, texel_m, count=1)
    return np.clip(img, 0.03, 1.0)


_GENERATORS = {
    "mli": _tex_mli,
    "solar_cells": _tex_solar,
    "panel_back": _tex_panel_back,
    "structure": _tex_structure,
    "radiator": _tex_radiator,
}


def procedural_texture(kind: str, width_m: float, height_m: float, *, texel_m: float = 0.005,
                       rng: np.random.Generator | int | None = None) -> np.ndarray:
    """A procedural albedo texture of one surface patch.

    Parameters
    ----------
    kind : str
        One of :data:`TEXTURE_KINDS`.
    width_m, height_m : float
        Patch size, metres (texture columns along the width).
    texel_m : float, optional
        Texel size, metres.
    rng : Generator, int or None
        Random source.

    Returns
    -------
    ndarray, shape (ceil(height_m/texel_m), ceil(width_m/texel_m)), float32
        Texture values in [0, 1] (multiplied by the material albedo when rendered).
    """
    if kind not in _GENERATORS:
        raise ValueError(f"kind must be one of {TEXTURE_KINDS}, got {kind!r}")
    if not (width_m > 0 and height_m > 0 and texel_m > 0):
        raise ValueError(f"width_m, height_m and texel_m must be > 0, got {width_m}, {height_m}, {texel_m}")
    rng = np.random.default_rng(rng)
    shape = (max(2, int(np.ceil(height_m / texel_m))), max(2, int(np.ceil(width_m / texel_m))))
    return _GENERATORS[kind](rng, shape, float(texel_m)).astype(np.float32)

