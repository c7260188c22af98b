"""The shipped rendered-mode calibration and its interpolation (vision.calibration)."""

import json

import numpy as np
import pytest

from vision.calibration import SIZE_EDGES_PX, calibration_path, load_calibration


@pytest.fixture(scope="module")
def data():
    return json.loads(calibration_path().read_text(encoding="utf-8"))


def test_shipped_calibration_states_its_provenance_and_sample_counts(data):
    p = data["provenance"]
    assert p["command"].startswith("coobs calibrate")
    assert p["renderer"]["function"] == "vision.render.render" and p["renderer"]["image_px"] == 1024
    assert p["detector"]["opencv_options"] == {"enable_precise_upscale": True}
    assert set(data["targets"]) >= {"fy1", "topex"}
    for t in data["targets"].values():
        assert t["ranges_m"] == [40.0, 80.0]
        assert min(t["samples_per_range"]) >= 20
        assert sum(t["sigma_pairs_per_bin"]) > 5000


@pytest.mark.parametrize("name", ["fy1", "topex"])
def test_measured_sigma_grows_from_the_smallest_to_the_largest_sift_keypoints(name):
    cal = load_calibration(name)
    assert 0.05 < cal.sigma_px[0] < 0.3             # issue 16: 0.15-0.20 px for the bulk of keypoints
    assert cal.sigma_px[-1] > 1.5 * cal.sigma_px[0]  # a 32 px blob is localised worse than a 2 px one
    sizes = 0.5 * (SIZE_EDGES_PX[:-2] + SIZE_EDGES_PX[1:-1])
    np.testing.assert_array_equal(cal.sigma_for_size(sizes), cal.sigma_px[:-1])


def test_sigma_at_an_image_scale_is_the_by_range_table_and_held_beyond_it():
    cal = load_calibration("fy1")
    sizes = 0.5 * (SIZE_EDGES_PX[:-2] + SIZE_EDGES_PX[1:-1])
    for r, fp in enumerate(cal.footprint_m_per_px):
        np.testing.assert_allclose(cal.sigma_for_size(sizes, fp), cal.sigma_px_by_range[r, :-1])
    np.testing.assert_allclose(cal.sigma_for_size(sizes, 3 * cal.footprint_m_per_px[-1]), cal.sigma_px_by_range[-1, :-1])
    mid = cal.sigma_for_size(sizes, np.sqrt(np.prod(cal.footprint_m_per_px)))
    np.testing.assert_allclose(mid, cal.sigma_px_by_range[:, :-1].mean(axis=0))


def test_density_is_interpolated_in_log_footprint_and_follows_the_power_law_beyond():
    cal = load_calibration("fy1")
    f0, f1 = cal.footprint_m_per_px
    cos_v, sun = np.array([0.95]), np.array([5])
    d0, d1 = cal.density(f0, cos_v, sun), cal.density(f1, cos_v, sun)
    mid = cal.density(np.sqrt(f0 * f1), cos_v, sun)
    np.testing.assert_allclose(mid, np.sqrt(d0 * d1), rtol=1e-12)
    beyond = cal.density(f1 * f1 / f0, cos_v, sun)                  # one more factor of two in range
    np.testing.assert_allclose(beyond, d1 * d1 / d0, rtol=1e-12)


def test_rates_hold_the_nearest_calibrated_value_outside_the_calibrated_grid():
    cal = load_calibration("topex")
    f0 = cal.footprint_m_per_px[0]
    np.testing.assert_allclose(cal.association_survival_at(0.5 * f0, 0.1),
                               cal.association_survival[0, 0])
    np.testing.assert_allclose(cal.association_survival_at(f0, cal.change_deg[-1] + 30),
                               cal.association_survival[0, -1])
    assert np.all(np.diff(cal.association_survival_at(f0, cal.change_deg)) <= 0.05)  # survival falls with the change


def test_unknown_meshes_use_the_topex_calibration_and_a_missing_file_is_one_error(tmp_path):
    assert load_calibration("hubble").target == "topex"
    assert load_calibration("FY-1-like").target == "fy1"
    with pytest.raises(ValueError, match="coobs calibrate"):
        load_calibration("fy1", path=tmp_path / "none.json")


