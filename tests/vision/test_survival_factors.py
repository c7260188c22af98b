"""Joint cross-view survival factors of Sun phase, material, brightness and view angle (vision.calibration.survival_factors)."""

import numpy as np
import pytest

from vision.calibration.survival_factors import (
    MIN_EXPECTED_CORRECT,
    fit_main_effects,
    survival_factors,
)


def _product(f):
    return f[0][:, None, None] * f[1][None, :, None] * f[2][None, None, :]


def test_main_effects_are_recovered_exactly_from_a_noise_free_table():
    """observed = expected · f_p · f_m · f_b exactly: the fit returns that product (the factors up to
    the shared scale), to 1e-8."""
    rng = np.random.default_rng(0)
    expected = rng.uniform(1.0, 50.0, size=(6, 7, 9))
    truth = [rng.uniform(0.2, 2.0, n) for n in expected.shape]
    f = fit_main_effects(expected, expected * _product(truth))
    np.testing.assert_allclose(_product(f), _product(truth), rtol=1e-8)
    # the scale convention: phase and material factors have mean 1 over their expected margins
    for k, axes in ((0, (1, 2)), (1, (0, 2))):
        w = expected.sum(axis=axes)
        assert np.sum(w * f[k]) / np.sum(w) == pytest.approx(1.0, rel=1e-12)


def test_the_fit_reproduces_every_margin_of_poisson_counts():
    """The maximum-likelihood main-effects fit of Poisson counts matches each axis's observed margin."""
    rng = np.random.default_rng(1)
    expected = rng.uniform(0.0, 30.0, size=(6, 7, 9))
    expected[2, 3] = 0.0                                    # an empty cell
    observed = rng.poisson(expected * _product([rng.uniform(0.5, 1.5, n) for n in expected.shape]))
    model = expected * _product(fit_main_effects(expected, observed))
    for axes in ((1, 2), (0, 2), (0, 1)):
        np.testing.assert_allclose(model.sum(axis=axes), observed.sum(axis=axes), rtol=1e-8)


def test_joint_factors_do_not_count_a_correlated_effect_twice():
    """Brightness follows the material (material 0 mostly bright, material 1 mostly dim) and only the
    material changes the survival (material 0 twice material 1; the base table predicts the total, as
    the calibration's does).  The marginal factors put the effect in both kinds (material 4/3 and 2/3,
    brightness 11/15 and 19/15), so their product predicts 242.7 correct matches on material 0 where
    200 were measured; the joint factors give every cell exactly."""
    expected = np.zeros((1, 2, 2))
    expected[0, 0] = [15.0, 135.0]
    expected[0, 1] = [135.0, 15.0]
    observed = expected * np.array([4.0 / 3.0, 2.0 / 3.0])[None, :, None]
    f = fit_main_effects(expected, observed)
    np.testing.assert_allclose(expected * _product(f), observed, rtol=1e-8)
    marginal = [observed.sum(axis=a) / expected.sum(axis=a) for a in ((1, 2), (0, 2), (0, 1))]
    np.testing.assert_allclose(marginal[0], [1.0])
    m_model = expected * _product(marginal)
    assert m_model[0, 0].sum() == pytest.approx(242.0 + 2.0 / 3.0) and observed[0, 0].sum() == pytest.approx(200.0)


def _cv(expected, correct):
    return {"joint_expected": np.asarray(expected).tolist(), "joint_correct": np.asarray(correct).tolist(),
            "survival": [[0.3, 0.2]]}


def test_sparse_classes_get_no_factor_of_their_own():
    """A phase bin expected to have fewer than MIN_EXPECTED_CORRECT correct matches takes its nearest
    neighbour's factor, a material, brightness or view class 1."""
    expected = np.full((6, 3, 4, 5), 2.0)
    expected[5] = 0.02                      # phase bin 5
    expected[:, 2] = 0.02                   # material 2
    expected[:, :, 3] = 0.01                # brightness bin 3
    expected[:, :, :, 0] = 0.01             # view bin 0
    assert expected[5].sum() < MIN_EXPECTED_CORRECT and expected[:, 2].sum() < MIN_EXPECTED_CORRECT
    assert expected[:, :, :, 0].sum() < MIN_EXPECTED_CORRECT <= expected[:, :, :, 1].sum()
    rng = np.random.default_rng(2)
    correct = rng.poisson(expected * 0.8)
    f = survival_factors(_cv(expected, correct))
    assert f["phase"][5] == f["phase"][4]
    assert f["material"][2] == 1.0 and f["brightness"][3] == 1.0 and f["view"][0] == 1.0
    assert all(np.all(np.isfinite(f[k])) for k in f) and f["phase"].shape == (6,) and f["view"].shape == (5,)


def test_a_file_without_joint_counts_keeps_the_marginal_factors():
    """Without the joint counts each kind's factor is its marginal ratio (the previous model)."""
    cv = {"survival": [[0.5]], "material_matchable": [[[400.0, 100.0]]], "material_correct": [[[100.0, 40.0]]]}
    f = survival_factors(cv)
    np.testing.assert_allclose(f["material"], [100.0 / 200.0, 40.0 / 50.0])
    assert f["phase"] is None and f["brightness"] is None and f["view"] is None


def test_mismatched_tables_are_refused_naming_them():
    with pytest.raises(ValueError, match="expected and observed"):
        fit_main_effects(np.ones((2, 2)), np.ones((2, 3)))
