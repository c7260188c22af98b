"""Outer-surface feature sampling (vision.outer_surface, surface_features(surface="outer"))."""

import numpy as np
import open3d as o3d

from vision.geometric import surface_features
from vision.outer_surface import outer_mask, outer_surface_area_m2, probe_directions


def test_outer_features_always_have_an_escaping_probe_ray(topex):
    """Every sampled point sees out along its normal or a probe 60° off it, on one side of its
    triangle; points whose normal ray is free on a side are never rejected."""
    f = surface_features(topex, n_features=3000, surface="outer")
    assert len(f) == 3000
    free = np.zeros(len(f), bool)
    for sign in (1.0, -1.0):
        for d in probe_directions(sign * f.normal_T):
            free |= _escapes_side(topex, f, sign, d)
    assert free.all()
    rng = np.random.default_rng(0)
    g = surface_features(topex, n_features=3000, rng=rng)      # the whole mesh, internal faces included
    normal_free = _escapes_side(topex, g, 1.0, g.normal_T) | _escapes_side(topex, g, -1.0, -g.normal_T)
    assert outer_mask(topex, g.X_T, g.normal_T)[normal_free].all()
    assert (~normal_free).mean() > 0.3                        # TOPEX: much of the mesh is inside


def _escapes_side(target, f, sign, d):
    eps = max(1e-3, 1e-4 * target.radius_m)
    rays = np.concatenate([f.X_T + eps * sign * f.normal_T, d], axis=1).astype(np.float32)
    return ~target.scene.test_occlusions(o3d.core.Tensor(rays)).numpy().astype(bool)


def test_outer_area_is_the_outer_fraction_of_the_mesh(topex, fy1):
    for t in (topex, fy1):
        a = outer_surface_area_m2(t)
        assert 0 < a <= t.triangle_areas_m2.sum()
        f = surface_features(t, n_features=500, surface="outer")
        assert f.area_m2 == a
    assert outer_surface_area_m2(fy1) > 0.9 * fy1.triangle_areas_m2.sum()
    assert outer_surface_area_m2(topex) < 0.7 * topex.triangle_areas_m2.sum()


def test_whole_mesh_sampling_is_unchanged_by_the_option(fy1):
    """surface="all" (the default) draws exactly as before: the fixed mode's features do not move."""
    a = surface_features(fy1, n_features=200, rng=3)
    b = surface_features(fy1, n_features=200, rng=3, surface="all")
    np.testing.assert_array_equal(a.X_T, b.X_T)
    np.testing.assert_array_equal(a.descriptors, b.descriptors)
    assert a.area_m2 == fy1.triangle_areas_m2.sum()
