"""Detection in the calibrated geometric mode (:mod:`vision.geometric_calibrated`, step 1).

Feature f is detected in view i when its uniform ``u_f`` (one per feature and trial) is below the
measured keypoint density of its bin (image footprint, view angle, Sun incidence, material, times
the detection factor of its relative brightness, :mod:`vision.face_brightness`) over the features'
own density.  With texture sites (:mod:`vision.texture_sites`) the sites of a material carry its
density first and uniform fillers the rest; a site narrower than :data:`MIN_FORESHORTENED_PX`
across in the image is not seen (not renormalised: a surface seen near edge-on gives fewer
keypoints than its view-angle bin measured, there mostly on silhouettes and the edges between
faces, whose cross-view matches rarely survive, :mod:`vision.calibration.survival_factors`).

A feature whose uniform is above the largest probability it can have at the trial's ranges is
never detected in that trial and is left out of its projection and ray casting.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtr, ndtri

from vision.calibration import COS_VIEW_EDGES, SUN_BIN_EDGES, SiftCalibration, load_calibration
from vision.face_brightness import entry_brightness

__all__ = ["MIN_FORESHORTENED_PX", "SITE_RANK_CORRELATION", "detect_trial", "detections", "setup_detection"]

#: correlation (Gaussian copula) between a texture site's detection uniform and its response rank
#: among the sites of its material: 1 would detect the sites strictly strongest first in every bin
#: and trial, 0 at random; a choice (not measured): the response on a rendered image also depends
#: on the shading and the view, so the order is kept loosely
SITE_RANK_CORRELATION = 0.8
#: smallest foreshortened diameter (diameter times the cosine of the view angle) of a texture site's
#: keypoint in an image, px: a texture blob narrower than a pixel across is averaged away (surfaces
#: seen edge-on, such as a solar wing at grazing view, keep only their largest sites)
MIN_FORESHORTENED_PX = 1.0


def detections(cams, T, target, q, sun, fsun, feats, rng, *, calibration=None, margin_px: float = 0.0):
    """The detection step alone for one trial (the same draws as :func:`vision.geometric_calibrated.observe_trials_calibrated`):
    the indices ``keep`` of the features that can be detected and their detections ``vis (E, n, len(keep))``."""
    cal = calibration if calibration is not None else load_calibration(target.name)
    st = setup_detection(cams, T[None], target, feats, cal, [rng])
    keep, g, _ = detect_trial(st, 0, cams, T, q, sun, fsun, feats, target, cal, margin_px)
    return keep, g.vis


def setup_detection(cams, T, target, feats, cal, rngs) -> dict:
    """Per-feature densities, detection uniforms ``(R, N)`` and their bound of the trials ``T (R, E, n, 4, 4)``."""
    N = len(feats)
    area_m2 = feats.area_m2 if np.isfinite(feats.area_m2) else float(target.triangle_areas_m2.sum())
    rho_F = N / area_m2
    material = target.triangle_material[feats.triangle_id] if cal.material_factor.shape[1] == len(target.materials) \
        else None
    f_px = np.array([math.sqrt(c.K[0, 0] * c.K[1, 1]) for c in cams])
    rho_sub = 0.0                                                         # density left to others, per m²
    is_site = np.zeros(N, dtype=bool)
    if feats.sites is not None:
        # texture sites first (their material's site density), then uniform fillers that carry what
        # a bin's measured density asks beyond the sites of its material
        Ns = len(feats.sites)
        is_site[:Ns] = True
        mat_all = target.triangle_material[feats.triangle_id]
        rho_F = np.where(is_site, np.maximum(feats.sites.density_by_material[mat_all], 1e-9), max(N - Ns, 1) / area_m2)
        rho_sub = np.where(is_site, 0.0, feats.sites.density_by_material[mat_all])
        u_det = np.stack([np.concatenate([_site_uniforms(feats.sites.detection_rank, r), r.random(N - Ns)])
                          for r in rngs])
    else:
        u_det = np.stack([r.random(N) for r in rngs])                     # (R, N), one per feature and trial
    c_dist = np.linalg.norm(np.einsum("...ji,...j->...i", T[..., :3, :3], T[..., :3, 3]), axis=-1)  # (R, E, n)
    fp_lo = max(float(np.min(c_dist)) - target.radius_m, 1e-3) / float(np.max(f_px))
    fp_hi = (float(np.max(c_dist)) + target.radius_m) / float(np.min(f_px))
    bound = (_detection_bound(cal, fp_lo, fp_hi, material) * max(cal.max_brightness_factor, 1.0) - rho_sub) / rho_F  # (V, S, N)
    bound = np.broadcast_to(bound, (*bound.shape[:2], N))
    return {"u_det": u_det, "bound": bound.max(axis=(0, 1)), "bound_view": bound.max(axis=1),
            "bound_sun": bound.max(axis=0), "rho_F": rho_F, "rho_sub": rho_sub, "is_site": is_site,
            "material": material, "f_px": f_px}


def detect_trial(st: dict, r: int, cams, T, q, sun, fsun, feats, target, cal, margin_px):
    """Trial r's features that can be detected, their geometry with detections and footprints (:func:`_detect`)."""
    from vision.geometric import _sun_T

    keep = np.flatnonzero(st["u_det"][r] < st["bound"])
    # a feature is lit at the bin of its Sun incidence (|cos|: either side may face the cameras) or
    # unlit: above the bounds of both at every lit epoch, it is never detected (the bins of the
    # incidence ± 1e-6, against rounding at a bin edge)
    cos_sun = np.abs(np.einsum("ei,fi->ef", _sun_T(q, sun), feats.normal_T[keep]))          # (E, K)
    bs = np.ascontiguousarray(st["bound_sun"][:, keep])                                     # (S, K)
    lit = np.maximum(np.take_along_axis(bs, cal.sun_bin(cos_sun - 1e-6, True), axis=0),
                     np.take_along_axis(bs, cal.sun_bin(cos_sun + 1e-6, True), axis=0))
    can = (st["u_det"][r, keep] < np.maximum(lit, bs[0])) & (fsun > 0)[:, None]
    keep = keep[can.any(axis=0)]
    rho_F, rho_sub, material = st["rho_F"], st["rho_sub"], st["material"]
    g, fp = _detect(cams, T, q, sun, fsun, _subset(feats, keep), target, cal, st["u_det"][r, keep],
                    None if material is None else material[keep], rho_F if np.ndim(rho_F) == 0 else rho_F[keep],
                    st["f_px"], margin_px, rho_sub=rho_sub if np.ndim(rho_sub) == 0 else rho_sub[keep],
                    is_site=st["is_site"][keep],
                    bound_view=np.ascontiguousarray(st["bound_view"][:, keep]))
    return keep, g, fp


