"""The geometric mode driven by the rendered-mode calibration (``noise_model = "calibrated"``).

Same surface features as :mod:`vision.geometric` and its visibility tests towards the cameras (in
the image, facing the camera, unoccluded); the Sun only sets each feature's Sun bin (lit, with its
incidence, or in shadow / facing away: rendered keypoints are found there too, on shadow edges and
silhouettes).  Then, with the statistics of :mod:`vision.calibration` measured on rendered images:

1. **Detection** (:mod:`vision.calibrated_detection`): feature f is detected in view i when
   ``u_f < ρ(z/f, view angle, Sun incidence, material) / ρ_F``, the measured keypoint density over
   the features' density ``ρ_F = N / area``.  ``u_f`` is one uniform per feature for the whole call,
   so detections are correlated across views and persist across epochs, as a textured spot is
   detected again when the view barely changes.
2. **Matching across views**: a pair of views (i, j) that both detect f matches it with the measured
   survival ``S(z/f, angle between the cameras)``, times the measured factors of the pair's Sun phase
   (the Sun's angle from the pair's mean line of sight) and of the feature's surface material
   (:meth:`SiftCalibration.pair_survival_at`) and the geometric mean of the two views' factors of
   the feature's relative brightness and view angle (:mod:`vision.calibration.survival_factors`),
   through a Gaussian copula whose correlation
   between pairs reproduces the measured ratio of three-view to two-view tracks; tracks are the
   connected components of the pair matches with at least ``min_views`` views (with three cameras,
   no more of them in all three views than the measured share, :func:`_thin_full_tracks`).  The matches are
   re-decided every epoch, the copula variables an AR(1) process over the epochs whose correlation
   gives the measured track persistence (on rendered images only about half of the tracks of one
   epoch are tracks again 1° later: the ratio test is decided anew in every image pair).
3. **Localisation**: every (track, view) gets a keypoint size (a texture site's own SIFT diameter at
   the view's image scale, :mod:`vision.texture_sites`; for other features the quantile ``v_f`` of the
   measured size distribution of tracked keypoints at its image scale, one ``v_f`` per feature), the
   measured σ of that size at that image scale times the square root of the measured σ² inflation of
   the track's class and camera angle (``SiftCalibration.sigma_inflation``, as the rendered mode's
   ``track_sigma_px``), carried as ``track_sigma_px``.  The projection's Gaussian error has that σ
   times the square root of the measured factor of the feature's surface material
   (``SiftCalibration.material_noise_factors``: on FY-1, keypoints on the MLI err more than on the
   solar cells) and of a lognormal multiplier of mean 1 drawn once per feature and trial with the
   measured spread (``SiftCalibration.error_spread_at``, :mod:`vision.calibration.scale_mixture`:
   rendered errors are heavy-tailed), neither of which the σ knows, as the rendered mode's does not.
   The part the measured *increment* inflation and factor leave (what cancels between epochs on
   rendered images) is the feature's own in that view for the whole trial, the rest is drawn anew
   every epoch.
4. **False matches** at the measured cross-view rate, made as in the fixed model (a wrong point on
   the first view's ray: epipolar-consistent).
5. **Association between epochs**: each feature keeps its descriptor from epoch to epoch with the
   measured association survival of re-detected keypoints (correct associations over keypoints
   detected again at their true position) at the viewpoint change between the two epochs (the rotation of
   the camera frames relative to the body); otherwise it gets a new, unrelated descriptor.  A
   fraction of the tracks (the measured false-association rate) takes the previous descriptor of
   another feature instead: a false association.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.special import ndtr, ndtri

from vision.calibrated_detection import detect_trial, setup_detection
from vision.calibration import SiftCalibration, load_calibration, track_class
from vision.camera import PinholeCamera
from vision.observation import (
    REASON_EARTH_SHADOW,
    REASON_OUTSIDE_FOV,
    REASON_TOO_FEW_MATCHES,
    Observation,
)
from vision.outer_surface import outer_surface_area_m2
from vision.target import Target

__all__ = ["calibrated_feature_count", "filler_feature_count", "pair_copula_correlation",
           "pair_phase_deg", "temporal_correlation", "observe_epochs_calibrated", "observe_trials_calibrated"]

#: margin on the largest measured density when sizing the feature set
_DENSITY_MARGIN = 1.2
_MAX_FEATURES = 100_000


def calibrated_feature_count(camera: PinholeCamera, target: Target, T_CW: np.ndarray,
                             calibration: SiftCalibration | None = None) -> int:
    """Surface features needed so that the largest measured density at the closest camera is reachable
    on the target's outer surface (:mod:`vision.outer_surface`: the features are sampled there)."""
    cal = calibration if calibration is not None else load_calibration(target.name)
    T = np.asarray(T_CW, dtype=float).reshape(-1, 4, 4)
    c = -np.einsum("kji,kj->ki", T[:, :3, :3], T[:, :3, 3])
    z_min = max(float(np.min(np.linalg.norm(c, axis=1))) - target.radius_m, 0.5 * float(np.min(np.linalg.norm(c, axis=1))))
    f = float(np.sqrt(camera.K[0, 0] * camera.K[1, 1]))
    rho = cal.max_density(z_min / f)
    n = int(math.ceil(_DENSITY_MARGIN * rho * outer_surface_area_m2(target)))
    return min(max(n, 1), _MAX_FEATURES)


