"""The result of rendering one view: the sensor image and the renderer's per-pixel ground truth.

:class:`RenderResult` is what :func:`vision.render.render` and :func:`vision.render.render_batch` return
(re-exported there); it also answers the body-frame truth at sub-pixel keypoint positions
(:meth:`RenderResult.body_points_at`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from vision.camera import PinholeCamera

__all__ = ["RenderResult"]


@dataclass(frozen=True, eq=False)
class RenderResult:
    """A rendered view with its per-pixel ground truth (all arrays full image size ``(H, W)``).

    Attributes
    ----------
    image : ndarray, (H, W), uint8 or uint16
        Sensor image (digital numbers).
    radiance : ndarray, (H, W), float32
        Noiseless, unblurred radiance (1 = white Lambertian surface facing the full Sun).
    depth_z_m : ndarray, (H, W), float32
        z-depth of the visible surface along the optical axis, metres; NaN off the target.
    mask : ndarray, (H, W), bool
        True on target pixels.
    X_T : ndarray, (H, W, 3), float32
        Body-frame coordinates of the surface point seen at each pixel centre, metres; NaN off target.
    triangle_id : ndarray, (H, W), int32
        Index of the hit triangle; -1 off the target.
    lit : ndarray, (H, W), bool
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

    image: np.ndarray
    radiance: np.ndarray
    depth_z_m: np.ndarray
    mask: np.ndarray
    X_T: np.ndarray
    triangle_id: np.ndarray
    lit: np.ndarray
    roi: tuple[int, int, int, int]
    failure_reason: str
    camera: PinholeCamera
    T_CW: np.ndarray
    exposure_s: float = float("nan")

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
        H, W = self.mask.shape
        out = np.full((len(uv), 3), np.nan)
        ui = np.rint(uv[:, 0]).astype(np.int64)
        vi = np.rint(uv[:, 1]).astype(np.int64)
        offs = sorted(((dx, dy) for dx in range(-search_px, search_px + 1)
                       for dy in range(-search_px, search_px + 1)), key=lambda d: d[0] ** 2 + d[1] ** 2)
        todo = np.ones(len(uv), dtype=bool)
        for dx, dy in offs:
            if not todo.any():
                break
            u, v = ui + dx, vi + dy
            ok = todo & (u >= 0) & (u < W) & (v >= 0) & (v < H)
            idx = np.nonzero(ok)[0]
            hit = self.mask[v[idx], u[idx]]
            idx = idx[hit]
            out[idx] = self.X_T[v[idx], u[idx]]
            todo[idx] = False
        return out
