"""Observation constraints (003 §1.2) and observer selection with hysteresis."""

import numpy as np
import pytest

from formation.constraints import ObservationConstraints, evaluate
from formation.geometry import symmetric_views
from formation.selection import point_dop, select_observers


def test_minimum_distance_forms_of_eq1_and_flag_P003_1():
    c_tan = ObservationConstraints(fov_rad=np.deg2rad(20), target_radius_m=5.0, d_min_form="tan")
    c_sin = ObservationConstraints(fov_rad=np.deg2rad(20), target_radius_m=5.0, d_min_form="sin")
    assert c_tan.d_min_m == pytest.approx(5.0 / np.tan(np.deg2rad(10)), rel=1e-12)  # 28.36 m
    assert c_sin.d_min_m == pytest.approx(5.0 / np.sin(np.deg2rad(10)), rel=1e-12)  # 28.79 m
    assert (c_sin.d_min_m - c_tan.d_min_m) / c_tan.d_min_m < 0.02  # flag P003-1 (docs/papers.md#p003-1): < 2 % for FoV <= 20°


def test_margins_of_each_constraint_against_hand_computed_values():
    c = ObservationConstraints(d_max_m=150.0, keep_out_radius_m=20.0, pointing_max_rad=np.deg2rad(5),
                               sun_exclusion_rad=np.deg2rad(30), comm_range_m=100.0)
    r = np.array([[[0.0, -60.0, 0.0], [0.0, 200.0, 0.0], [10.0, 0.0, 0.0]]])  # (1 epoch, 3 spacecraft)
    bore = np.array([[[0.0, 1.0, 0.0], [np.sin(0.1), -np.cos(0.1), 0.0], [-1.0, 0.0, 0.0]]])
    sun = np.array([[0.0, -1.0, 0.0]])  # Sun behind spacecraft 0, i.e. along its boresight's opposite
    ev = evaluate(c, r, boresight_H=bore, sun_H=sun)
    np.testing.assert_allclose(ev.margins["range"][0], [60 - c.d_min_m, 150 - 200, 10 - c.d_min_m])
    np.testing.assert_allclose(ev.margins["pointing"][0], [np.deg2rad(5), np.deg2rad(5) - 0.1, np.deg2rad(5)], atol=1e-12)
    np.testing.assert_allclose(ev.margins["keep_out"][0], [40.0, 180.0, -10.0])
    # spacecraft 1 looks almost straight at the Sun: angle 0.1 rad < 30°
    assert ev.margins["sun"][0, 1] == pytest.approx(0.1 - np.deg2rad(30), abs=1e-12)
    assert ev.margins["comm"][0, 0, 1] == pytest.approx(100 - 260.0)
    assert list(ev.single_ok[0]) == [True, False, False]
    assert ev.reasons((0,), 2)[0].startswith("range") and "keep_out" in " ".join(ev.reasons((0,), 2))
    # eclipse: nobody can observe
    dark = evaluate(c, r, sun_H=sun, target_lit=np.array([False]))
    assert not dark.single_ok.any()


def test_symmetric_geometry_passes_every_constraint():
    g = symmetric_views(3, 60.0, 10.0)
    ev = evaluate(ObservationConstraints(), g.r_CT_H[None])
    assert ev.set_ok([0, 1, 2])[0]


def test_infeasible_constraint_set_names_the_conflict():
    with pytest.raises(ValueError, match="keep-out radius 200 m > d_max 150 m"):
        ObservationConstraints(keep_out_radius_m=200.0, d_max_m=150.0)
    with pytest.raises(ValueError, match="fov_rad"):
        ObservationConstraints(fov_rad=-1.0)


def test_point_dop_equals_closed_form_for_two_orthogonal_cameras():
    """Two cameras at 50 m with perpendicular lines of sight: σ² = tr(Λ⁻¹) = (σθ d)² (1/2·... ) computed by hand."""
    r = np.array([[50.0, 0, 0], [0, 50.0, 0]])
    s = 1e-4
    # Λ = (I − x xᵀ + I − y yᵀ)/(s·50)² = diag(1, 1, 2)/(s·50)²  →  tr Λ⁻¹ = (s·50)² (1 + 1 + 0.5)
    assert point_dop(r, angular_sigma_rad=s) == pytest.approx(s * 50 * np.sqrt(2.5), rel=1e-12)
    assert point_dop(r[:1], angular_sigma_rad=s) == np.inf


def test_selection_keeps_the_set_while_feasible_and_reports_exclusions():
    g = symmetric_views(3, 60.0, 10.0).r_CT_H
    far = np.array([[0.0, 0.0, 400.0]])  # out of range
    wide = np.array([[60.0, 0.0, 0.0]])  # in range but 90° from the others
    T = 5
    r = np.repeat(np.concatenate([g, far, wide])[None], T, axis=0)
    r[3:, 0] = [0.0, 0.0, 300.0]  # camera 0 leaves the range window at epoch 3
    ev = evaluate(ObservationConstraints(), r)
    tl = select_observers(ev, r, 3)
    assert list(tl.subset[0]) == [0, 1, 2]
    assert tl.excluded[0][3].startswith("range")
    assert "axis_angle" in tl.excluded[0][4]
    assert tl.short[3:].all() and not tl.short[:3].any()
    assert tl.switches == 0


def test_selection_hysteresis_prevents_flicker_between_near_equal_sets():
    rng = np.random.default_rng(0)
    base = symmetric_views(4, 60.0, 10.0).r_CT_H
    T = 50
    r = base[None] + rng.normal(scale=0.05, size=(T, 4, 3))  # near-equal subsets, noisy scores
    ev = evaluate(ObservationConstraints(), r)
    with_h = select_observers(ev, r, 3, hysteresis=0.1)
    without = select_observers(ev, r, 3, hysteresis=0.0)
    assert with_h.switches == 0
    assert without.switches > 5
