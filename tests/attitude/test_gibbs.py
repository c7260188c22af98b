"""Gibbs vectors (001 eq 1–5, 8′, 10) and MRPs: conventions, switching, composition (hypothesis)."""

import numpy as np
import pytest
from hypothesis import given

from attitude.gibbs import (
    GIBBS_SET_MATRICES,
    best_gibbs_set,
    gibbs_from_quat,
    gibbs_multiply,
    gibbs_set_from_quat,
    gibbs_switch,
    gibbs_transform,
    matrix_from_gibbs,
    mrp_from_quat,
    mrp_shadow,
    quat_from_gibbs,
    quat_from_gibbs_set,
    quat_from_mrp,
    shuster_from_quat,
    shuster_gibbs_compose,
    shuster_matrix_from_gibbs,
    shuster_matrix_from_gibbs_set,
    shuster_quat_multiply,
)
from attitude.quaternion import (
    matrix_from_quat,
    quat_angle_between,
    quat_from_axis_angle,
    quat_multiply,
)
from tests.attitude.strategies import unit_quats, vectors


@given(unit_quats())
def test_every_parameter_set_gives_the_same_matrix(q):
    """001 eq (8′): A(g^(i)) R^(i) = A(q) = R_ABᵀ for all four sets where the set exists."""
    A = matrix_from_quat(q).T
    q_s = shuster_from_quat(q)
    for i in range(4):
        den = q_s[3] if i == 0 else q_s[i - 1]
        if abs(den) < 1e-3:
            continue
        g = gibbs_set_from_quat(q, i)
        np.testing.assert_allclose(shuster_matrix_from_gibbs_set(g, i), A, atol=1e-9)
        assert quat_angle_between(quat_from_gibbs_set(g, i), q) < 1e-6


@given(unit_quats())
def test_best_set_has_all_components_at_most_one_and_round_trips(q):
    g, i = best_gibbs_set(q)
    assert np.all(np.abs(g) <= 1.0 + 1e-12)
    np.testing.assert_allclose(shuster_matrix_from_gibbs_set(g, i), matrix_from_quat(q).T, atol=1e-12)
    assert quat_angle_between(quat_from_gibbs_set(g, i), q) < 1e-7


@given(unit_quats())
def test_switching_from_any_set_ends_with_components_at_most_one(q):
    """001 eq (5) rule: after switching every |g_j| <= 1 and the matrix is unchanged."""
    q_s = shuster_from_quat(q)
    for i in range(4):
        den = q_s[3] if i == 0 else q_s[i - 1]
        if abs(den) < 1e-6:
            continue
        g = gibbs_set_from_quat(q, i)
        g2, i2 = gibbs_switch(g, i)
        assert np.all(np.abs(g2) <= 1.0 + 1e-12)
        np.testing.assert_allclose(shuster_matrix_from_gibbs_set(g2, i2), matrix_from_quat(q).T, atol=1e-9)


def test_transforms_reproduce_the_parameter_sets_for_all_twelve_combinations():
    """001 eq (4)–(5): g^(i') = T_j(g^(i)) with i' = j (i = 0), 0 (j = i), 6 − j − i otherwise."""
    q = quat_from_axis_angle([0.3, -0.7, 0.5], 2.1)
    for i in range(4):
        for j in (1, 2, 3):
            i_new = j if i == 0 else (0 if j == i else 6 - j - i)
            np.testing.assert_allclose(gibbs_transform(gibbs_set_from_quat(q, i), j),
                                       gibbs_set_from_quat(q, i_new), atol=1e-12)


def test_switch_with_hysteresis_keeps_set_just_above_one():
    g = np.array([1.02, 0.1, 0.2])
    g2, i2 = gibbs_switch(g, 0, eta=0.05)
    assert i2 == 0 and np.array_equal(g2, g)
    g3, i3 = gibbs_switch(g, 0)
    assert i3 == 1 and np.all(np.abs(g3) <= 1)


@given(unit_quats())
def test_hamilton_gibbs_matrix_is_transpose_of_shuster(q):
    if abs(q[0]) < 1e-3:
        return
    g = gibbs_from_quat(q)
    np.testing.assert_allclose(matrix_from_gibbs(g), matrix_from_quat(q), atol=1e-9)
    np.testing.assert_allclose(shuster_matrix_from_gibbs(g), matrix_from_quat(q).T, atol=1e-9)
    assert quat_angle_between(quat_from_gibbs(g), q) < 1e-7


@given(vectors, vectors)
def test_composition_laws_hamilton_and_shuster_eq10(g1, g2):
    if abs(1 - g1 @ g2) < 1e-2:
        return
    np.testing.assert_allclose(matrix_from_gibbs(gibbs_multiply(g1, g2)),
                               matrix_from_gibbs(g1) @ matrix_from_gibbs(g2), atol=1e-9)
    np.testing.assert_allclose(shuster_matrix_from_gibbs(shuster_gibbs_compose(g1, g2)),
                               shuster_matrix_from_gibbs(g1) @ shuster_matrix_from_gibbs(g2), atol=1e-9)


@given(unit_quats(), unit_quats())
def test_shuster_product_reverses_hamilton_order(p, q):
    """p ⊗_S q has the numbers of q ⊗_H p (flag P001-3, docs/papers.md#p001-3)."""
    np.testing.assert_allclose(shuster_quat_multiply(shuster_from_quat(p), shuster_from_quat(q)),
                               shuster_from_quat(quat_multiply(q, p)), atol=1e-14)


def test_gibbs_set_matrices_are_pi_rotations_about_reference_axes():
    for i in (1, 2, 3):
        axis = np.eye(3)[i - 1]
        np.testing.assert_allclose(GIBBS_SET_MATRICES[i], matrix_from_quat(quat_from_axis_angle(axis, np.pi)),
                                   atol=1e-15)


@given(unit_quats())
def test_mrp_round_trip_and_shadow_set(q):
    p = mrp_from_quat(q)
    assert np.linalg.norm(p) <= 1 + 1e-12
    assert quat_angle_between(quat_from_mrp(p), q) < 1e-7
    if np.linalg.norm(p) > 1e-3:
        np.testing.assert_allclose(matrix_from_quat(quat_from_mrp(mrp_shadow(p))), matrix_from_quat(q), atol=1e-9)


def test_gibbs_of_180_degrees_is_an_error_naming_q():
    with pytest.raises(ValueError, match="q: rotation of 180 degrees"):
        gibbs_from_quat([0.0, 1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="i: parameter-set index"):
        gibbs_set_from_quat([1.0, 0, 0, 0], 4)


def test_subnormal_denominator_gives_inf_without_a_warning():
    """A set whose denominator underflows is simply unusable (inf), never a RuntimeWarning."""
    q = np.array([1e-310, 1.0, 0.0, 0.0])
    g = gibbs_set_from_quat(q, 0)
    assert np.isinf(g[0])
    g_best, i = best_gibbs_set(q)
    assert i == 1 and np.all(np.isfinite(g_best))
