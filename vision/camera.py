"""Pinhole camera model and camera poses.

Conventions (``docs/conventions.md``):

- camera frame C in the OpenCV convention: z along the boresight, x right and y down in the image;
- pixel coordinates ``uv_px = (u, v)`` with u to the right and v down, and the origin at the
  **centre** of the top-left pixel (OpenCV). The image covers ``[-0.5, width - 0.5] × [-0.5,
  height - 0.5]``. COLMAP puts the origin at the top-left *corner* instead, so pixel coordinates and
  principal points differ by exactly 0.5 px between the two (see :func:`uv_colmap_from_opencv`);
- a camera pose is ``T_CW`` (camera-from-world, 4×4 homogeneous): ``X_C = R_CW X_W + t_CW``. It is
  OpenCV's ``(rvec, tvec)`` and pycolmap's ``cam_from_world``. The world frame W is the Hill frame H.

All functions broadcast over leading batch axes: points ``(..., 3)``, poses ``(..., 4, 4)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "PinholeCamera",
    "camera_center",
    "cameras_per_view",
    "check_pose",
    "invert_pose",
    "look_at",
    "pose_from_rigid3d",
    "pose_from_Rt",
    "pose_from_rvec_tvec",
    "rigid3d_from_pose",
    "Rt_from_pose",
    "rvec_tvec_from_pose",
    "transform_points",
    "uv_colmap_from_opencv",
    "uv_opencv_from_colmap",
]


# ----------------------------------------------------------------------------------------------
# poses
# ----------------------------------------------------------------------------------------------


def check_pose(T: ArrayLike, *, name: str = "T_CW", atol: float = 1e-6) -> np.ndarray:
    """Validate a homogeneous rigid transform (or a batch ``(..., 4, 4)``) and return it as float.

    Raises
    ------
    ValueError
        Naming ``name`` when the shape is not ``(..., 4, 4)``, an entry is not finite, the last row is
        not ``[0, 0, 0, 1]`` or the rotation block is not a proper rotation within ``atol``.
    """
    T = np.asarray(T, dtype=float)
    if T.ndim < 2 or T.shape[-2:] != (4, 4):
        raise ValueError(f"{name} must have shape (..., 4, 4), got {T.shape}")
    if not np.all(np.isfinite(T)):
        raise ValueError(f"{name} must be finite, got non-finite entries")
    if not np.allclose(T[..., 3, :], [0.0, 0.0, 0.0, 1.0], atol=atol):
        raise ValueError(f"{name} must have last row [0, 0, 0, 1], got {T[..., 3, :].tolist()}")
    R = T[..., :3, :3]
    err = np.abs(R @ np.swapaxes(R, -1, -2) - np.eye(3)).max(initial=0.0)
    if err > atol or np.any(np.linalg.det(R) <= 0):
        raise ValueError(f"{name} rotation block is not a proper rotation (|R R^T - I| = {err:.3g})")
    return T


def pose_from_Rt(R: ArrayLike, t: ArrayLike) -> np.ndarray:
    """Homogeneous transform ``(..., 4, 4)`` from a rotation ``(..., 3, 3)`` and translation ``(..., 3)``."""
    R = np.asarray(R, dtype=float)
    t = np.asarray(t, dtype=float)
    batch = np.broadcast_shapes(R.shape[:-2], t.shape[:-1])
    T = np.zeros((*batch, 4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = t
    T[..., 3, 3] = 1.0
    return T


def Rt_from_pose(T: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Rotation ``(..., 3, 3)`` and translation ``(..., 3)`` of a transform ``(..., 4, 4)``."""
    T = np.asarray(T, dtype=float)
    return T[..., :3, :3].copy(), T[..., :3, 3].copy()


def invert_pose(T_AB: ArrayLike) -> np.ndarray:
    """Inverse rigid transform: ``T_BA`` from ``T_AB`` (``(..., 4, 4)``), without a general inverse."""
    R, t = Rt_from_pose(T_AB)
    Rt = np.swapaxes(R, -1, -2)
    return pose_from_Rt(Rt, -np.einsum("...ij,...j->...i", Rt, t))


