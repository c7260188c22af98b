"""The observation of one epoch by n cameras: multi-view tracks.

Both observation modes return an :class:`Observation`:

- the rendered mode (``vision.render`` → ``vision.features.match_views``): images are rendered,
  SIFT keypoints detected, matched with FLANN and Lowe's ratio test (0.6, paper 003), gated with the
  epipolar constraint of the known relative pose (003 eq 2–3, corrected form, flag P003-2,
  docs/papers.md#p003-2) and chained into multi-view tracks;
- the geometric mode (``vision.geometric.observe``): a fixed set of surface feature points is
  projected into every camera where visible, with Gaussian pixel noise and a fraction of false
  matches.

The structure is the same in both modes, so reconstruction cannot tell them apart. The fields
``feature_id`` and ``X_T_true`` are ground truth, for metrics and tests only; estimators must not use
them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "Observation",
    "REASON_EARTH_SHADOW",
    "REASON_OUTSIDE_FOV",
    "REASON_TOO_FEW_MATCHES",
]

#: ``failure_reason`` of an observation made while the target is in the Earth's shadow.
REASON_EARTH_SHADOW = "target in Earth shadow"
#: ``failure_reason`` when fewer than two cameras see the target.
REASON_OUTSIDE_FOV = "target outside field of view"
#: ``failure_reason`` when no multi-view track survives matching.
REASON_TOO_FEW_MATCHES = "too few matches"


@dataclass(frozen=True)
class Observation:
    """One epoch seen by n cameras: multi-view tracks (same structure for rendered and geometric modes).

    Attributes
    ----------
    uv_px : ndarray, shape (M, n, 2), float
        Pixel coordinates of track m in view i (OpenCV convention: x right, y down, origin at the
        centre of the top-left pixel). NaN where the track is absent in a view.
    descriptors : ndarray, shape (M, D), float32
        One descriptor per track (rendered mode: the SIFT descriptor of its keypoint in the first view
        where it is seen; geometric mode: a fixed random unit descriptor per surface feature, seeded
        from the target, plus small per-observation noise; false matches get unrelated descriptors).
    K : ndarray, shape (n, 3, 3)
        Intrinsic matrices of the n cameras.
    T_CW : ndarray, shape (n, 4, 4)
        Camera-from-world poses (world W = Hill frame H), see ``docs/conventions.md``.
    image_size : tuple of int
        ``(width, height)`` in pixels (the same for all views).
    pixel_sigma_px : float
        Pixel noise standard deviation used (geometric mode) or assumed (rendered mode), pixels.
    feature_id : ndarray, shape (M,), int
        Ground-truth id of the surface feature of each track; -1 for a false match or unknown.
        Truth only: never used by estimators.
    X_T_true : ndarray, shape (M, 3)
        Ground-truth target-body-frame coordinates of each track's point, metres (NaN when unknown).
        Truth only: never used by estimators.
    failure_reason : str
        Empty when the observation is usable, else why it has no tracks (e.g.
        ``"target in Earth shadow"``, ``"target outside field of view"``); see :attr:`ok`.
    track_sigma_px : ndarray, shape (M, n), optional
        Per track and view localisation σ per axis, px (NaN where the track is absent), when the
        observation knows it (the calibrated noise model: from each keypoint's SIFT size); None:
        every coordinate has ``pixel_sigma_px``.  :attr:`sigma_uv_px` gives the array either way.
    keypoint_size_px : ndarray, shape (M, n), optional
        Keypoint diameter per track and view, px (NaN where absent), when known.
    """

    uv_px: np.ndarray
    descriptors: np.ndarray
    K: np.ndarray
    T_CW: np.ndarray
    image_size: tuple[int, int]
    pixel_sigma_px: float
    feature_id: np.ndarray
    X_T_true: np.ndarray
    failure_reason: str = ""
    track_sigma_px: np.ndarray | None = None
    keypoint_size_px: np.ndarray | None = None

    def __post_init__(self) -> None:
        uv = np.asarray(self.uv_px, dtype=float)
        K = np.asarray(self.K, dtype=float)
        T = np.asarray(self.T_CW, dtype=float)
        if K.ndim != 3 or K.shape[1:] != (3, 3):
            raise ValueError(f"K must have shape (n, 3, 3), got {K.shape}")
        n = K.shape[0]
        if T.shape != (n, 4, 4):
            raise ValueError(f"T_CW must have shape ({n}, 4, 4), got {T.shape}")
        if uv.ndim != 3 or uv.shape[1:] != (n, 2):
            raise ValueError(f"uv_px must have shape (M, {n}, 2), got {uv.shape}")
        m = uv.shape[0]
        desc = np.asarray(self.descriptors, dtype=np.float32)
        if desc.ndim != 2 or desc.shape[0] != m:
            raise ValueError(f"descriptors must have shape ({m}, D), got {desc.shape}")
        fid = np.asarray(self.feature_id, dtype=np.int64)
        if fid.shape != (m,):
            raise ValueError(f"feature_id must have shape ({m},), got {fid.shape}")
        X = np.asarray(self.X_T_true, dtype=float)
        if X.shape != (m, 3):
            raise ValueError(f"X_T_true must have shape ({m}, 3), got {X.shape}")
        size = tuple(int(s) for s in self.image_size)
        if len(size) != 2 or min(size) <= 0:
            raise ValueError(f"image_size must be (width, height) > 0, got {self.image_size!r}")
        sigma = float(self.pixel_sigma_px)
        if not np.isfinite(sigma) or sigma < 0:
            raise ValueError(f"pixel_sigma_px must be finite and >= 0, got {self.pixel_sigma_px!r}")
        if not isinstance(self.failure_reason, str):
            raise ValueError(f"failure_reason must be a string, got {self.failure_reason!r}")
        for name in ("track_sigma_px", "keypoint_size_px"):
            a = getattr(self, name)
            if a is None:
                continue
            a = np.asarray(a, dtype=float)
            if a.shape != (m, n):
                raise ValueError(f"{name} must have shape ({m}, {n}), got {a.shape}")
            present = np.isfinite(uv).all(axis=-1)
            if not np.all(a[present] > 0):
                raise ValueError(f"{name} must be finite and > 0 wherever the track is seen")
            object.__setattr__(self, name, a)
        object.__setattr__(self, "uv_px", uv)
        object.__setattr__(self, "descriptors", desc)
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "T_CW", T)
        object.__setattr__(self, "image_size", size)
        object.__setattr__(self, "pixel_sigma_px", sigma)
        object.__setattr__(self, "feature_id", fid)
        object.__setattr__(self, "X_T_true", X)

    @property
    def n_views(self) -> int:
        """Number of cameras n."""
        return int(self.K.shape[0])

    @property
    def n_tracks(self) -> int:
        """Number of tracks M."""
        return int(self.uv_px.shape[0])

    @property
    def ok(self) -> bool:
        """True when the observation is usable (``failure_reason`` is empty)."""
        return not self.failure_reason

    @property
    def sigma_uv_px(self) -> np.ndarray:
        """``(M, n)`` localisation σ per axis of every track and view, px: :attr:`track_sigma_px` where
        given, else ``pixel_sigma_px`` (also where a track is absent)."""
        base = np.full((self.n_tracks, self.n_views), self.pixel_sigma_px)
        if self.track_sigma_px is None:
            return base
        return np.where(np.isfinite(self.track_sigma_px), self.track_sigma_px, base)

    @property
    def seen(self) -> np.ndarray:
        """``(M, n)`` bool: track m is present in view i."""
        return np.isfinite(self.uv_px).all(axis=-1)

    @classmethod
    def empty(
        cls,
        K: np.ndarray,
        T_CW: np.ndarray,
        image_size: tuple[int, int],
        pixel_sigma_px: float,
        failure_reason: str,
        *,
        descriptor_dim: int = 128,
    ) -> Observation:
        """An observation with no tracks, flagged with the reason.

        Parameters
        ----------
        K : ndarray, shape (n, 3, 3)
            Intrinsics of the n cameras.
        T_CW : ndarray, shape (n, 4, 4)
            Camera-from-world poses.
        image_size : tuple of int
            ``(width, height)`` in pixels.
        pixel_sigma_px : float
            Pixel noise standard deviation, pixels.
        failure_reason : str
            Why the observation is empty (e.g. ``"target in Earth shadow"``); must not be empty.
        descriptor_dim : int, optional
            Descriptor length D of the empty ``(0, D)`` descriptor array (128, SIFT's, by default).
        """
        if not failure_reason:
            raise ValueError("failure_reason: an empty observation needs a non-empty reason")
        K = np.asarray(K, dtype=float)
        n = K.shape[0] if K.ndim == 3 else 0
        return cls(
            uv_px=np.zeros((0, n, 2)),
            descriptors=np.zeros((0, int(descriptor_dim)), dtype=np.float32),
            K=K,
            T_CW=T_CW,
            image_size=image_size,
            pixel_sigma_px=pixel_sigma_px,
            feature_id=np.zeros(0, dtype=np.int64),
            X_T_true=np.zeros((0, 3)),
            failure_reason=failure_reason,
        )
