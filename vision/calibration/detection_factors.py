"""Keypoint detection density per (view, Sun) cell, material and relative brightness, fitted jointly.

The calibration counts SIFT keypoints on the target's visible surface, and the area they are counted
on, per range and per bin of view angle (:data:`vision.calibration.COS_VIEW_EDGES`), Sun incidence
(:data:`vision.calibration.SUN_BIN_EDGES`, bin 0 unlit), surface material and relative brightness
(:data:`vision.face_brightness.BRIGHTNESS_EDGES`, bin 0 unlit).  The geometric mode's density is

    ρ(view, Sun, material, brightness) = D(view, Sun) · M(material) · F(brightness)    (keypoints per m²)

- **Sequential factors** (files without the joint counts): ``D`` the keypoints over the area of each
  (view, Sun) cell, ``M`` each material's density over the mean, then ``F`` the keypoints of each
  brightness bin over what ``D · M`` predicts there.  Each factor is a ratio of margins taken after
  the ones before it, so where the kinds are correlated (the brightest faces are mostly lit face-on
  and of a few materials) an effect is counted twice: on the calibration's own images the product
  misses a material's keypoints by tens of per cent.
- **Joint factors** (files with ``detection_joint``: the area and the keypoints per (brightness,
  view, Sun, material) bin of each range): the main-effects Poisson model
  ``keypoints ~ Poisson(area · D · M · F)`` fitted per range by iterative proportional fitting
  (:func:`vision.calibration.survival_factors.fit_main_effects`), its maximum-likelihood solution:
  every margin (each (view, Sun) cell, each material, each brightness bin) is reproduced at once.

Classes with too little data keep a factor of 1 (materials seen on less than
:data:`MIN_MATERIAL_AREA_M2`, brightness bins expected to hold fewer than :data:`MIN_EXPECTED_KEYPOINTS`
keypoints, and the unlit brightness bin, which is the unlit Sun bin's own); a (view, Sun) cell seen on
less than :data:`MIN_CELL_AREA_M2` takes the product of its view and Sun margins.
"""

from __future__ import annotations

import numpy as np

from vision.calibration.survival_factors import fit_main_effects

__all__ = ["MIN_CELL_AREA_M2", "MIN_EXPECTED_KEYPOINTS", "MIN_MATERIAL_AREA_M2", "detection_factors",
           "detection_tables", "sequential_expected_keypoints", "sequential_factors"]

#: visible area below which a (view, Sun) density cell is the product of its view and Sun margins, m²
MIN_CELL_AREA_M2 = 2.0
#: visible area a material needs at a range to get a detection factor of its own, m²
MIN_MATERIAL_AREA_M2 = 2.0
#: keypoints a brightness bin must be expected to hold (at a factor of 1) to get a factor of its own
MIN_EXPECTED_KEYPOINTS = 20.0