def _site_uniforms(detection_rank: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Detection uniforms ``(N,)`` of texture sites: uniform over a material's sites (its ranks are
    uniform), small for strong sites through a Gaussian copula of correlation :data:`SITE_RANK_CORRELATION`,
    so that a bin's measured density is reached with the strongest sites first."""
    r = SITE_RANK_CORRELATION
    z = math.sqrt(r) * ndtri(np.clip(detection_rank, 1e-12, 1 - 1e-12)) + math.sqrt(1.0 - r) * rng.standard_normal(len(detection_rank))
    return ndtr(z)


def _detection_bound(cal: SiftCalibration, fp_lo: float, fp_hi: float, material: np.ndarray | None) -> np.ndarray:
    """Largest measured density (per m²) a feature of each material can have at footprints in
    ``[fp_lo, fp_hi]`` m/px, per view-angle and Sun bin: ``(V, S, N)`` (``(V, S, 1)`` without
    materials); its maximum over the bins bounds the feature over every bin.

    The density is piecewise linear in log footprint between the calibrated footprints (and beyond
    them), so its largest value on the interval is at an end or at a calibrated footprint inside.
    """

    knots = cal.footprint_m_per_px[(cal.footprint_m_per_px > fp_lo) & (cal.footprint_m_per_px < fp_hi)]
    fps = np.concatenate([[fp_lo, fp_hi], knots])
    cos_v = 0.5 * (COS_VIEW_EDGES[:-1] + np.minimum(COS_VIEW_EDGES[1:], 1.0))     # one per view bin
    sun_b = np.arange(len(SUN_BIN_EDGES) - 1)
    if material is None:
        fp_g, v_g, s_g = np.meshgrid(fps, cos_v, sun_b, indexing="ij")
        return (np.max(cal.density(fp_g, v_g, s_g), axis=0) * (1.0 + 1e-9))[:, :, None]
    mats = np.arange(int(np.max(material)) + 1)
    fp_g, v_g, s_g, m_g = np.meshgrid(fps, cos_v, sun_b, mats, indexing="ij")
    per_material = np.max(cal.density(fp_g, v_g, s_g, m_g), axis=0) * (1.0 + 1e-9)   # (V, S, P)
    return per_material[:, :, material]


def _subset(feats, keep: np.ndarray):
    """The features ``keep`` for the geometry (positions, normals, scales; no descriptors)."""
    from vision.geometric import SurfaceFeatures

    return SurfaceFeatures(feats.X_T[keep], feats.normal_T[keep], feats.scale_m[keep], feats.descriptors[:0],
                           feats.triangle_id[keep], feats.area_m2)