def filler_feature_count(camera: PinholeCamera, target: Target, T_CW: np.ndarray, sites,
                         calibration: SiftCalibration | None = None) -> int:
    """Uniform filler features (outer surface) that the texture sites ``sites`` need beside them: enough
    that the largest excess of a material's measured density at the closest camera (the measured
    cells, as :func:`calibrated_feature_count`) over its site density is reachable (0 where the sites
    cover every bin)."""
    cal = calibration if calibration is not None else load_calibration(target.name)
    T = np.asarray(T_CW, dtype=float).reshape(-1, 4, 4)
    c = -np.einsum("kji,kj->ki", T[:, :3, :3], T[:, :3, 3])
    d = np.linalg.norm(c, axis=1)
    z_min = max(float(np.min(d)) - target.radius_m, 0.5 * float(np.min(d)))
    fp = z_min / float(np.sqrt(camera.K[0, 0] * camera.K[1, 1]))
    P = len(target.materials)
    if cal.material_factor.shape[1] == P:   # each material's factor at this footprint, over the largest
        factor = cal.density(np.full(P, fp), np.ones(P), np.ones(P, dtype=int), np.arange(P)) \
            / cal.density(fp, 1.0, 1)
        factor = factor / np.max(factor)
    else:
        factor = np.ones(P)
    excess = float(np.max(np.maximum(cal.max_density(fp) * factor - sites.density_by_material, 0.0)))
    n = int(math.ceil(_DENSITY_MARGIN * excess * outer_surface_area_m2(target)))
    return min(n, _MAX_FEATURES)


def _three_over_two(rho: float, s: float) -> float:
    """P(a feature seen in 3 views forms a track) / P(one pair matches), equicorrelated copula."""
    if s <= 0:
        return 1.0
    c = ndtri(min(s, 1 - 1e-12))
    x, w = np.polynomial.hermite_e.hermegauss(64)
    w = w / w.sum()
    r = min(max(rho, 0.0), 1 - 1e-9)
    fail = 1.0 - ndtr((c - math.sqrt(r) * x) / math.sqrt(1.0 - r))  # each pair fails given the common factor
    return float((1.0 - np.sum(w * fail**3)) / s)