def detection_tables(t: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """The density ``(R, V, S)``, material factors ``(R, P)`` (``(R, 1)``: none), brightness factors
    ``(R, B)`` (None: none) and measured cells ``(R, V, S)`` of a target's section of the calibration
    file: the joint fit where it has ``detection_joint``, else the sequential factors."""
    if "detection_joint" in t:
        return detection_factors(t["detection_joint"]["area_m2"], t["detection_joint"]["keypoints"])
    return sequential_factors(t)


def sequential_factors(t: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """:func:`detection_tables` from the margins alone (files without the joint counts; module
    docstring): each (view, Sun) cell's keypoints over its area (a sparse cell the product of its
    range's view and Sun margins), each material's density over the mean, each brightness bin's
    keypoints over those the two predict (``brightness_expected_keypoints``; pooled over the ranges
    where a range expects too few, 1 if those too are short)."""
    kp = np.asarray(t["keypoints"], dtype=float)          # (R, V, S)
    area = np.asarray(t["visible_area_m2"], dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        rho_r = kp.sum(axis=(1, 2)) / area.sum(axis=(1, 2))
        g_v = (kp.sum(axis=2) / area.sum(axis=2)) / rho_r[:, None]
        h_s = (kp.sum(axis=1) / area.sum(axis=1)) / rho_r[:, None]
        cell = kp / area
    factor = rho_r[:, None, None] * np.nan_to_num(g_v)[:, :, None] * np.nan_to_num(h_s)[:, None, :]
    measured = area >= MIN_CELL_AREA_M2
    return np.where(measured, cell, factor), _sequential_material(t), _sequential_brightness(t), measured


def _sequential_material(t: dict) -> np.ndarray:
    if "material_keypoints" not in t:
        return np.ones((len(t["ranges_m"]), 1))
    kp = np.asarray(t["material_keypoints"], dtype=float)
    area = np.asarray(t["material_area_m2"], dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        f = (kp / area) / (kp.sum(axis=1, keepdims=True) / area.sum(axis=1, keepdims=True))
    f = np.where(area >= MIN_MATERIAL_AREA_M2, f, 1.0)
    # renormalise so that the area-weighted mean factor stays 1 (the table already holds the mean)
    return f * area.sum(axis=1, keepdims=True) / np.sum(f * area, axis=1, keepdims=True)


def _sequential_brightness(t: dict) -> np.ndarray | None:
    if "brightness_expected_keypoints" not in t:
        return None
    kp = np.asarray(t["brightness_keypoints"], dtype=float)
    expected = np.asarray(t["brightness_expected_keypoints"], dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        pooled = np.where(expected.sum(0) >= MIN_EXPECTED_KEYPOINTS, kp.sum(0) / expected.sum(0), 1.0)
        return np.where(expected >= MIN_EXPECTED_KEYPOINTS, kp / expected, pooled[None])


def detection_factors(area_m2: np.ndarray, keypoints: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Joint detection factors from the area ``(R, B, V, S, P)`` and keypoints ``(R, B, V, S, P)`` per
    range, brightness, view, Sun and material bin: the density ``D (R, V, S)`` per m², the material
    factors ``M (R, P)`` (area-weighted mean 1), the brightness factors ``F (R, B)`` (area-weighted
    mean 1) and the cells measured ``(R, V, S)`` (see the module docstring)."""
    A = np.asarray(area_m2, dtype=float)
    K = np.asarray(keypoints, dtype=float)
    if A.shape != K.shape or A.ndim != 5:
        raise ValueError(f"area_m2 and keypoints must both be (R, B, V, S, P), got {A.shape} and {K.shape}")
    R, B, V, S, P = A.shape
    dens, mat, bright, measured = np.zeros((R, V, S)), np.ones((R, P)), np.ones((R, B)), np.zeros((R, V, S), bool)
    for r in range(R):
        a, k = A[r], K[r]
        rho = k.sum() / a.sum() if a.sum() > 0 else 0.0
        fixed_m = a.sum(axis=(0, 1, 2)) < MIN_MATERIAL_AREA_M2
        fixed_b = a.sum(axis=(1, 2, 3)) * rho < MIN_EXPECTED_KEYPOINTS
        fixed_b[0] = True                                                   # unlit: the Sun bin 0 carries it
        # axes (material, brightness, view x Sun): the scale goes into the last, the density; the
        # expected count at the range's mean density, so that a class held at 1 has the mean density
        e = np.moveaxis(a * rho, 3, 0).reshape(P, B, V * S)
        o = np.moveaxis(k, 3, 0).reshape(P, B, V * S)
        f_m, f_b, d = fit_main_effects(e, o, fixed=[fixed_m, fixed_b, np.zeros(V * S, bool)])
        cell_area = a.sum(axis=(0, 3))                                      # (V, S)
        d = d.reshape(V, S) * rho
        # a sparse cell: the product of its view and Sun margins of the fitted density
        w = cell_area * np.isfinite(d)
        with np.errstate(invalid="ignore", divide="ignore"):
            d_v = np.sum(w * d, axis=1) / w.sum(axis=1)
            d_s = np.sum(w * d, axis=0) / w.sum(axis=0)
            d_all = np.sum(w * d) / w.sum()
        ok = cell_area >= MIN_CELL_AREA_M2
        dens[r] = np.where(ok, d, np.nan_to_num(d_v[:, None] * d_s[None, :] / d_all))
        mat[r], bright[r], measured[r] = f_m, f_b, ok
    return dens, mat, bright, measured


def sequential_expected_keypoints(density_per_m2: np.ndarray, material_factor: np.ndarray,
                                  area_m2: np.ndarray) -> np.ndarray:
    """Keypoints ``(R, B)`` the density table ``(R, V, S)`` and the material factors ``(R, P)`` (or
    ``(R, 1)``: none) predict on the area ``(R, B, V, S, P)`` of each range and brightness bin: the
    denominator of the sequential brightness factor."""
    A = np.asarray(area_m2, dtype=float)
    mf = material_factor if material_factor.shape[1] == A.shape[-1] else np.ones((len(A), A.shape[-1]))
    return np.einsum("rbvsp,rvs,rp->rb", A, density_per_m2, mf)
