"""Feature detection, pairwise matching with epipolar gating, and multi-view tracks.

Paper 003 §1.4 (step 4 of its pipeline): detect features in every view, match each pair of
views at the same epoch by approximate nearest neighbours with Lowe's ratio test (λ = 0.6), and
reject matches that violate the epipolar constraint of the known relative pose, 003 eq (2)–(3) in the
corrected form of flag P003-2 (docs/papers.md#p003-2):

- pixel homogeneous coordinates with ``F = K_A^-T [t_AB]x R_AB K_B^-1`` (eq 3), where
  ``X_A = R_AB X_B + t_AB`` maps camera-B coordinates into camera A (flag P003-2 (b));
- ``x_Aᵀ F x_B = 0`` holds to a tolerance: the distance from each point to the other's epipolar line
  must be below ``epipolar_tol_px`` (1.5 px, flag P003-2 (c)).

Detectors: SIFT (OpenCV, default). The paper used SURF (64-D); SURF is patented ("non-free") and the
PyPI build of OpenCV (``opencv-contrib-python-headless``) is compiled without it, so
``detector="surf"`` works only where ``cv2.xfeatures2d.SURF_create`` does (see
:func:`available_detectors`). ORB and AKAZE (binary descriptors, matched with FLANN's LSH index) are
options.

Float descriptors are L2-normalised (unit norm), the same scale as the geometric mode's descriptors.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from vision.camera import PinholeCamera, cameras_per_view, check_pose
from vision.observation import REASON_TOO_FEW_MATCHES, Observation

__all__ = [
    "Keypoints",
    "available_detectors",
    "detect",
    "epipolar_distance_px",
    "epipolar_residual",
    "fundamental_from_poses",
    "match_pair",
    "match_views",
    "tracks_from_matches",
]

DETECTORS = ("sift", "surf", "orb", "akaze")


@dataclass(frozen=True)
class Keypoints:
    """Keypoints of one image.

    Attributes
    ----------
    uv_px : ndarray, shape (K, 2)
        Pixel coordinates (OpenCV convention, pixel centres at integers).
    descriptors : ndarray, shape (K, D)
        float32 unit-norm (SIFT 128-D, SURF 64-D) or uint8 binary (ORB 32 B, AKAZE 61 B).
    size_px : ndarray, shape (K,)
        Keypoint diameter, pixels.
    angle_deg : ndarray, shape (K,)
        Orientation, degrees (OpenCV).
    response : ndarray, shape (K,)
        Detector response.
    detector : str
        Detector name.
    """

    uv_px: np.ndarray
    descriptors: np.ndarray
    size_px: np.ndarray
    angle_deg: np.ndarray
    response: np.ndarray
    detector: str

    def __len__(self) -> int:
        return int(len(self.uv_px))

    @property
    def binary(self) -> bool:
        """True for binary (uint8, Hamming) descriptors."""
        return self.descriptors.dtype == np.uint8

    def subset(self, idx: ArrayLike) -> Keypoints:
        """The keypoints selected by an index or boolean mask."""
        i = np.asarray(idx)
        return Keypoints(self.uv_px[i], self.descriptors[i], self.size_px[i], self.angle_deg[i],
                         self.response[i], self.detector)


def available_detectors() -> tuple[str, ...]:
    """Detectors usable with the installed OpenCV (SURF only when built with the non-free module)."""
    import cv2

    out = ["sift", "orb", "akaze"]
    try:
        cv2.xfeatures2d.SURF_create()
        out.insert(1, "surf")
    except (AttributeError, cv2.error):
        pass
    return tuple(out)


def _make_detector(detector: str, max_features: int, options: dict):
    import cv2

    if detector == "sift":
        # precise upscaling removes OpenCV's +0.25 px keypoint bias of the upsampled first octave
        opts = {"enable_precise_upscale": True}
        opts.update(options)
        return cv2.SIFT_create(nfeatures=int(max_features), **opts)
    if detector == "surf":
        try:
            # 003 names SURF without parameters; ours: Hessian threshold 400, 4 octaves, 3 layers, upright false
            opts = {"hessianThreshold": 400, "nOctaves": 4, "nOctaveLayers": 3, "upright": False}
            opts.update(options)
            return cv2.xfeatures2d.SURF_create(**opts)
        except (AttributeError, cv2.error) as exc:
            raise ValueError(
                "detector: 'surf' needs OpenCV built with the non-free module (OPENCV_ENABLE_NONFREE); "
                "the PyPI opencv-contrib-python-headless build has no SURF. Use 'sift' (the default), "
                "'orb' or 'akaze'") from exc
    if detector == "orb":
        return cv2.ORB_create(nfeatures=int(max_features) or 5000, **options)
    if detector == "akaze":
        create = getattr(cv2, "AKAZE_create", None) or cv2.xfeatures2d.AKAZE_create  # OpenCV 5 moved it
        return create(**options)
    raise ValueError(f"detector must be one of {DETECTORS}, got {detector!r}")


def detect(image: ArrayLike, *, detector: str = "sift", roi: tuple[int, int, int, int] | None = None,
           mask: ArrayLike | None = None, max_features: int = 0, options: dict | None = None) -> Keypoints:
    """Detect keypoints and compute descriptors.

    Parameters
    ----------
    image : array_like, shape (H, W), uint8 or uint16
        Grey image (uint16 is scaled to uint8 by its maximum value).
    detector : {"sift", "surf", "orb", "akaze"}
        Detector and descriptor.
    roi : (x0, y0, x1, y1), optional
        Detect only in this region (pixel columns ``x0 <= u < x1``, rows ``y0 <= v < y1``);
        coordinates are returned in the full image.
    mask : array_like of bool, shape (H, W), optional
        Detect only where True.
    max_features : int
        Keep the strongest ``max_features`` (0: all; ORB defaults to 5000).
    options : dict, optional
        Extra keyword arguments of the OpenCV constructor (e.g. ``{"contrastThreshold": 0.03}``).
    """

    img = np.asarray(image)
    if img.ndim != 2 or img.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"image must be a 2-D uint8 or uint16 array, got {img.dtype} {img.shape}")
    if img.dtype == np.uint16:
        img = (img.astype(np.float32) * (255.0 / max(1, int(img.max())))).astype(np.uint8)
    x0, y0 = 0, 0
    if roi is not None:
        x0, y0, x1, y1 = (int(r) for r in roi)
        if not (0 <= x0 < x1 <= img.shape[1] and 0 <= y0 < y1 <= img.shape[0]):
            raise ValueError(f"roi must lie inside the image {img.shape[::-1]}, got {roi!r}")
        img = img[y0:y1, x0:x1]
    m = None
    if mask is not None:
        m = np.asarray(mask, dtype=bool)
        if m.shape != np.asarray(image).shape:
            raise ValueError(f"mask must have the image's shape {np.asarray(image).shape}, got {m.shape}")
        m = m[y0:y0 + img.shape[0], x0:x0 + img.shape[1]].astype(np.uint8) * 255
    det = _make_detector(detector, max_features, dict(options or {}))
    kps, desc = det.detectAndCompute(np.ascontiguousarray(img), m)
    n = len(kps)
    if desc is None or n == 0:
        dim, dt = {"sift": (128, np.float32), "surf": (64, np.float32), "orb": (32, np.uint8),
                   "akaze": (61, np.uint8)}[detector]
        desc = np.zeros((0, dim), dtype=dt)
    uv = np.array([k.pt for k in kps], dtype=float).reshape(n, 2) + np.array([x0, y0], dtype=float)
    if desc.dtype != np.uint8:
        desc = desc.astype(np.float32)
        desc /= np.maximum(np.linalg.norm(desc, axis=1, keepdims=True), 1e-12)
    return Keypoints(uv, desc, np.array([k.size for k in kps], dtype=float),
                     np.array([k.angle for k in kps], dtype=float),
                     np.array([k.response for k in kps], dtype=float), detector)


# ----------------------------------------------------------------------------------------------
# epipolar geometry (003 eq 2–3, flag P003-2)
# ----------------------------------------------------------------------------------------------


def fundamental_from_poses(K_A: ArrayLike, T_AW: ArrayLike, K_B: ArrayLike, T_BW: ArrayLike) -> np.ndarray:
    """Fundamental matrix of two calibrated views, 003 eq (3) corrected (flag P003-2, docs/papers.md#p003-2).

    ``F = K_A^-T [t_AB]x R_AB K_B^-1`` with ``R_AB = R_AW R_BWᵀ``, ``t_AB = t_AW - R_AB t_BW``
    (``X_A = R_AB X_B + t_AB``), so that ``x_Aᵀ F x_B = 0`` for pixel homogeneous coordinates of the
    same world point in views A and B (003 eq 2).

    Parameters
    ----------
    K_A, K_B : array_like, shape (3, 3)
        Intrinsics.
    T_AW, T_BW : array_like, shape (4, 4)
        Camera-from-world poses.

    Returns
    -------
    F : ndarray, shape (3, 3)
        Scaled to unit Frobenius norm.
    """
    TA = check_pose(T_AW, name="T_AW")
    TB = check_pose(T_BW, name="T_BW")
    R_AB = TA[:3, :3] @ TB[:3, :3].T
    t_AB = TA[:3, 3] - R_AB @ TB[:3, 3]
    if np.linalg.norm(t_AB) < 1e-12:
        raise ValueError("T_AW and T_BW share the camera centre: the epipolar geometry is undefined")
    tx = np.array([[0, -t_AB[2], t_AB[1]], [t_AB[2], 0, -t_AB[0]], [-t_AB[1], t_AB[0], 0]])
    F = np.linalg.inv(np.asarray(K_A, float)).T @ tx @ R_AB @ np.linalg.inv(np.asarray(K_B, float))
    return F / np.linalg.norm(F)


def epipolar_residual(F: ArrayLike, uv_A: ArrayLike, uv_B: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Algebraic epipolar residual ``r = x_Aᵀ F x_B`` (``(N,)`` from ``(N, 2)`` inputs) and the two
    epipolar lines: ``l_A = F x_B`` in image A and ``l_B = Fᵀ x_A`` in image B, ``(N, 3)``."""
    F = np.asarray(F, dtype=float)
    a = np.asarray(uv_A, dtype=float)
    b = np.asarray(uv_B, dtype=float)
    xa = np.concatenate([a, np.ones(a.shape[:-1] + (1,))], axis=-1)
    xb = np.concatenate([b, np.ones(b.shape[:-1] + (1,))], axis=-1)
    la = xb @ F.T            # lines in image A
    lb = xa @ F              # lines in image B
    return np.sum(xa * la, axis=-1), la, lb


def epipolar_distance_px(F: ArrayLike, uv_A: ArrayLike, uv_B: ArrayLike) -> np.ndarray:
    """Larger of the two point-to-epipolar-line distances, pixels (``(N,)`` from ``(N, 2)`` inputs).

    The line of ``x_B`` in image A is ``F x_B``; that of ``x_A`` in image B is ``Fᵀ x_A``.
    """
    r, la, lb = epipolar_residual(F, uv_A, uv_B)
    with np.errstate(divide="ignore", invalid="ignore"):
        da = np.abs(r) / np.hypot(la[..., 0], la[..., 1])
        db = np.abs(r) / np.hypot(lb[..., 0], lb[..., 1])
    return np.maximum(da, db)


# ----------------------------------------------------------------------------------------------
# matching
# ----------------------------------------------------------------------------------------------


def _flann_index(desc_b: np.ndarray, *, flann_trees: int, flann_checks: int) -> _FlannIndex:
    """A FLANN index of the descriptors ``desc_b`` (non-empty): kd-trees, or LSH for binary ones."""
    import cv2

    if desc_b.dtype == np.uint8:
        params = {"algorithm": 6, "table_number": 6, "key_size": 12, "multi_probe_level": 1}  # LSH
    else:
        params = {"algorithm": 1, "trees": int(flann_trees)}                                # kd-tree
    # FLANN's randomised kd-trees draw from OpenCV's (thread-local) RNG when they are built: seed it
    # so that matching is reproducible (searching draws nothing, so a built index can be reused).
    cv2.setRNGSeed(0)
    return _FlannIndex(cv2.flann_Index(np.ascontiguousarray(desc_b), params), int(flann_checks),
                       desc_b.dtype == np.uint8)


class _FlannIndex:
    """``cv2.flann_Index`` of one view's descriptors and its search checks.

    The same index and search as ``cv2.FlannBasedMatcher`` (which wraps a ``flann::Index`` built with
    these parameters) with the neighbours returned as arrays: the matcher's ``DMatch`` lists cost about
    as much again as the search.  Distances are L2 (FLANN's squared L2, rooted in float32 as the
    matcher does) or Hamming for binary descriptors.
    """

    def __init__(self, index, checks: int, binary: bool):
        self.index, self.checks, self.binary = index, checks, binary

    def search(self, desc_a: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """``(idx (N, k), dist (N, k))``, neighbours sorted by distance, -1 / inf where none was found."""
        idx, d = self.index.knnSearch(np.ascontiguousarray(desc_a), k, params={"checks": self.checks})
        idx = idx.astype(np.int64)
        dist = d.astype(np.float64) if self.binary else np.sqrt(d.astype(np.float32)).astype(np.float64)
        dist[idx < 0] = np.inf
        idx[idx < 0] = -1
        return idx, dist


def _knn(desc_a: np.ndarray, desc_b: np.ndarray, k: int, *, flann_trees: int, flann_checks: int,
         index: _FlannIndex | None = None):
    """k approximate nearest neighbours (FLANN) in B of every descriptor of A.

    ``index``: :func:`_flann_index` of ``desc_b`` if already built.
    Returns ``(idx (N, k), dist (N, k))`` with -1 / inf where fewer than k were found.
    """
    n = len(desc_a)
    idx = np.full((n, k), -1, dtype=np.int64)
    dist = np.full((n, k), np.inf)
    if n == 0 or len(desc_b) == 0:
        return idx, dist
    if index is None:
        index = _flann_index(desc_b, flann_trees=flann_trees, flann_checks=flann_checks)
    kk = min(k, len(desc_b))
    idx[:, :kk], dist[:, :kk] = index.search(desc_a, kk)
    return idx, dist


def match_pair(kp_A: Keypoints, kp_B: Keypoints, *, ratio: float = 0.6, F_AB: ArrayLike | None = None,
               epipolar_tol_px: float = 1.5, guided: bool = False, guided_k: int = 16,
               flann_trees: int = 4, flann_checks: int = 32, flann_index=None) -> np.ndarray:
    """Match two keypoint sets: FLANN nearest neighbours, Lowe's ratio test, epipolar gate, one-to-one.

    Two orders of the same three tests (003 §1.4 uses the epipolar constraint "to shrink the search
    region and reject outliers"):

    - ``guided=False`` (default, the paper's order): 2-NN ratio test over all of B, then the epipolar
      gate;
    - ``guided=True`` (needs ``F_AB``): among the ``guided_k`` nearest neighbours of each
      A descriptor, keep only the B keypoints within ``epipolar_tol_px`` of the epipolar line, and
      apply the ratio test to the two nearest of those. When fewer than two of the ``guided_k``
      neighbours are in the band, the second distance is bounded below by the k-th neighbour's, so the
      test is conservative. Repetitive texture elsewhere in the image no longer vetoes a match, so
      more matches survive, at a lower inlier rate (``docs/vision.md`` has measured figures).

    Parameters
    ----------
    kp_A, kp_B : Keypoints
        Keypoints of views A and B (same detector).
    ratio : float
        Lowe's ratio λ: keep a match when ``d_1st / d_2nd < ratio`` (003: 0.6).
    F_AB : array_like, shape (3, 3), optional
        Fundamental matrix with ``x_Aᵀ F x_B = 0`` (:func:`fundamental_from_poses`); no gate if None.
    epipolar_tol_px : float
        Largest point-to-epipolar-line distance kept, pixels (flag P003-2 (c): 1.5 px).
    guided, guided_k : bool, int
        Epipolar-guided search and its neighbour count.
    flann_trees, flann_checks : int
        FLANN kd-tree parameters (4 trees, 32 checks by default: our choice, 003 gives none).
    flann_index : optional
        A FLANN index of ``kp_B``'s descriptors built with these parameters
        (:func:`match_views` reuses one per view); built here if None.

    Returns
    -------
    ndarray, shape (M, 2), int
        Index pairs ``(i_A, i_B)``; each keypoint appears at most once.
    """
    if not 0.0 < ratio <= 1.0:
        raise ValueError(f"ratio must be in (0, 1], got {ratio!r}")
    if not epipolar_tol_px > 0:
        raise ValueError(f"epipolar_tol_px must be > 0, got {epipolar_tol_px!r}")
    if int(guided_k) < 2:
        raise ValueError(f"guided_k must be >= 2, got {guided_k!r}")
    if kp_A.descriptors.dtype != kp_B.descriptors.dtype or \
            kp_A.descriptors.shape[1] != kp_B.descriptors.shape[1]:
        raise ValueError("kp_A and kp_B must come from the same detector (descriptor types differ)")
    use_guided = guided and F_AB is not None
    k = int(guided_k) if use_guided else 2
    idx, dist = _knn(kp_A.descriptors, kp_B.descriptors, k, flann_trees=flann_trees,
                     flann_checks=flann_checks, index=flann_index)
    if use_guided:
        valid = idx >= 0
        rows = np.repeat(np.arange(len(idx)), k).reshape(idx.shape)
        e = np.full(idx.shape, np.inf)
        e[valid] = epipolar_distance_px(F_AB, kp_A.uv_px[rows[valid]], kp_B.uv_px[idx[valid]])
        band = valid & (e <= epipolar_tol_px)
        # order of the in-band candidates (FLANN returns neighbours sorted by distance)
        rank = np.cumsum(band, axis=1) - 1
        d_band = np.where(band, dist, np.inf)
        first = np.argmax(band, axis=1)
        has1 = band.any(axis=1)
        d1 = np.where(has1, d_band[np.arange(len(idx)), first], np.inf)
        second = np.where(band & (rank == 1), dist, np.inf).min(axis=1)
        kth = np.where(valid, dist, -np.inf).max(axis=1)
        d2 = np.where(np.isfinite(second), second, kth)
        with np.errstate(invalid="ignore"):
            good = has1 & (d1 < ratio * d2)
        ia = np.nonzero(good)[0]
        ib = idx[ia, first[ia]]
        d = d1[ia]
    else:
        with np.errstate(invalid="ignore", divide="ignore"):
            good = (idx[:, 0] >= 0) & (dist[:, 0] < ratio * dist[:, 1])
        ia = np.nonzero(good)[0]
        ib = idx[ia, 0]
        d = dist[ia, 0]
    # one-to-one: where several A keypoints chose the same B keypoint keep the closest
    order = np.lexsort((d, ib))
    first_b = np.ones(len(order), dtype=bool)
    first_b[1:] = ib[order][1:] != ib[order][:-1]
    keep = order[first_b]
    pairs = np.stack([ia[keep], ib[keep]], axis=1)
    if F_AB is not None and len(pairs) and not use_guided:
        e = epipolar_distance_px(F_AB, kp_A.uv_px[pairs[:, 0]], kp_B.uv_px[pairs[:, 1]])
        pairs = pairs[e <= epipolar_tol_px]
    return pairs[np.argsort(pairs[:, 0])]


def tracks_from_matches(n_keypoints: Sequence[int], pair_matches: dict[tuple[int, int], np.ndarray], *,
                        min_views: int = 2) -> np.ndarray:
    """Chain pairwise matches into multi-view tracks.

    Keypoints are graph nodes and matches edges; every connected component with at most one keypoint
    per view and at least ``min_views`` views is a track. Components holding two keypoints of the same
    view are inconsistent and dropped.

    Parameters
    ----------
    n_keypoints : sequence of int
        Number of keypoints in each of the n views.
    pair_matches : dict
        ``{(i, j): (M, 2) index pairs}`` for view pairs ``i < j``.
    min_views : int
        Smallest number of views of a kept track.

    Returns
    -------
    ndarray, shape (T, n), int
        Keypoint index of each track in each view, -1 where absent.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n_views = len(n_keypoints)
    offs = np.concatenate([[0], np.cumsum(n_keypoints)]).astype(np.int64)
    N = int(offs[-1])
    rows, cols = [], []
    for (i, j), pm in pair_matches.items():
        pm = np.asarray(pm, dtype=np.int64).reshape(-1, 2)
        rows.append(pm[:, 0] + offs[i])
        cols.append(pm[:, 1] + offs[j])
    if N == 0 or not rows or sum(len(r) for r in rows) == 0:
        return np.zeros((0, n_views), dtype=np.int64)
    r = np.concatenate(rows)
    c = np.concatenate(cols)
    g = coo_matrix((np.ones(len(r)), (r, c)), shape=(N, N))
    _, label = connected_components(g, directed=False)
    view_of = np.repeat(np.arange(n_views), n_keypoints)
    local = np.arange(N) - offs[view_of]
    used = np.zeros(N, dtype=bool)
    used[r] = True
    used[c] = True
    nodes = np.nonzero(used)[0]
    lab = label[nodes]
    uniq, comp = np.unique(lab, return_inverse=True)
    counts = np.zeros((len(uniq), n_views), dtype=np.int64)
    np.add.at(counts, (comp, view_of[nodes]), 1)
    ok = (counts.max(axis=1) <= 1) & ((counts > 0).sum(axis=1) >= min_views)
    tracks = np.full((len(uniq), n_views), -1, dtype=np.int64)
    tracks[comp, view_of[nodes]] = local[nodes]
    return tracks[ok]


def match_views(keypoints: Sequence[Keypoints], camera: PinholeCamera | Sequence[PinholeCamera],
                T_CW: ArrayLike, *, ratio: float = 0.6, epipolar_tol_px: float = 1.5,
                min_views: int = 2, pixel_sigma_px: float = 0.5, guided: bool = False,
                flann_trees: int = 4, flann_checks: int = 32) -> Observation:
    """Match keypoints across n views of one epoch into multi-view tracks (003 §1.4, eq 2–3).

    Every pair of views is matched with :func:`match_pair` (ratio test, one-to-one, epipolar gate
    from the known poses); the matches are chained by :func:`tracks_from_matches`; a track whose views
    are not all pairwise consistent with the epipolar constraint is dropped.

    Parameters
    ----------
    keypoints : sequence of Keypoints
        Keypoints of the n views.
    camera : PinholeCamera or sequence of n PinholeCamera
        Intrinsics (one camera for all views or one per view; same image size).
    T_CW : array_like, shape (n, 4, 4)
        Camera poses.
    ratio, epipolar_tol_px : float
        Ratio-test threshold (0.6, paper 003) and epipolar tolerance (1.5 px, flag P003-2).
    min_views : int
        Smallest number of views in a track.
    pixel_sigma_px : float
        Keypoint position noise assumed downstream, recorded in the observation.
    guided : bool
        Epipolar-guided ratio test (:func:`match_pair`); default the paper's order.

    Returns
    -------
    Observation
        Tracks with the descriptor of each track's first view and the keypoint diameters
        (``keypoint_size_px``); ``feature_id = -1`` and
        ``X_T_true = NaN`` (no ground truth here: see :func:`vision.rendered.label_tracks`).
        ``failure_reason`` is ``"too few matches"`` when no track survives.
    """
    kps = list(keypoints)
    n = len(kps)
    T = check_pose(T_CW, name="T_CW")
    if T.shape != (n, 4, 4):
        raise ValueError(f"T_CW must have shape ({n}, 4, 4), got {T.shape}")
    cams = cameras_per_view(camera, n)
    if n < 2:
        raise ValueError(f"keypoints: need at least 2 views, got {n}")
    if not 2 <= min_views <= n:
        raise ValueError(f"min_views must be in [2, {n}], got {min_views!r}")
    K = np.stack([c.K for c in cams])
    Fs = {}
    pm = {}
    index = {}                                 # FLANN index of view j, built once for all pairs (i, j)
    for i in range(n):
        for j in range(i + 1, n):
            Fs[i, j] = fundamental_from_poses(K[i], T[i], K[j], T[j])
            if j not in index and len(kps[i]) and len(kps[j]):
                index[j] = _flann_index(kps[j].descriptors, flann_trees=flann_trees, flann_checks=flann_checks)
            pm[i, j] = match_pair(kps[i], kps[j], ratio=ratio, F_AB=Fs[i, j],
                                  epipolar_tol_px=epipolar_tol_px, guided=guided,
                                  flann_trees=flann_trees,
                                  flann_checks=flann_checks, flann_index=index.get(j))
    tracks = tracks_from_matches([len(k) for k in kps], pm, min_views=min_views)
    M = len(tracks)
    uv = np.full((M, n, 2), np.nan)
    size = np.full((M, n), np.nan)
    for i in range(n):
        sel = tracks[:, i] >= 0
        uv[sel, i] = kps[i].uv_px[tracks[sel, i]]
        size[sel, i] = kps[i].size_px[tracks[sel, i]]
    # every pair of views in a track must satisfy the epipolar constraint (chains skip some pairs)
    good = np.ones(M, dtype=bool)
    for (i, j), F in Fs.items():
        both = (tracks[:, i] >= 0) & (tracks[:, j] >= 0)
        if both.any():
            e = epipolar_distance_px(F, uv[both, i], uv[both, j])
            good[np.nonzero(both)[0][e > epipolar_tol_px]] = False
    tracks, uv, size = tracks[good], uv[good], size[good]
    M = len(tracks)
    dim = kps[0].descriptors.shape[1]
    desc = np.zeros((M, dim), dtype=np.float32)
    first = np.argmax(tracks >= 0, axis=1)
    for i in range(n):
        sel = first == i
        desc[sel] = kps[i].descriptors[tracks[sel, i]].astype(np.float32)
    return Observation(uv_px=uv, descriptors=desc, K=K, T_CW=T, image_size=cams[0].image_size,
                       pixel_sigma_px=pixel_sigma_px, feature_id=np.full(M, -1, dtype=np.int64),
                       X_T_true=np.full((M, 3), np.nan),
                       failure_reason="" if M > 0 else REASON_TOO_FEW_MATCHES,
                       keypoint_size_px=np.where(np.isfinite(size), np.maximum(size, 1e-6), np.nan))