def pair_copula_correlation(ratio_three_over_two: float, survival: float) -> float:
    """Correlation of the pair-match Gaussian copula that gives this 3-view / 2-view track ratio.

    With independent pairs (0) a feature seen in three views forms a track about three times as
    often as in two; with fully correlated pairs (1) equally often.  Solved by bisection.
    """
    target = float(np.clip(ratio_three_over_two, _three_over_two(1.0, survival), _three_over_two(0.0, survival)))
    lo, hi = 0.0, 1.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if _three_over_two(mid, survival) > target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _both_below(c: float, rho: float) -> float:
    """P(X < c, Y < c) for standard bivariate normal X, Y with correlation rho (quadrature in X)."""
    x = np.linspace(-9.0, c, 4001)
    r = min(max(rho, -1 + 1e-9), 1 - 1e-9)
    f = np.exp(-0.5 * x * x) / math.sqrt(2 * math.pi) * ndtr((c - r * x) / math.sqrt(1 - r * r))
    return float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(x)))


def temporal_correlation(persistence: float, survival: float) -> float:
    """Epoch-to-epoch correlation of a pair's copula variable that makes a match made at one epoch
    be made again at the next with probability ``persistence`` (marginal probability ``survival``)."""
    if not (np.isfinite(persistence) and 0 < survival < 1):
        return 0.0
    c = float(ndtri(survival))
    target = float(np.clip(persistence, survival, 1.0 - 1e-6))
    lo, hi = 0.0, 1.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if _both_below(c, mid) / survival < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _rotation_angle_deg(R: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip((np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)))


def _components(adj: np.ndarray) -> np.ndarray:
    """Views connected to each feature's best-connected view: ``adj (N, n, n)`` bool → ``(N, n)``."""
    N, n, _ = adj.shape
    reach = adj | np.eye(n, dtype=bool)[None]
    for _ in range(max(1, int(math.ceil(math.log2(max(n, 2)))))):
        reach = (reach.astype(np.int32) @ reach.astype(np.int32)) > 0
    root = np.argmax(adj.sum(axis=2), axis=1)
    return reach[np.arange(N), root]


def _thin_full_tracks(seen: np.ndarray, share: float, rng: np.random.Generator,
                      cos_view: np.ndarray | None = None) -> np.ndarray:
    """``seen (M, 3)`` with no larger a share of tracks in all three views than ``share`` (measured on
    rendered images, :attr:`SiftCalibration.three_view_track_share`): where the epoch has more, each
    such track keeps its three views with probability ``share`` over the epoch's share, else loses one
    of them: the one that sees its surface most obliquely (smallest ``cos_view (M, 3)``, whose
    keypoints survive matching least, :mod:`vision.calibration.survival_factors`), or one at random
    without ``cos_view``.  The shared detection uniform and pair copula put a feature matched in one
    pair into all three views more often than SIFT does (on the check grid 65 % of the correct tracks
    against 40-46 % rendered)."""
    full = seen.all(axis=1)
    f = float(np.mean(full)) if len(seen) else 0.0
    u, which = rng.random(len(seen)), rng.integers(0, seen.shape[1], len(seen))
    if f <= share:
        return seen
    drop = np.flatnonzero(full & (u >= share / f))
    if cos_view is not None:                       # the view that sees the surface most obliquely
        which = np.argmin(cos_view, axis=1)
    out = seen.copy()
    out[drop, which[drop]] = False
    return out


@functools.lru_cache(maxsize=16)
def _copula_correlations(ratio: float, survival_mean: float, persistence: tuple, survival: tuple) -> tuple[float, float]:
    """The pair copula's correlation between pairs and over epochs (constants of a calibration; cached)."""
    rho_c = pair_copula_correlation(ratio, survival_mean)
    rho_t = float(np.mean([temporal_correlation(p, s) for p, s in zip(persistence, survival, strict=True)])) \
        if persistence else 0.0
    return rho_c, rho_t


