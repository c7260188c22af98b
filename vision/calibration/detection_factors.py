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
           "sequential_expected_keypoints"]

#: visible area below which a (view, Sun) density cell is the product of its view and Sun margins, m²
MIN_CELL_AREA_M2 = 2.0
#: visible area a material needs at a range to get a detection factor of its own, m²
MIN_MATERIAL_AREA_M2 = 2.0
#: keypoints a brightness bin must be expected to hold (at a factor of 1) to get a factor of its own
MIN_EXPECTED_KEYPOINTS = 20.0


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