def _density_formula(cal, fp, cos_view, sun_bin, material=None):
    """The density's definition on the raw tables (one searchsorted and log per call): the reference
    of the tabulated :meth:`SiftCalibration.density`."""
    from vision.calibration import COS_VIEW_EDGES

    lf = np.log(cal.footprint_m_per_px)
    x = np.log(fp)
    i = np.clip(np.searchsorted(lf, x) - 1, 0, lf.size - 2)
    w = (x - lf[i]) / (lf[i + 1] - lf[i])
    v = np.clip(np.searchsorted(COS_VIEW_EDGES, np.abs(cos_view), side="right") - 1, 0, len(COS_VIEW_EDGES) - 2)
    lo = np.maximum(cal.density_per_m2[i, v, sun_bin], 1e-9)
    hi = np.maximum(cal.density_per_m2[i + 1, v, sun_bin], 1e-9)
    if material is not None:
        lo, hi = lo * cal.material_factor[i, material], hi * cal.material_factor[i + 1, material]
    return np.exp((1.0 - w) * np.log(lo) + w * np.log(hi))


@pytest.mark.parametrize("name", ["fy1", "topex"])
def test_tabulated_density_equals_its_definition_bit_for_bit(name):
    """density (log table, flat look-ups, bins by comparison) gives exactly the formula's numbers, with
    and without materials, inside and beyond the calibrated footprints; density_at on shared bins too."""
    cal = load_calibration(name)
    rng = np.random.default_rng(3)
    n = 20000
    fp = np.exp(rng.uniform(np.log(0.3 * cal.footprint_m_per_px[0]), np.log(3 * cal.footprint_m_per_px[-1]), n))
    cos_v = np.concatenate([rng.uniform(-1.0, 1.0, n - 6), [0.0, 0.26, -0.5, 0.71, 0.87, 1.0]])
    sun = rng.integers(0, 6, n)
    mat = rng.integers(0, cal.material_factor.shape[1], n)
    np.testing.assert_array_equal(cal.density(fp, cos_v, sun), _density_formula(cal, fp, cos_v, sun))
    np.testing.assert_array_equal(cal.density(fp, cos_v, sun, mat), _density_formula(cal, fp, cos_v, sun, mat))
    bins = cal.density_bins(fp, cos_v)
    np.testing.assert_array_equal(cal.density_at(bins, np.zeros(n, dtype=int), mat),
                                  _density_formula(cal, fp, cos_v, np.zeros(n, dtype=int), mat))
    assert cal.density(fp[0], cos_v[0], sun[0]) == _density_formula(cal, fp[:1], cos_v[:1], sun[:1])[0]


def test_bins_by_comparison_equal_searchsorted():
    from vision.calibration.tables import bin_index

    rng = np.random.default_rng(4)
    for edges in (SIZE_EDGES_PX, np.array([-1.0, 0.0, 0.26, 0.5, 1.0001]), np.array([5.0, 10.0, 20.0, 30.0]), np.array([2.0])):
        x = np.concatenate([rng.uniform(-3.0, 40.0, 2000), edges, [np.nan, np.inf, -np.inf]])
        for side in ("left", "right"):
            for lo, hi in ((0, max(len(edges) - 2, 0)), (1, len(edges) - 2), (0, len(edges) - 1)):
                if hi < lo:
                    continue
                ref = np.clip(np.searchsorted(edges, x, side=side) - 1, lo, hi)
                np.testing.assert_array_equal(bin_index(edges, x, side, lo, hi), ref)


@pytest.mark.parametrize("name", ["fy1", "topex"])
def test_rates_on_broadcast_arrays_equal_their_pointwise_values(name):
    """A rate of (footprints × angles) arrays is, element by element, the rate at each pair of scalars."""
    cal = load_calibration(name)
    fp = np.array([0.5, 1.0, 1.7, 4.0]) * cal.footprint_m_per_px[0]
    ang = np.array([[0.0, 7.0, 12.5], [20.0, 33.0, 80.0]])
    for rate in (cal.pair_survival_at, cal.false_match_rate_at, cal.association_survival_at):
        many = rate(fp[:, None, None], ang[None])
        one = np.array([[[rate(f, a) for a in row] for row in ang] for f in fp])
        np.testing.assert_array_equal(many, one)
        np.testing.assert_array_equal(rate(fp, 3.0), [rate(f, 3.0) for f in fp])
