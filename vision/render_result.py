"""The result of rendering one view: the sensor image and the renderer's per-pixel ground truth.

:class:`RenderResult` is what :func:`vision.render.render` and :func:`vision.render.render_batch` return
(re-exported there); it also answers the body-frame truth at sub-pixel keypoint positions
(:meth:`RenderResult.body_points_at`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

from vision.camera import PinholeCamera

__all__ = ["RenderResult"]


@dataclass(frozen=True, eq=False)
class RenderResult:
    """A rendered view with its per-pixel ground truth.

    The arrays are stored over the region of interest (``*_roi``, shape ``(h, w)`` of :attr:`roi`);
    the full-size ``(H, W)`` arrays (:attr:`image`, :attr:`radiance`, :attr:`depth_z_m`, :attr:`mask`,
    :attr:`X_T`, :attr:`triangle_id`, :attr:`lit`) are built on first access, with the values a
    full-frame render has off the target there (nothing is rendered outside the ROI).

    Attributes
    ----------
    image_roi : ndarray, (h, w), uint8 or uint16
        Sensor image (digital numbers); 0 outside the ROI.
    radiance_roi : ndarray, (h, w), float32
        Noiseless, unblurred radiance (1 = white Lambertian surface facing the full Sun); 0 outside.
    depth_z_m_roi : ndarray, (h, w), float32
        z-depth of the visible surface along the optical axis, metres; NaN off the target.
    mask_roi : ndarray, (h, w), bool
        True on target pixels.
    X_T_roi : ndarray, (h, w, 3), float32
        Body-frame coordinates of the surface point seen at each pixel centre, metres; NaN off target.
    triangle_id_roi : ndarray, (h, w), int32
        Index of the hit triangle; -1 off the target.
    lit_roi : ndarray, (h, w), bool
        True where the surface point is sunlit (facing the Sun and not self-shadowed).
    roi : tuple of int
        ``(x0, y0, x1, y1)``: the rendered pixel columns ``x0 <= u < x1`` and rows ``y0 <= v < y1``.
    failure_reason : str
        Empty when the target was rendered in sunlight, else ``"target in Earth shadow"`` (rendered,
        but dark), ``"target outside field of view"`` or ``"target behind camera"``; see :attr:`ok`.
    camera : PinholeCamera
    T_CW : ndarray, (4, 4)
    exposure_s : float
        Exposure time the sensor used, seconds (NaN when nothing was rendered).
    """

    image_roi: np.ndarray
    radiance_roi: np.ndarray
    depth_z_m_roi: np.ndarray
    mask_roi: np.ndarray
    X_T_roi: np.ndarray
    triangle_id_roi: np.ndarray
    lit_roi: np.ndarray
    roi: tuple[int, int, int, int]
    failure_reason: str
    camera: PinholeCamera
    T_CW: np.ndarray
    exposure_s: float = float("nan")

    def _full(self, crop: np.ndarray, fill: float | int | bool) -> np.ndarray:
        out = np.full((self.camera.height, self.camera.width) + crop.shape[2:], fill, dtype=crop.dtype)
        out[self.roi_slices] = crop
        return out

    @cached_property
    def image(self) -> np.ndarray:
        """Sensor image ``(H, W)``, digital numbers (0 outside the ROI)."""
        return self._full(self.image_roi, 0)

    @cached_property
    def radiance(self) -> np.ndarray:
        """Noiseless radiance ``(H, W)``, float32."""
        return self._full(self.radiance_roi, 0.0)

    @cached_property
    def depth_z_m(self) -> np.ndarray:
        """z-depth ``(H, W)``, metres, float32; NaN off the target."""
        return self._full(self.depth_z_m_roi, np.nan)

    @cached_property
    def mask(self) -> np.ndarray:
        """Target pixels ``(H, W)``."""
        return self._full(self.mask_roi, False)

    @cached_property
    def X_T(self) -> np.ndarray:
        """Body-frame point at each pixel centre ``(H, W, 3)``, metres, float32; NaN off the target."""
        return self._full(self.X_T_roi, np.nan)

    @cached_property
    def triangle_id(self) -> np.ndarray:
        """Hit triangle ``(H, W)``, int32; -1 off the target."""
        return self._full(self.triangle_id_roi, -1)

    @cached_property
    def lit(self) -> np.ndarray:
        """Sunlit target pixels ``(H, W)``."""
        return self._full(self.lit_roi, False)

    @property
    def ok(self) -> bool:
        """True when the target was rendered in sunlight (``failure_reason`` is empty)."""
        return not self.failure_reason

    @property
    def roi_slices(self) -> tuple[slice, slice]:
        """``(rows, cols)`` slices of the ROI."""
        x0, y0, x1, y1 = self.roi
        return slice(y0, y1), slice(x0, x1)

    def body_points_at(self, uv_px: ArrayLike, *, search_px: int = 2) -> np.ndarray:
        """Body-frame ground truth ``(N, 3)`` at pixel coordinates ``uv_px`` (``(N, 2)``).

        The nearest pixel's point; where that pixel is off the target (a keypoint on the silhouette),
        the nearest target pixel within ``search_px`` pixels. NaN when there is none.
        """
        uv = np.asarray(uv_px, dtype=float).reshape(-1, 2)
        H, W = self.mask_roi.shape                       # pixels outside the ROI are never target pixels
        out = np.full((len(uv), 3), np.nan)
        ui = np.rint(uv[:, 0]).astype(np.int64) - self.roi[0]
        vi = np.rint(uv[:, 1]).astype(np.int64) - self.roi[1]
        offs = sorted(((dx, dy) for dx in range(-search_px, search_px + 1)
                       for dy in range(-search_px, search_px + 1)), key=lambda d: d[0] ** 2 + d[1] ** 2)
        todo = np.ones(len(uv), dtype=bool)
        for dx, dy in offs:
            if not todo.any():
                break
            u, v = ui + dx, vi + dy
            ok = todo & (u >= 0) & (u < W) & (v >= 0) & (v < H)
            idx = np.nonzero(ok)[0]
            hit = self.mask_roi[v[idx], u[idx]]
            idx = idx[hit]
            out[idx] = self.X_T_roi[v[idx], u[idx]]
            todo[idx] = False
        return out
