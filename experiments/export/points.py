"""The snapshot epoch of a stored closed-loop run as a PLY point cloud and as a COLMAP model.

``write_ply``
    The triangulated cloud ``snapshot_X_W_m`` (world frame W = H at the snapshot epoch, metres),
    valid points only by default, written by Open3D (``open3d.t.io.write_point_cloud``) with two
    extra ``uchar`` vertex properties: ``n_views`` (cameras that saw the track) and ``correct``
    (1 when the track follows one true surface feature, 0 for a simulated false match).
``write_colmap``
    A COLMAP sparse model written by pycolmap: one ``PINHOLE`` camera (the run's intrinsics), one
    image per observer active at the snapshot with its pose ``cam_from_world = T_CW`` (the look-at
    pose of :func:`formation.quality.camera_poses_at_target`, as in the loop), its 2-D track
    observations as keypoints, and the valid triangulated points with their tracks.  COLMAP puts
    the origin of pixel coordinates at the top-left corner of the top-left pixel, coobs (OpenCV) at
    its centre: principal point and keypoints are shifted by +0.5 px
    (:func:`vision.camera.uv_colmap_from_opencv`).  The snapshot images go to ``images/`` and the
    points take their grey level from them (``Reconstruction.extract_colors_for_all_images``).
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from pathlib import Path

import numpy as np
import xarray as xr

from experiments.export.run import camera_of, require, snapshot_epoch_index
from formation.quality import camera_poses_at_target
from vision.camera import rigid3d_from_pose, uv_colmap_from_opencv

__all__ = ["SNAPSHOT_VARIABLES", "write_ply", "write_colmap", "snapshot_poses", "image_names"]

#: variables a snapshot export reads
SNAPSHOT_VARIABLES = ("snapshot_uv_px", "snapshot_X_W_m", "snapshot_point_valid", "snapshot_track_correct",
                      "snapshot_image", "r_H_m")


def image_names(ds: xr.Dataset) -> list[str]:
    """File names ``<index>_<observer>.png`` of the snapshot images (observer names made file-safe)."""
    names = [str(s) for s in ds["spacecraft"].values]
    views = np.asarray(ds["snapshot_view"].values, dtype=int)
    return [f"{j:02d}_{re.sub(r'[^A-Za-z0-9_.-]+', '_', names[int(v)])}.png" for j, v in enumerate(views)]


def snapshot_poses(ds: xr.Dataset) -> np.ndarray:
    """Poses ``T_CW (n_views, 4, 4)`` (H → C) of the cameras active at the snapshot epoch."""
    require(ds, SNAPSHOT_VARIABLES, "a snapshot export")
    k = snapshot_epoch_index(ds)
    views = np.asarray(ds["snapshot_view"].values, dtype=int)
    return camera_poses_at_target(np.asarray(ds["r_H_m"].values, dtype=float)[views, k])


def write_ply(ds: xr.Dataset, path: Path | str, *, valid_only: bool = True) -> Path:
    """Write the snapshot's triangulated cloud as a binary PLY file (Open3D).

    Parameters
    ----------
    ds : xarray.Dataset
        A stored closed-loop run with a snapshot (:func:`experiments.export.open_run`).
    path : path
        The ``.ply`` file (replaced if it exists; its folder is created).
    valid_only : bool, keyword-only
        Write only points the triangulation marked valid (``snapshot_point_valid``); otherwise
        every finite point, with a ``valid`` property.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    ValueError
        ``run:`` when the dataset has no snapshot or no point to write; nothing is written then.
    """
    import open3d as o3d

    require(ds, SNAPSHOT_VARIABLES, "the PLY")
    X = np.asarray(ds["snapshot_X_W_m"].values, dtype=float)
    valid = np.asarray(ds["snapshot_point_valid"].values, dtype=bool)
    keep = np.all(np.isfinite(X), axis=1) & (valid if valid_only else True)
    if not keep.any():
        raise ValueError("run: the snapshot has no valid triangulated point to write")
    n_views = np.sum(np.all(np.isfinite(ds["snapshot_uv_px"].values), axis=2), axis=1)
    pc = o3d.t.geometry.PointCloud(o3d.core.Tensor(X[keep], dtype=o3d.core.float64))
    pc.point["n_views"] = o3d.core.Tensor(n_views[keep, None].astype(np.uint8))
    pc.point["correct"] = o3d.core.Tensor(np.asarray(ds["snapshot_track_correct"].values)[keep, None].astype(np.uint8))
    if not valid_only:
        pc.point["valid"] = o3d.core.Tensor(valid[keep, None].astype(np.uint8))
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.stem}.", suffix=".ply", dir=p.parent)
    os.close(fd)
    try:
        if not o3d.t.io.write_point_cloud(tmp, pc, write_ascii=False):
            raise OSError(f"Open3D could not write {tmp}")
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p


def _reconstruction(ds: xr.Dataset):
    """The pycolmap reconstruction of the snapshot (no colours yet)."""
    import pycolmap

    T_CW = snapshot_poses(ds)
    cam = camera_of(ds)
    h, w = ds["snapshot_image"].shape[1:]
    if (w, h) != tuple(cam.image_size):
        raise ValueError(f"run: snapshot images are {w}x{h} px but the stored config's camera is "
                         f"{cam.image_size[0]}x{cam.image_size[1]}")
    cx, cy = uv_colmap_from_opencv([cam.cx, cam.cy])
    rec = pycolmap.Reconstruction()
    rec.add_camera_with_trivial_rig(pycolmap.Camera(model="PINHOLE", width=int(w), height=int(h),
                                                    params=[cam.fx, cam.fy, cx, cy], camera_id=1))
    uv = np.asarray(ds["snapshot_uv_px"].values, dtype=float)          # (track, view, 2), NaN = unseen
    X = np.asarray(ds["snapshot_X_W_m"].values, dtype=float)
    valid = np.asarray(ds["snapshot_point_valid"].values, dtype=bool) & np.all(np.isfinite(X), axis=1)
    seen = np.all(np.isfinite(uv), axis=2)
    idx_of = {}                                                          # (track, view) -> point2D index
    for j, name in enumerate(image_names(ds)):
        tracks = np.flatnonzero(seen[:, j])
        idx_of.update({(int(i), j): n for n, i in enumerate(tracks)})
        image = pycolmap.Image(name=name, keypoints=uv_colmap_from_opencv(uv[tracks, j]), camera_id=1,
                               image_id=j + 1)
        rec.add_image_with_trivial_frame(image, rigid3d_from_pose(T_CW[j]))
    for i in np.flatnonzero(valid):
        track = pycolmap.Track()
        for j in np.flatnonzero(seen[i]):
            track.add_element(int(j) + 1, idx_of[(int(i), int(j))])
        if track.length() >= 2:
            rec.add_point3D(X[i], track)
    rec.update_point_3d_errors()                                         # points3D ERROR: reprojection RMS, px
    return rec


def write_colmap(ds: xr.Dataset, folder: Path | str, *, binary: bool = False, images: bool = True) -> Path:
    """Write the snapshot as a COLMAP sparse model (``cameras``, ``images``, ``points3D``, ``rigs``, ``frames``).

    Parameters
    ----------
    ds : xarray.Dataset
        A stored closed-loop run with a snapshot (:func:`experiments.export.open_run`).
    folder : path
        Output folder: the model goes to ``folder/sparse/``, the images to ``folder/images/``
        (both replaced if they exist).
    binary : bool, keyword-only
        COLMAP's binary files (``.bin``) instead of text (``.txt``).
    images : bool, keyword-only
        Also write the snapshot images as PNG and colour the points from them.

    Returns
    -------
    Path
        ``folder/sparse``, which ``pycolmap.Reconstruction(path)`` (and COLMAP) reads.

    Raises
    ------
    ValueError
        ``run:`` when the dataset has no snapshot or no triangulated point seen twice; nothing is
        written then.
    """
    import cv2

    rec = _reconstruction(ds)
    if rec.num_points3D() == 0:
        raise ValueError("run: the snapshot has no valid triangulated point seen by two cameras")
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".colmap-", dir=out))
    try:
        (tmp / "sparse").mkdir()
        if images:
            (tmp / "images").mkdir()
            imgs = np.asarray(ds["snapshot_image"].values)
            for name, img in zip(image_names(ds), imgs, strict=True):
                if not cv2.imwrite(str(tmp / "images" / name), img):
                    raise OSError(f"OpenCV could not write {name}")
            rec.extract_colors_for_all_images(str(tmp / "images"))
        (rec.write_binary if binary else rec.write_text)(str(tmp / "sparse"))
        for sub in ("sparse", "images"):
            if (tmp / sub).exists():
                if (out / sub).exists():
                    shutil.rmtree(out / sub)
                os.replace(tmp / sub, out / sub)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out / "sparse"