def _calibration_correlations(cal: SiftCalibration) -> tuple[float, float]:
    ok = np.isfinite(cal.track_persistence)
    return _copula_correlations(float(cal.three_over_two_ratio), float(np.mean(cal.pair_survival[:, 0])),
                                tuple(float(p) for p in cal.track_persistence[ok]),
                                tuple(float(s) for s in cal.pair_survival[ok, 0]))


def observe_epochs_calibrated(cams, T, target, q, sun, fsun, feats, rng, *, calibration, min_views, cos_view,
                              cos_sun, descriptor_noise, margin_px, batch_size) -> list[Observation]:
    """The calibrated model (module docstring) over epochs already validated by :func:`vision.geometric.observe_epochs`.

    ``cos_view`` and ``cos_sun`` (the fixed model's limits) are not used: the measured density
    covers every view angle and unlit surfaces.  One trial of :func:`observe_trials_calibrated`.
    """
    del cos_view, cos_sun
    return observe_trials_calibrated(cams, T[None], target, q[None], sun[None], fsun[None], feats, [rng],
                                     calibration=calibration, min_views=min_views,
                                     descriptor_noise=descriptor_noise, margin_px=margin_px,
                                     batch_size=batch_size)[0]


def observe_trials_calibrated(cams, T, target, q, sun, fsun, feats, rngs, *, calibration, min_views,
                              descriptor_noise, margin_px, batch_size) -> list[list[Observation]]:
    """The calibrated model for R independent trials of E consecutive epochs each.

    ``T (R, E, n, 4, 4)``, ``q (R, E, 4)``, ``sun (R, E, 3)``, ``fsun (R, E)`` and one generator per
    trial in ``rngs``.  The random draws of trial r come from ``rngs[r]`` alone and in the same order
    whatever the other trials, so a trial gives the same observations alone
    (:func:`observe_epochs_calibrated`) or with others.  A feature whose detection uniform is above
    the largest detection probability its material can have at the trial's ranges
    (:mod:`vision.calibrated_detection`) is never detected in that trial: it is left out of the trial's
    projection and ray casting (exact, and most of the features at the close ranges, where the
    feature set is sized for the densest surfaces).  Only the features that some epoch of the
    trial detects in two views take part in the draws after detection.  ``batch_size`` is unused.
    """
    del batch_size
    cal = calibration if calibration is not None else load_calibration(target.name)
    st = setup_detection(cams, T, target, feats, cal, rngs)
    out: list[list[Observation]] = []
    for r in range(len(rngs)):
        keep, g, fp = detect_trial(st, r, cams, T[r], q[r], sun[r], fsun[r], feats, target, cal, margin_px)
        out.append(_trial(g, fp, keep, T[r], fsun[r], feats, cal, rngs[r], target=target, cams=cams,
                          min_views=min_views, descriptor_noise=descriptor_noise, margin_px=margin_px,
                          phase_deg=pair_phase_deg(T[r], sun[r])))
    return out


def _descriptors(labels: np.ndarray, feats, extra: tuple[np.ndarray, np.ndarray], rng: np.random.Generator) -> np.ndarray:
    """Descriptor of each state label: a feature's own (label < N) or a fresh unrelated unit vector
    drawn the first time the label is seen (in increasing label order).  ``extra``: the trial's
    descriptors of labels ``N, N + 1, …`` ``(L, D)`` and whether each is drawn yet ``(L,)`` (updated)."""
    N, D = feats.descriptors.shape
    out = feats.descriptors[np.minimum(labels, N - 1)]
    fresh = np.flatnonzero(labels >= N)
    if fresh.size:
        store, drawn = extra
        j = labels[fresh] - N
        new = np.unique(j[~drawn[j]])
        if new.size:
            d = rng.standard_normal((new.size, D)).astype(np.float32)
            d /= np.linalg.norm(d, axis=1, keepdims=True)
            store[new] = d
            drawn[new] = True
        out[fresh] = store[j]
    return out


