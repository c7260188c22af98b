"""Symmetric n-view geometry (003 §3.1): angles, ranges, look-at poses."""

import numpy as np
import pytest

from attitude.quaternion import quat_from_axis_angle
from formation.geometry import look_at, optical_axis_angles, symmetric_views


@pytest.mark.parametrize("n", [2, 3])
@pytest.mark.parametrize("gamma_deg", [5.0, 10.0, 20.0, 60.0])
def test_every_pair_of_optical_axes_is_at_gamma_for_two_and_three_views(n, gamma_deg):
    g = symmetric_views(n, 50.0, gamma_deg, orientation=quat_from_axis_angle([1, -2, 0.5], 1.1))
    ang = np.rad2deg(optical_axis_angles(g.boresight_H))
    iu = np.triu_indices(n, 1)
    np.testing.assert_allclose(ang[iu], gamma_deg, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(g.r_CT_H, axis=-1), 50.0, rtol=1e-9)


def test_four_views_have_adjacent_pairs_at_gamma_and_opposite_pairs_wider():
    g = symmetric_views(4, 80.0, 15.0)
    ang = np.rad2deg(optical_axis_angles(g.boresight_H))
    for k in range(4):
        assert ang[k, (k + 1) % 4] == pytest.approx(15.0, abs=1e-9)
    assert ang[0, 2] > 15.0 and ang[1, 3] > 15.0
    np.testing.assert_allclose(np.linalg.norm(g.r_CT_H, axis=-1), 80.0, rtol=1e-9)


def test_three_view_cone_matches_the_spec_example():
    """Three views at d = 50 m, γ = 10° give φ = 5.78° and baseline 8.72 m."""
    g = symmetric_views(3, 50.0, 10.0)
    assert np.rad2deg(g.cone_half_angle_rad) == pytest.approx(5.78, abs=0.005)
    np.testing.assert_allclose(g.baselines_m[np.triu_indices(3, 1)], 2 * 50 * np.sin(np.deg2rad(5)), rtol=1e-12)
    assert 2 * 50 * np.sin(np.deg2rad(5)) == pytest.approx(8.72, abs=0.005)


def test_poses_look_at_the_target_with_a_proper_rotation():
    c = np.array([1.0, -2.0, 3.0])
    g = symmetric_views(3, 40.0, 12.0, target_center_H=c)
    for k in range(3):
        R, t = g.T_CW[k, :3, :3], g.T_CW[k, :3, 3]
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        p_C = R @ c + t  # the target centre in camera k: straight ahead at 40 m
        np.testing.assert_allclose(p_C, [0.0, 0.0, 40.0], atol=1e-9)
        np.testing.assert_allclose(R[2], g.boresight_H[k], atol=1e-12)


def test_look_at_puts_up_vector_at_image_top():
    T = look_at(np.array([0.0, -10.0, 0.0]), np.zeros(3), np.array([0.0, 0.0, 1.0]))
    up_C = T[:3, :3] @ np.array([0.0, 0.0, 1.0])
    assert up_C[1] < -0.99  # −y_C is image up


def test_impossible_geometry_and_bad_arguments_are_named():
    with pytest.raises(ValueError, match="axis_angle_deg: .*impossible for 3 views"):
        symmetric_views(3, 50.0, 130.0)
    with pytest.raises(ValueError, match="distance_m"):
        symmetric_views(3, -5.0, 10.0)
    with pytest.raises(ValueError, match="n: number of views"):
        symmetric_views(0, 50.0, 10.0)
    with pytest.raises(ValueError, match="orientation"):
        symmetric_views(2, 50.0, 10.0, orientation=[1.0, 1.0, 0.0, 0.0])


@pytest.mark.parametrize(("n", "gamma_deg"), [(2, 190.0), (3, 121.0), (3, 250.0), (4, 91.0)])
def test_axis_angle_beyond_360_over_n_is_refused_instead_of_folding_back(n, gamma_deg):
    """n = 2, γ = 190° used to give the geometry of 170° (sin(γ/2) folds back above 360°/n)."""
    with pytest.raises(ValueError, match=rf"^axis_angle_deg: {gamma_deg:g} deg is impossible for {n} views"):
        symmetric_views(n, 50.0, gamma_deg)


@pytest.mark.parametrize("n", [2, 3, 4])
def test_axis_angle_of_exactly_360_over_n_is_the_widest_geometry_at_phi_90_deg(n):
    g = symmetric_views(n, 50.0, 360.0 / n)
    assert np.rad2deg(g.cone_half_angle_rad) == pytest.approx(90.0, abs=1e-6)
    assert np.rad2deg(optical_axis_angles(g.boresight_H)[0, 1]) == pytest.approx(360.0 / n, abs=1e-6)


@pytest.mark.parametrize(("kwargs", "name"), [
    ({"target_center_H": [np.nan, 0.0, 0.0]}, "target_center_H"),
    ({"target_center_H": [0.0, np.inf, 0.0]}, "target_center_H"),
    ({"target_center_H": [0.0, 0.0]}, "target_center_H"),
    ({"azimuth_offset_rad": np.nan}, "azimuth_offset_rad"),
])
def test_non_finite_or_misshapen_keyword_arguments_are_refused_not_turned_into_nan_poses(kwargs, name):
    with pytest.raises(ValueError, match=rf"^{name}:"):
        symmetric_views(3, 50.0, 10.0, **kwargs)


def test_nan_axis_angle_is_refused_even_for_one_view_and_look_at_refuses_nan():
    with pytest.raises(ValueError, match="^axis_angle_deg: must be positive and finite"):
        symmetric_views(1, 50.0, np.nan)
    with pytest.raises(ValueError, match="^target_H: contains non-finite"):
        look_at(np.array([0.0, -10.0, 0.0]), [np.nan, 0.0, 0.0], np.array([0.0, 0.0, 1.0]))