def _detect(cams, T, q, sun, fsun, feats, target, cal, u_det, material, rho_F, f_px, margin_px, rho_sub=0.0,
            is_site=None, bound_view=None):
    """Projection, visibility and detection of one trial's epochs: the geometry (``vis`` the detections)
    and the footprints ``(E, n, N)``, m/px.  A feature is detected with probability ``(ρ − rho_sub) / rho_F``
    (ρ the measured density of its bin; ``rho_sub`` the density other features carry: the sites of
    its material, for a filler); the texture sites (``is_site``) only where their foreshortened
    diameter is at least :data:`MIN_FORESHORTENED_PX`.  ``bound_view (V, N)``: detection probabilities
    that bound each feature's in each view-angle bin (:func:`_detection_bound`; the densities are
    evaluated only below them)."""
    from vision.geometric import _geometry, _occlude, _sun_T

    # every surface facing a camera counts, lit or not: keypoints on shadowed or unlit surfaces
    # (shadow edges, silhouettes against lit parts) are measured as their own Sun bin
    g = _geometry(cams, T, q, sun, fsun, feats, min_feature_px=0.0, cos_view=0.0, cos_sun=-2.0, margin_px=margin_px)
    fp = g.z / f_px[None, :, None]                                        # (E, n, N) m/px
    # the detection probabilities only where the cheap tests pass (elsewhere nothing is detected), on
    # the flat indices of those (epoch, camera, feature)
    E, n, N = g.vis.shape
    at = np.flatnonzero(g.vis)
    f_i, e_i = at % N, at // (n * N)
    fp_v, cv_v = np.take(fp, at), np.take(g.cos_view, at)
    det = np.ones(len(at), dtype=bool)
    if is_site is not None and is_site.any():
        # a site is seen where its foreshortened diameter reaches MIN_FORESHORTENED_PX (not
        # renormalised: the density a bin measured at grazing view comes mostly from silhouettes and
        # the edges between faces, not from the texture of the grazing surface)
        with np.errstate(invalid="ignore", divide="ignore"):
            det &= ~is_site[f_i] | (feats.scale_m[f_i] * np.abs(cv_v) / fp_v >= MIN_FORESHORTENED_PX)
    u = u_det[f_i]
    if bound_view is not None:          # above the bound of its view bin: not detected, whatever the density
        det &= u < np.take(bound_view, cal.view_bin(cv_v) * N + f_i)
    sel = np.flatnonzero(det)
    at, f_i, e_i, fp_v, cv_v, u = at[sel], f_i[sel], e_i[sel], fp_v[sel], cv_v[sel], u[sel]
    det = np.ones(len(at), dtype=bool)
    side_sun = np.where(cv_v >= 0, 1.0, -1.0) * np.take(g.cos_sun, e_i * N + f_i)
    can_lit = side_sun > 0
    mat = None if material is None else material[f_i]
    sub = rho_sub if np.ndim(rho_sub) == 0 else rho_sub[f_i]
    rho = rho_F if np.ndim(rho_F) == 0 else rho_F[f_i]
    bins = cal.density_bins(fp_v, cv_v)
    # the brightness of each entry if lit, relative to its image's auto-exposure, and its detection factor
    s_T = _sun_T(q, sun)
    b_lit = None if cal.detection_brightness_factor is None else \
        entry_brightness(g, target, feats, s_T, f_px, at, e_i, f_i, side_sun)
    f_lit, f_dark = cal.lit_and_unlit_factors_at(np.zeros(len(at)) if b_lit is None else b_lit, fp_v)
    with np.errstate(invalid="ignore", divide="ignore"):
        p_lit = (cal.density_at(bins, cal.sun_bin(side_sun, can_lit), mat) * f_lit - sub) / rho
        p_dark = (cal.density_at(bins, np.zeros(len(at), dtype=int), mat) * f_dark - sub) / rho
    # features above both detection probabilities are not detected whatever the ray casting gives:
    # cast rays only for the others (the shadow of a feature decides only its own lit flag)
    det &= u < np.maximum(p_lit, p_dark)
    vis = np.zeros(E * n * N, dtype=bool)
    vis[at] = det
    g.vis = vis.reshape(E, n, N)
    dark = _occlude(g, target, feats, s_T, drop_shadowed=False)                # (E, N)
    lit = can_lit & ~np.take(dark, e_i * N + f_i)
    vis[at] &= u < np.where(lit, p_lit, p_dark)
    if b_lit is not None:
        b = np.full(E * n * N, np.nan)
        b[at] = np.where(lit, b_lit, 0.0)
        g.brightness = b.reshape(E, n, N)
    return g, fp