def pair_phase_deg(T_CW: np.ndarray, sun_H: np.ndarray) -> np.ndarray:
    """Sun phase of every pair of cameras, degrees ``(E, n, n)``: the angle between the direction to the
    Sun and the pair's mean line of sight from the target (at the origin of H) to the two cameras
    (on the diagonal: the camera's own phase).  ``T_CW (E, n, 4, 4)``, ``sun_H (E, 3)``."""
    T = np.asarray(T_CW, dtype=float)
    c_H = -np.einsum("enji,enj->eni", T[..., :3, :3], T[..., :3, 3])          # camera centres
    u = c_H / np.linalg.norm(c_H, axis=-1, keepdims=True)
    mean = u[:, :, None, :] + u[:, None, :, :]
    s = np.asarray(sun_H, dtype=float)
    s = s / np.linalg.norm(s, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = np.einsum("eijk,ek->eij", mean, s) / np.linalg.norm(mean, axis=-1)
    return np.degrees(np.arccos(np.clip(np.nan_to_num(c, nan=1.0), -1.0, 1.0)))


def _trial(g, fp, ids, T, fsun, feats, cal, rng, *, target, cams, min_views, descriptor_noise,
           margin_px, phase_deg) -> list[Observation]:
    """Matching, localisation, false matches and association of one trial's epochs, from its detections
    ``g`` (:func:`_detect`) of the features ``ids`` of ``feats``; ``phase_deg (E, n, n)`` the pairs' Sun
    phases (:func:`pair_phase_deg`)."""
    from vision.geometric import _false_matches

    E, n = fp.shape[:2]
    N, D = feats.descriptors.shape
    size = tuple(int(s) for s in cams[0].image_size)
    sigma0 = float(np.mean(cal.sigma_px))
    cand = np.nonzero(np.any(g.vis.sum(axis=1) >= 2, axis=0))[0]          # features that can form a track
    C = cand.size
    det_all = g.vis[:, :, cand]                                           # (E, n, C)
    fp_c = fp[:, :, cand]
    cand_id = ids[cand]                                                   # their indices in feats
    mat_cand = target.triangle_material[feats.triangle_id[cand_id]]       # each candidate's surface material
    mat_c = mat_cand if cal.pair_survival_material_factor is not None \
        and len(cal.pair_survival_material_factor) == len(target.materials) else None
    # each view's survival factor of its relative brightness and view angle (E, n, C); a pair takes the
    # geometric mean of its two views' (the brightness is NaN where a view does not detect the feature)
    f_view = []
    if g.brightness is not None and cal.pair_survival_brightness_factor is not None:
        f_view.append(cal.survival_brightness_factor_at(np.nan_to_num(g.brightness[:, :, cand])))
    if cal.pair_survival_view_factor is not None:
        f_view.append(cal.survival_view_factor_at(g.cos_view[:, :, cand]))
    f_view = np.sqrt(np.prod(f_view, axis=0)) if f_view else None
    v_size = rng.random(C)
    e_kept = rng.standard_normal((C, n, 2))                               # each feature's error kept per view
    z_spread = rng.standard_normal(C)                                     # each feature's σ² multiplier (its log)
    rho_c, rho_t = _calibration_correlations(cal)
    # copula variables of every candidate's view pairs: a common factor and one per pair, each an
    # AR(1) process over the epochs of the trial with correlation rho_t
    w_pair = rng.standard_normal(C)
    e_pair = rng.standard_normal((C, n, n))
    first = True
    state = cand_id.astype(np.int64)                                      # descriptor labels (< N: own)
    next_label = N
    extra = (np.empty((max(E - 1, 0) * C, D), np.float32), np.zeros(max(E - 1, 0) * C, bool))  # labels ≥ N
    prev = None                                                           # (R_CT (n,3,3), tracked, states)
    off_diagonal, pairs = ~np.eye(n, dtype=bool)[None], np.triu_indices(n, 1)
    radius_m = target.radius_m
    out: list[Observation] = []
    for k in range(E):
        if fsun[k] == 0.0 or g.in_fov[k].sum() < 2:
            out.append(Observation.empty(g.K, T[k], size, sigma0,
                                         REASON_EARTH_SHADOW if fsun[k] == 0.0 else REASON_OUTSIDE_FOV,
                                         descriptor_dim=D))
            prev = None
            continue
        det = det_all[k].T                                                # (C, n)
        c_dir = g.c_T[k] / np.linalg.norm(g.c_T[k], axis=1, keepdims=True)
        ang = np.degrees(np.arccos(np.clip(c_dir @ c_dir.T, -1.0, 1.0)))   # (n, n) between the cameras
        n_det = det.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            fp_f = np.where(n_det > 0, np.sum(np.where(det, fp_c[k].T, 0.0), axis=1) / n_det, np.nan)  # (C,)
        two = np.nonzero(n_det >= 2)[0]
        S = cal.pair_survival_at(np.nan_to_num(fp_f[two], nan=1.0)[:, None, None], ang[None], phase_deg[k][None],
                                 None if mat_c is None else mat_c[two][:, None, None])
        if f_view is not None:
            fb = f_view[k][:, two].T                                                      # (two, n)
            S = np.minimum(S * fb[:, :, None] * fb[:, None, :], 1.0)
        if feats.sites is not None:                                       # distinct sites match more often
            site = cand_id[two] < len(feats.sites)
            S = np.where(site[:, None, None], feats.sites.pair_survival(
                S, np.minimum(cand_id[two], len(feats.sites) - 1)[:, None, None]), S)
        # the pair matches are re-decided every epoch, correlated with the previous epoch's as
        # measured (track persistence) and between the pairs of one feature (3-view/2-view ratio)
        if not first:
            a = math.sqrt(1.0 - rho_t * rho_t)
            w_pair = rho_t * w_pair + a * rng.standard_normal(C)
            e_pair = rho_t * e_pair + a * rng.standard_normal((C, n, n))
        first = False
        eps = np.triu(e_pair[two], 1)
        eps = eps + np.swapaxes(eps, 1, 2)
        z = math.sqrt(rho_c) * w_pair[two][:, None, None] + math.sqrt(1.0 - rho_c) * eps
        adj = det[two][:, :, None] & det[two][:, None, :] & (ndtr(z) < S)
        adj &= off_diagonal
        members = _components(adj) & det[two]
        is_track = members.sum(axis=1) >= min_views
        fid = two[is_track]                                               # local (candidate) indices
        seen = members[is_track]                                          # (M, n)
        if n == 3 and min_views == 2 and np.isfinite(cal.three_view_track_share):   # measured with min_views 2
            seen = _thin_full_tracks(seen, cal.three_view_track_share, rng,
                                     np.abs(g.cos_view[k][:, cand[fid]]).T)
        # association state: keep, renew or (false association) take another feature's descriptor
        if prev is not None:
            change = float(np.mean(_rotation_angle_deg(g.R_CT[k] @ np.swapaxes(prev[0], -1, -2))))
            fin = np.isfinite(fp_f)
            fpa = np.where(fin, fp_f, float(np.median(fp_f[fin])) if fin.any() else 1.0)
            keep = rng.random(C) < cal.association_survival_at(fpa, change)
            fresh = next_label + np.arange(C)
            next_label += C
            new_state = np.where(keep, state, fresh)
            donors = prev[1]
            if len(fid) and len(donors) > 1:
                fa = cal.false_association_rate_at(fpa[fid], change)
                recv = fid[rng.random(len(fid)) < fa]
                if len(recv):
                    pick = donors[rng.integers(0, len(donors), len(recv))]
                    ok = pick != recv
                    recv, pick = recv[ok], pick[ok]
                    new_state[recv] = prev[2][pick]
                    new_state[pick] = fresh[recv]
            state = new_state
        M = len(fid)
        if M == 0:
            out.append(Observation.empty(g.K, T[k], size, sigma0, REASON_TOO_FEW_MATCHES, descriptor_dim=D))
            prev = (g.R_CT[k], fid, state.copy())
            continue
        loc, gid = cand[fid], cand_id[fid]
        uv_e = np.swapaxes(g.uv[k][:, loc], 0, 1).copy()                  # (M, n, 2)
        fp_m = fp_c[k][:, fid].T                                          # (M, n)
        size_px = cal.size_px(fp_m, np.broadcast_to(v_size[fid, None], (M, n)))
        if feats.sites is not None:                                       # a site's SIFT diameter at this footprint
            size_px = np.where((gid < len(feats.sites))[:, None], feats.scale_m[gid][:, None] / fp_m, size_px)
        # σ of the size times the measured σ² inflation of the track's class and camera angle (as the
        # rendered mode's Observation.track_sigma_px, which does not know the surface); the error has
        # that σ² times its material's measured factor and the feature's own lognormal multiplier
        # (the measured spread: rendered errors are heavy-tailed); the part of it that does not
        # cancel in an increment (the increment inflation and factor) is drawn anew, the rest is the
        # feature's own in that view for the whole trial
        sig_size = cal.sigma_for_size(size_px, fp_m)
        both = seen[:, :, None] & seen[:, None, :]
        angle = np.max(np.where(both, ang[None], 0.0), axis=(1, 2))
        cls = track_class(seen.sum(axis=1), n)[:, None]
        infl, infl_inc = cal.sigma_inflations(fp_m, angle[:, None], cls)
        sig = sig_size * np.sqrt(infl)
        f_mat, f_mat_inc = cal.material_noise_factors(fp_m, mat_cand[fid][:, None])
        s_w = cal.error_spread_at(fp_m)
        w = np.exp(s_w * z_spread[fid][:, None] - 0.5 * s_w**2)          # lognormal, mean 1
        var, var_inc = infl * f_mat * w, infl_inc * f_mat_inc * w
        var_inc = np.minimum(var_inc, var)
        uv_e += sig_size[..., None] * (np.sqrt(var - var_inc)[..., None] * e_kept[fid]
                                       + np.sqrt(var_inc)[..., None] * rng.standard_normal(uv_e.shape))
        uv_e[~seen] = np.nan
        desc = _descriptors(state[fid], feats, extra, rng)
        if descriptor_noise > 0:
            desc += (descriptor_noise / np.sqrt(D)) * rng.standard_normal(desc.shape).astype(np.float32)
            desc /= np.linalg.norm(desc, axis=1, keepdims=True)
        ids = gid.astype(np.int64)
        X_true = feats.X_T[gid].copy()
        prev = (g.R_CT[k], fid, state.copy())
        fp_med = float(np.median(fp_f[fid]))
        fm = float(np.mean(cal.false_match_rate_at(fp_med, ang[pairs])))
        if fm > 0:
            keep_m = _false_matches(rng, fm, uv_e, seen, g.z[k][:, loc].T, cams, T[k], desc, ids, X_true,
                                    radius_m, float(np.median(sig)), margin_px)
            uv_e, desc, ids, X_true = uv_e[keep_m], desc[keep_m], ids[keep_m], X_true[keep_m]
            sig, size_px = sig[keep_m], size_px[keep_m]
        present = np.isfinite(uv_e).all(axis=-1)
        sig = np.where(present, sig, np.nan)
        size_px = np.where(present, size_px, np.nan)
        out.append(Observation(uv_px=uv_e, descriptors=desc, K=g.K, T_CW=T[k], image_size=size,
                               pixel_sigma_px=float(np.sqrt(np.mean(sig[present] ** 2))) if present.any()
                               else sigma0, feature_id=ids,
                               X_T_true=X_true, failure_reason="" if len(ids) else REASON_TOO_FEW_MATCHES,
                               track_sigma_px=sig, keypoint_size_px=size_px))
    return out
