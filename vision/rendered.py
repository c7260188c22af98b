"""The rendered observation mode: render every view, detect, match, and label with ground truth.

``observe`` is the rendered counterpart of :func:`vision.geometric.observe` (same arguments first,
same :class:`~vision.observation.Observation` out): render each camera (:func:`vision.render.render`),
detect features in each image's region of interest (:func:`vision.features.detect`), match them across
views with the ratio test and epipolar gate (:func:`vision.features.match_views`), and attach the
per-pixel ground truth (:func:`label_tracks`) as ``feature_id`` and ``X_T_true``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from attitude.quaternion import matrix_from_quat
from vision.calibration import SiftCalibration, load_calibration
from vision.camera import PinholeCamera, cameras_per_view, check_pose
from vision.earth import EarthScene
from vision.features import Keypoints, detect, match_views
from vision.observation import REASON_OUTSIDE_FOV, Observation
from vision.render import (
    REASON_BEHIND_CAMERA,
    REASON_EARTH_SHADOW,
    RenderResult,
    cast_body_points,
    render,
    render_batch,
)
from vision.sensor import SensorModel
from vision.target import Target

__all__ = ["NOISE_MODELS", "detect_views", "foreground_mask", "label_tracks", "observe", "observe_renders",
           "render_views"]

#: ``noise_model`` values: the configured σ for every keypoint, or the σ measured for its SIFT size
NOISE_MODELS = ("fixed", "calibrated")


def render_views(camera: PinholeCamera | Sequence[PinholeCamera], T_CW: ArrayLike, target: Target,
                 q_HT: ArrayLike, sun_H: ArrayLike, *, rng: np.random.Generator | int | None = None,
                 batched: bool = True, **render_options: Any) -> list[RenderResult]:
    """Render the n views of one epoch, each with its own independent noise stream.

    ``T_CW`` is ``(n, 4, 4)``; ``render_options`` go to :func:`vision.render.render`.  ``batched``:
    all views in one :func:`vision.render.render_batch` call (the same images, faster); ``False``
    renders view by view (with ``sensor=SensorModel(noise_stream="tiles")``, the path before issue 16
    item 7, kept as the benchmark's baseline).
    """
    T = check_pose(T_CW, name="T_CW")
    if T.ndim != 3:
        raise ValueError(f"T_CW must have shape (n, 4, 4), got {T.shape}")
    cams = cameras_per_view(camera, len(T))
    rngs = np.random.default_rng(rng).spawn(len(T))
    if batched:
        return render_batch(list(cams), T, target, q_HT, sun_H, rngs=rngs, **render_options)
    return [render(c, t, target, q_HT, sun_H, rng=r, **render_options) for c, t, r in zip(cams, T, rngs, strict=True)]


def detect_views(renders: Sequence[RenderResult], *, detector: str = "sift", foreground_dn: float = 3.0,
                 detector_options: dict | None = None, threads: int = 1) -> list[Keypoints]:
    """Keypoints of every rendered view (in its ROI, on the target's foreground; none for a blind view).

    ``threads > 1`` detects the views concurrently (OpenCV releases the GIL); the keypoints are the
    same as one view after the other.
    """
    def one(r: RenderResult) -> Keypoints:
        if not r.ok:
            return detect(np.zeros((8, 8), np.uint8), detector=detector)
        kp = detect(r.image_roi, detector=detector, options=detector_options,
                    mask=_foreground_mask_roi(r, foreground_dn))
        return dataclasses.replace(kp, uv_px=kp.uv_px + np.array(r.roi[:2], dtype=float))

    if int(threads) <= 1 or len(renders) < 2:
        return [one(r) for r in renders]
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(min(int(threads), len(renders))) as pool:
        return list(pool.map(one, renders))


def label_tracks(obs: Observation, renders: Sequence[RenderResult], target: Target, q_HT: ArrayLike,
                 *, tol_px: float = 2.0) -> Observation:
    """Attach the renderer's per-pixel ground truth to the tracks of an observation.

    The body point seen at a keypoint is found by casting a ray through its sub-pixel position
    (:func:`vision.render.cast_body_points`), or, for a keypoint just off the silhouette, taken from
    the nearest target pixel within 2 px (:meth:`RenderResult.body_points_at`).
    A track is *correct* when, for every view j after its first view f, the body point seen at the
    keypoint of view f reprojects within ``tol_px`` of the keypoint in view j **and** the body point
    seen at the keypoint of view j reprojects within ``tol_px`` of the keypoint in view f (the second
    condition rejects matches onto an occluding surface). Correct tracks get ``feature_id`` = their
    index and ``X_T_true`` = the body point of the first view; the others get -1 and NaN.
    Rendered-mode ids are unique within one observation, not across epochs (use ``X_T_true``).
    """
    R_HT = matrix_from_quat(np.asarray(q_HT, dtype=float))
    M, n = obs.n_tracks, obs.n_views
    seen = obs.seen
    Xs = np.full((M, n, 3), np.nan)
    for i, r in enumerate(renders):
        sel = seen[:, i]
        if sel.any():
            X, _ = cast_body_points(r.camera, r.T_CW, target, q_HT, obs.uv_px[sel, i])
            miss = ~np.isfinite(X[:, 0])
            if miss.any():
                X[miss] = r.body_points_at(obs.uv_px[sel, i][miss])
            Xs[sel, i] = X

    def reproj(X_T, i):
        X_C = (obs.T_CW[i, :3, :3] @ (R_HT @ X_T.T)).T + obs.T_CW[i, :3, 3]
        return renders[i].camera.project(X_C)

    first = np.argmax(seen, axis=1)
    X_first = Xs[np.arange(M), first]
    uv_first = obs.uv_px[np.arange(M), first]
    correct = np.all(np.isfinite(X_first), axis=1)
    for j in range(n):
        sel = seen[:, j] & (first != j)
        if not sel.any():
            continue
        e1 = np.linalg.norm(reproj(X_first[sel], j) - obs.uv_px[sel, j], axis=1)
        e2 = np.full(sel.sum(), np.inf)
        idx = np.nonzero(sel)[0]
        for f in np.unique(first[idx]):
            k = first[idx] == f
            e2[k] = np.linalg.norm(reproj(Xs[idx[k], j], f) - uv_first[idx[k]], axis=1)
        bad = ~((e1 <= tol_px) & (e2 <= tol_px))
        correct[idx[bad]] = False
    fid = np.where(correct, np.arange(M), -1)
    X_true = np.where(correct[:, None], X_first, np.nan)
    return dataclasses.replace(obs, feature_id=fid, X_T_true=X_true)


def _foreground_mask_roi(r: RenderResult, threshold_dn: float) -> np.ndarray:
    """:func:`foreground_mask` of the full image, over the ROI only: the ROI padded with the full image's
    zeros by 2 px (the reach of the 3 × 3 closing) on its sides inside the image."""
    x0, y0, x1, y1 = r.roi
    H, W = r.camera.height, r.camera.width
    pad = ((2 * (y0 > 0), 2 * (y1 < H)), (2 * (x0 > 0), 2 * (x1 < W)))
    m = foreground_mask(np.pad(r.image_roi, pad), threshold_dn=threshold_dn)
    return m[pad[0][0]:m.shape[0] - pad[0][1], pad[1][0]:m.shape[1] - pad[1][1]]


def foreground_mask(image: ArrayLike, *, threshold_dn: float = 3.0) -> np.ndarray:
    """Target pixels segmented from the dark sky: ``image > threshold_dn``, closed with a 3×3 kernel.

    Keypoints centred on the sky (beyond the silhouette) have no surface point, and their 3-D
    position changes with the viewpoint, so detection is restricted to this mask.
    """
    import cv2

    img = np.asarray(image)
    m = (img > threshold_dn).astype(np.uint8)
    m = cv2.morphologyEx(m, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8))
    return m.astype(bool)


def observe_renders(renders: Sequence[RenderResult], target: Target, q_HT: ArrayLike, *,
                    detector: str = "sift",
                    ratio: float = 0.6, epipolar_tol_px: float = 1.5, pixel_sigma_px: float = 0.5,
                    min_views: int = 2, truth_tol_px: float = 2.0, foreground_dn: float = 3.0,
                    guided: bool = False, detector_options: dict | None = None,
                    noise_model: str = "fixed", calibration: SiftCalibration | None = None,
                    threads: int = 1) -> Observation:
    """Detect, match and label features in already rendered views of one epoch.

    ``threads``: views detected concurrently (:func:`detect_views`; the same keypoints).

    ``noise_model="fixed"`` gives every keypoint ``pixel_sigma_px``; ``"calibrated"`` gives each one
    the σ measured for its SIFT size at its view's image scale, scaled by the epoch's own variance
    factor (:mod:`vision.epoch_variance`) and inflated as measured beyond it for its track
    (:meth:`vision.calibration.SiftCalibration.track_sigma_px`; ``calibration``, default: the shipped calibration of the
    target, :func:`vision.calibration.load_calibration`) as ``track_sigma_px``, and records their
    root mean square as ``pixel_sigma_px``.
    Returns an empty, flagged observation (never raises) when the target is in Earth's shadow or seen
    by fewer than two views, or when no track survives matching.
    """
    if noise_model not in NOISE_MODELS:
        raise ValueError(f"noise_model must be one of {NOISE_MODELS}, got {noise_model!r}")
    cams = [r.camera for r in renders]
    T = np.stack([r.T_CW for r in renders])
    K = np.stack([c.K for c in cams])
    size = cams[0].image_size
    if all(r.failure_reason == REASON_EARTH_SHADOW for r in renders):
        return Observation.empty(K, T, size, pixel_sigma_px, REASON_EARTH_SHADOW)
    visible = [r.ok for r in renders]
    if sum(visible) < 2:
        # seen by fewer than two cameras: report the first blind view's reason
        reason = next(r.failure_reason for r in renders if not r.ok)
        return Observation.empty(K, T, size, pixel_sigma_px,
                                 REASON_OUTSIDE_FOV if reason == REASON_BEHIND_CAMERA else reason)
    kps = detect_views(renders, detector=detector, foreground_dn=foreground_dn, detector_options=detector_options,
                       threads=threads)
    obs = match_views(kps, cams, T, ratio=ratio, epipolar_tol_px=epipolar_tol_px,
                      min_views=min_views, pixel_sigma_px=pixel_sigma_px, guided=guided)
    if not obs.ok:
        return obs
    if noise_model == "calibrated":
        cal = calibration if calibration is not None else load_calibration(target.name)
        # σ of the keypoint's size at its view's image scale, inflated for its track (class, camera spread)
        sig = cal.track_sigma_px(obs)
        rms = float(np.sqrt(np.nanmean(sig**2)))
        obs = dataclasses.replace(obs, track_sigma_px=sig, pixel_sigma_px=rms)
    return label_tracks(obs, renders, target, q_HT, tol_px=truth_tol_px)


def observe(camera: PinholeCamera | Sequence[PinholeCamera], T_CW: ArrayLike, target: Target,
            q_HT: ArrayLike, sun_H: ArrayLike, *, rng: np.random.Generator | int | None = None,
            sensor: SensorModel | None = None, sun_visible_fraction: float = 1.0,
            detector: str = "sift", ratio: float = 0.6, epipolar_tol_px: float = 1.5,
            pixel_sigma_px: float = 0.5, min_views: int = 2, truth_tol_px: float = 2.0,
            roi: bool = True, guided: bool = False,
            detector_options: dict | None = None, noise_model: str = "fixed",
            calibration: SiftCalibration | None = None, earth: EarthScene | None = None) -> Observation:
    """Rendered-mode observation of one epoch by n cameras.

    Parameters
    ----------
    camera : PinholeCamera or sequence of n PinholeCamera
        Intrinsics (same image size).
    T_CW : array_like, shape (n, 4, 4)
        Camera poses (world = Hill frame H).
    target : Target
        Target model.
    q_HT : array_like, shape (4,)
        Target attitude (body → Hill).
    sun_H : array_like, shape (3,)
        Direction to the Sun, Hill components.
    rng : Generator, int or None
        Random source (independent stream per camera).
    sensor : SensorModel, optional
        Sensor chain of every camera.
    sun_visible_fraction : float
        1 in sunlight, 0 in Earth's umbra (gives an empty observation flagged
        ``"target in Earth shadow"``).
    detector, ratio, epipolar_tol_px, min_views, pixel_sigma_px :
        See :func:`vision.features.match_views`.
    truth_tol_px : float
        Reprojection tolerance of the ground-truth labelling (:func:`label_tracks`).
    roi : bool
        Render only the region of interest.
    guided : bool
        Epipolar-guided ratio test (:func:`vision.features.match_pair`).
    noise_model, calibration :
        ``"fixed"`` (``pixel_sigma_px`` for every keypoint) or ``"calibrated"`` (σ per keypoint from
        its SIFT size, :func:`observe_renders`).
    earth : EarthScene, optional
        The Earth behind the target and its albedo light (:mod:`vision.earth`); None: black sky.

    Returns
    -------
    Observation
    """
    if noise_model not in NOISE_MODELS:
        raise ValueError(f"noise_model must be one of {NOISE_MODELS}, got {noise_model!r}")
    renders = render_views(camera, T_CW, target, q_HT, sun_H, rng=rng, sensor=sensor,
                           sun_visible_fraction=sun_visible_fraction, roi=roi, earth=earth)
    return observe_renders(renders, target, q_HT, detector=detector, ratio=ratio,
                           epipolar_tol_px=epipolar_tol_px, pixel_sigma_px=pixel_sigma_px,
                           min_views=min_views, truth_tol_px=truth_tol_px, guided=guided,
                           detector_options=detector_options, noise_model=noise_model,
                           calibration=calibration)