def camera_center(T_CW: ArrayLike) -> np.ndarray:
    """Camera centre in world components, ``r_C_W = -R_CWᵀ t_CW`` (``(..., 3)``, metres)."""
    R, t = Rt_from_pose(T_CW)
    return -np.einsum("...ji,...j->...i", R, t)


def transform_points(T_AB: ArrayLike, X_B: ArrayLike) -> np.ndarray:
    """Apply ``T_AB`` to points ``X_B`` (``(..., 3)``), broadcasting batch axes: ``X_A = R X_B + t``."""
    T = np.asarray(T_AB, dtype=float)
    X = np.asarray(X_B, dtype=float)
    return np.einsum("...ij,...j->...i", T[..., :3, :3], X) + T[..., :3, 3]


def look_at(eye_W: ArrayLike, target_W: ArrayLike, up_W: ArrayLike = (0.0, 0.0, 1.0)) -> np.ndarray:
    """Camera pose ``T_CW`` of a camera at ``eye_W`` whose boresight points at ``target_W``.

    The camera z axis points from the eye to the target, y (image down) is along ``-up_W`` projected
    perpendicular to the boresight, and x = y × z completes a right-handed frame (image right).

    Parameters
    ----------
    eye_W, target_W : array_like, shape (..., 3)
        Camera centre and look-at point, world components, metres (batches broadcast).
    up_W : array_like, shape (..., 3), optional
        World direction that appears "up" in the image (default +z of W).

    Returns
    -------
    T_CW : ndarray, shape (..., 4, 4)

    Raises
    ------
    ValueError
        If the eye coincides with the target or ``up_W`` is parallel to the boresight.
    """
    eye = np.asarray(eye_W, dtype=float)
    tgt = np.asarray(target_W, dtype=float)
    up = np.asarray(up_W, dtype=float)
    for name, a in (("eye_W", eye), ("target_W", tgt), ("up_W", up)):
        if a.shape[-1:] != (3,) or not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite with shape (..., 3), got shape {a.shape}")
    z = tgt - eye  # boresight
    nz = np.linalg.norm(z, axis=-1, keepdims=True)
    if np.any(nz <= 1e-12):
        raise ValueError("eye_W coincides with target_W: the boresight is undefined")
    z = z / nz
    y = -(up - np.sum(up * z, axis=-1, keepdims=True) * z)
    ny = np.linalg.norm(y, axis=-1, keepdims=True)
    if np.any(ny <= 1e-9 * np.linalg.norm(up, axis=-1, keepdims=True)) or np.any(ny == 0):
        raise ValueError(f"up_W {up.tolist()} is parallel to the boresight: choose another up vector")
    y = y / ny
    x = np.cross(y, z)
    R_WC = np.stack([x, y, z], axis=-1)
    R_CW = np.swapaxes(R_WC, -1, -2)
    return pose_from_Rt(R_CW, -np.einsum("...ij,...j->...i", R_CW, eye))


# --- OpenCV and pycolmap pose types ----------------------------------------------------------


def rvec_tvec_from_pose(T_CW: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV ``(rvec, tvec)`` (each ``(3,)``, rotation vector in radians) of one pose ``T_CW``."""
    import cv2

    T = check_pose(T_CW)
    if T.shape != (4, 4):
        raise ValueError(f"T_CW must be a single (4, 4) pose, got shape {T.shape}")
    rvec, _ = cv2.Rodrigues(T[:3, :3])
    return rvec.reshape(3), T[:3, 3].copy()


def pose_from_rvec_tvec(rvec: ArrayLike, tvec: ArrayLike) -> np.ndarray:
    """Pose ``T_CW`` (4×4) from OpenCV's ``(rvec, tvec)`` (as returned by ``cv2.solvePnP``)."""
    import cv2

    r = np.asarray(rvec, dtype=float).reshape(-1)
    t = np.asarray(tvec, dtype=float).reshape(-1)
    if r.shape != (3,) or t.shape != (3,):
        raise ValueError(f"rvec and tvec must have 3 elements, got {r.shape} and {t.shape}")
    R, _ = cv2.Rodrigues(r)
    return pose_from_Rt(R, t)


def rigid3d_from_pose(T_CW: ArrayLike) -> Any:
    """pycolmap ``Rigid3d`` (``cam_from_world``) of one pose ``T_CW``."""
    import pycolmap

    T = check_pose(T_CW)
    if T.shape != (4, 4):
        raise ValueError(f"T_CW must be a single (4, 4) pose, got shape {T.shape}")
    return pycolmap.Rigid3d(T[:3, :4])


def pose_from_rigid3d(cam_from_world: Any) -> np.ndarray:
    """Pose ``T_CW`` (4×4) from a pycolmap ``Rigid3d`` ``cam_from_world``."""
    M = np.asarray(cam_from_world.matrix(), dtype=float)
    return pose_from_Rt(M[:3, :3], M[:3, 3])


def uv_colmap_from_opencv(uv_px: ArrayLike) -> np.ndarray:
    """Pixel coordinates in COLMAP's convention (origin at the top-left pixel's corner): ``uv + 0.5``."""
    return np.asarray(uv_px, dtype=float) + 0.5


def uv_opencv_from_colmap(uv_px: ArrayLike) -> np.ndarray:
    """Pixel coordinates in OpenCV's convention (origin at the top-left pixel's centre): ``uv - 0.5``."""
    return np.asarray(uv_px, dtype=float) - 0.5


# ----------------------------------------------------------------------------------------------
# pinhole camera
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PinholeCamera:
    """Ideal pinhole camera (no distortion), OpenCV pixel convention.

    Projection: ``u = fx x/z + cx``, ``v = fy y/z + cy`` for a point ``(x, y, z)`` in the camera frame.

    Attributes
    ----------
    width, height : int
        Image size in pixels.
    fx, fy : float
        Focal lengths in pixels.
    cx, cy : float
        Principal point in pixels (OpenCV convention: the image centre is ``((w-1)/2, (h-1)/2)``).
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            v = getattr(self, name)
            if isinstance(v, bool) or int(v) != v or int(v) <= 0:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
            object.__setattr__(self, name, int(v))
        for name in ("fx", "fy", "cx", "cy"):
            v = float(getattr(self, name))
            if not np.isfinite(v) or (name in ("fx", "fy") and v <= 0):
                raise ValueError(f"{name} must be finite{' and > 0' if name[0] == 'f' else ''}, got {v!r}")
            object.__setattr__(self, name, v)

    # --- construction ---------------------------------------------------------------------

    @classmethod
    def from_fov(cls, width: int, height: int, *, fov_x_deg: float | None = None,
                 fov_x_rad: float | None = None) -> PinholeCamera:
        """Square-pixel camera with the given horizontal field of view, principal point at the centre.

        ``fx = fy = (width / 2) / tan(fov_x / 2)`` and ``(cx, cy) = ((width-1)/2, (height-1)/2)``.
        Give exactly one of ``fov_x_deg`` and ``fov_x_rad`` (full angle, in (0, 180°)).
        """
        if (fov_x_deg is None) == (fov_x_rad is None):
            raise ValueError("give exactly one of fov_x_deg and fov_x_rad")
        fov = np.deg2rad(float(fov_x_deg)) if fov_x_deg is not None else float(fov_x_rad)
        if not (0.0 < fov < np.pi):
            name, val = ("fov_x_deg", fov_x_deg) if fov_x_deg is not None else ("fov_x_rad", fov_x_rad)
            raise ValueError(f"{name} must be in (0, 180) degrees, got {val!r}")
        if isinstance(width, bool) or int(width) != width or int(width) <= 0:
            raise ValueError(f"width must be a positive integer, got {width!r}")
        f = 0.5 * int(width) / np.tan(0.5 * fov)
        return cls(int(width), height, f, f, 0.5 * (int(width) - 1), 0.5 * (int(height) - 1))

    @classmethod
    def from_K(cls, K: ArrayLike, width: int, height: int) -> PinholeCamera:
        """Camera from a 3×3 intrinsic matrix (zero skew) and the image size."""
        K = np.asarray(K, dtype=float)
        if K.shape != (3, 3) or abs(K[0, 1]) > 1e-9 or not np.allclose(K[2], [0, 0, 1]) or K[1, 0] != 0:
            raise ValueError(f"K must be a 3x3 zero-skew intrinsic matrix, got {K.tolist()}")
        return cls(width, height, K[0, 0], K[1, 1], K[0, 2], K[1, 2])

    # --- properties -------------------------------------------------------------------------

    @property
    def K(self) -> np.ndarray:
        """Intrinsic matrix ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def K_inv(self) -> np.ndarray:
        """Inverse of :attr:`K`."""
        return np.array([[1 / self.fx, 0.0, -self.cx / self.fx],
                         [0.0, 1 / self.fy, -self.cy / self.fy], [0.0, 0.0, 1.0]])

    @property
    def image_size(self) -> tuple[int, int]:
        """``(width, height)`` in pixels."""
        return (self.width, self.height)

    @property
    def fov_x_rad(self) -> float:
        """Full horizontal field of view, radians (``2 atan(width / (2 fx))``)."""
        return float(2.0 * np.arctan(0.5 * self.width / self.fx))

    @property
    def fov_y_rad(self) -> float:
        """Full vertical field of view, radians."""
        return float(2.0 * np.arctan(0.5 * self.height / self.fy))

    # --- projection -----------------------------------------------------------------------------

    def project(self, X_C: ArrayLike) -> np.ndarray:
        """Pixel coordinates ``(..., 2)`` of camera-frame points ``X_C`` (``(..., 3)``, metres).

        Points with ``z <= 0`` (on or behind the camera plane) give NaN.
        """
        X = np.asarray(X_C, dtype=float)
        if X.shape[-1:] != (3,):
            raise ValueError(f"X_C must have shape (..., 3), got {X.shape}")
        z = X[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = np.where(z > 0, 1.0 / z, np.nan)
        return np.stack([self.fx * X[..., 0] * inv + self.cx, self.fy * X[..., 1] * inv + self.cy],
                        axis=-1)

    def project_world(self, X_W: ArrayLike, T_CW: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Project world points through pose(s) ``T_CW``.

        Parameters
        ----------
        X_W : array_like, shape (..., 3)
            World points, metres.
        T_CW : array_like, shape (..., 4, 4)
            Camera pose(s); batch axes broadcast with those of ``X_W``.

        Returns
        -------
        uv_px : ndarray, shape (..., 2)
            Pixel coordinates (NaN behind the camera).
        depth_z_m : ndarray, shape (...)
            z-depth along the optical axis, metres.
        """
        X_C = transform_points(T_CW, X_W)
        return self.project(X_C), X_C[..., 2]

    def ray_directions(self, uv_px: ArrayLike) -> np.ndarray:
        """Camera-frame ray directions ``(..., 3)`` through pixels, scaled to unit **z** (not unit norm).

        ``d = ((u - cx)/fx, (v - cy)/fy, 1)``: the point at z-depth ``z`` on the ray is ``z d``.
        """
        uv = np.asarray(uv_px, dtype=float)
        if uv.shape[-1:] != (2,):
            raise ValueError(f"uv_px must have shape (..., 2), got {uv.shape}")
        return np.stack([(uv[..., 0] - self.cx) / self.fx, (uv[..., 1] - self.cy) / self.fy,
                         np.ones(uv.shape[:-1])], axis=-1)

    def backproject(self, uv_px: ArrayLike, depth_z_m: ArrayLike) -> np.ndarray:
        """Camera-frame points ``(..., 3)`` at z-depth ``depth_z_m`` (``(...)``) behind pixels ``uv_px``."""
        return self.ray_directions(uv_px) * np.asarray(depth_z_m, dtype=float)[..., None]

    def in_image(self, uv_px: ArrayLike, *, margin_px: float = 0.0) -> np.ndarray:
        """True where ``uv_px`` (``(..., 2)``) lies inside the image, at least ``margin_px`` from its edge.

        The image area is ``[-0.5, width - 0.5] × [-0.5, height - 0.5]`` (pixel centres at integers).
        NaN coordinates are outside.
        """
        uv = np.asarray(uv_px, dtype=float)
        u, v = uv[..., 0], uv[..., 1]
        m = float(margin_px)
        with np.errstate(invalid="ignore"):
            return ((u >= -0.5 + m) & (u <= self.width - 0.5 - m)
                    & (v >= -0.5 + m) & (v <= self.height - 0.5 - m))

    def pixel_footprint_m(self, depth_z_m: ArrayLike) -> np.ndarray:
        """Side of one pixel's footprint on a fronto-parallel plane at z-depth ``depth_z_m``, metres."""
        return np.asarray(depth_z_m, dtype=float) / np.sqrt(self.fx * self.fy)

    # --- library conversions -------------------------------------------------------------------

    def to_opencv(self) -> tuple[np.ndarray, np.ndarray]:
        """OpenCV's ``(cameraMatrix, distCoeffs)``: ``K`` and five zero distortion coefficients."""
        return self.K, np.zeros(5)

    def to_pycolmap(self, *, camera_id: int = 1) -> Any:
        """pycolmap ``Camera`` with model ``PINHOLE``.

        COLMAP's pixel origin is the top-left pixel's corner, so its principal point is
        ``(cx + 0.5, cy + 0.5)``: pass pixel coordinates through :func:`uv_colmap_from_opencv` before
        giving them to pycolmap estimators with this camera.
        """
        import pycolmap

        return pycolmap.Camera(model="PINHOLE", width=self.width, height=self.height,
                               params=[self.fx, self.fy, self.cx + 0.5, self.cy + 0.5],
                               camera_id=int(camera_id))

    @classmethod
    def from_pycolmap(cls, camera: Any) -> PinholeCamera:
        """Camera from a pycolmap ``Camera`` of model ``PINHOLE`` or ``SIMPLE_PINHOLE``."""
        name = str(camera.model_name)
        p = np.asarray(camera.params, dtype=float)
        if name == "PINHOLE":
            fx, fy, cx, cy = p
        elif name == "SIMPLE_PINHOLE":
            fx, cx, cy = p
            fy = fx
        else:
            raise ValueError(f"camera.model must be PINHOLE or SIMPLE_PINHOLE, got {name!r}")
        return cls(int(camera.width), int(camera.height), fx, fy, cx - 0.5, cy - 0.5)


def cameras_per_view(camera: PinholeCamera | Sequence[PinholeCamera], n: int) -> list[PinholeCamera]:
    """One :class:`PinholeCamera` per view: ``camera`` repeated n times, or the n given cameras.

    Parameters
    ----------
    camera : PinholeCamera or sequence of n PinholeCamera
        Intrinsics common to all views, or one per view.
    n : int
        Number of views.

    Returns
    -------
    list of PinholeCamera, length n

    Raises
    ------
    ValueError
        ``camera`` is not a camera or a sequence of n of them, or the views differ in image size.
    """
    cams = [camera] * n if isinstance(camera, PinholeCamera) else list(camera)
    if len(cams) != n or not all(isinstance(c, PinholeCamera) for c in cams):
        raise ValueError(f"camera must be a PinholeCamera or a sequence of {n} of them")
    if len({c.image_size for c in cams}) != 1:
        raise ValueError("camera: all views must have the same image size")
    return cams
