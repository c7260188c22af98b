"""vision.pixel_noise and the sensor's "pixel" noise stream: the same noise law as one normal per pixel.

The stream of the faster rendered mode (issue 16 item 7) draws other numbers than the tile stream
before it; what must not change is the law of the digital numbers: checked here against the analytic
mean and variance of shot + read noise, the rate at which read noise alone lifts a dark pixel to 1
and 2 DN, independence of neighbouring pixels, and crop invariance.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
from scipy import stats
from scipy.special import ndtr

from vision.pixel_noise import dark_exceedances, pixel_normals
from vision.sensor import SensorModel


def test_pixel_normals_are_independent_standard_normals_keyed_by_position():
    rows, cols = np.mgrid[100:612, 3000:3512]
    z = pixel_normals(12345, rows, cols)
    n = z.size
    assert abs(z.mean()) < 4 / np.sqrt(n)
    assert z.var() == pytest.approx(1.0, abs=4 * np.sqrt(2 / n))
    assert stats.kstest(z.ravel(), "norm").pvalue > 1e-3
    for a, b in ((z[:, 1:], z[:, :-1]), (z[1:], z[:-1]), (z[1:, 1:], z[:-1, :-1])):
        assert abs(np.corrcoef(a.ravel(), b.ravel())[0, 1]) < 4 / np.sqrt(a.size)
    np.testing.assert_array_equal(pixel_normals(12345, rows[5:9, 7:30], cols[5:9, 7:30]), z[5:9, 7:30])
    assert abs(np.corrcoef(z.ravel(), pixel_normals(12346, rows, cols).ravel())[0, 1]) < 4 / np.sqrt(n)


def test_dark_exceedances_follow_a_bernoulli_process_with_the_conditional_tail():
    z0 = 1.5
    r, c, z = dark_exceedances(77, (1024, 1024), (0, 0), z0)
    n, p = 1024 * 1024, ndtr(-z0)
    assert len(r) == pytest.approx(n * p, abs=5 * np.sqrt(n * p))
    assert len(set(zip(r.tolist(), c.tolist(), strict=True))) == len(r)      # one draw per pixel
    assert np.all(z > z0)
    # the exceedances' values: the normal law conditioned on z > z0
    assert stats.kstest(z, lambda x: (p - ndtr(-x)) / p).pvalue > 1e-3      # P(Z <= x | Z > z0)
    # positions are uniform: counts per 32 x 32 tile and per column are Poisson-like
    per_col = np.bincount(c, minlength=1024)
    assert per_col.var() == pytest.approx(per_col.mean(), rel=0.2)
    # crop invariance: a crop's exceedances are the full frame's inside it
    r2, c2, z2 = dark_exceedances(77, (300, 250), (101, 517), z0)
    inside = (r >= 517) & (r < 817) & (c >= 101) & (c < 351)
    got = sorted(zip((r2 + 517).tolist(), (c2 + 101).tolist(), z2.tolist(), strict=True))
    want = sorted(zip(r[inside].tolist(), c[inside].tolist(), z[inside].tolist(), strict=True))
    assert got == want


def _quantised_gaussian_moments(mean_dn: float, sd_dn: float) -> tuple[float, float]:
    """Mean and variance of ``rint(X)``, X ~ N(mean_dn, sd_dn²) (clipping far away)."""
    k = np.arange(np.floor(mean_dn - 12 * sd_dn) - 1, np.ceil(mean_dn + 12 * sd_dn) + 2)
    pk = ndtr((k + 0.5 - mean_dn) / sd_dn) - ndtr((k - 0.5 - mean_dn) / sd_dn)
    m = float(np.sum(k * pk))
    return m, float(np.sum((k - m) ** 2 * pk))


def test_pixel_stream_mean_and_variance_follow_shot_read_and_quantisation_noise():
    """Shot (variance = signal, electrons) + read noise, quantised: the exact moments of the rounded
    Gaussian, at 0.34 DN and at 1 DN of noise."""
    s = SensorModel(auto_exposure=False, psf_sigma_px=0.0, exposure_s=1e-3)
    g = s.max_dn / s.full_well_e
    for level in (0.05, 0.5):
        img = s.apply(np.full((300, 300), level), rng=1, origin_px=(40, 900)).astype(float)
        e = level * s.electrons_per_unit_radiance
        mean, var = _quantised_gaussian_moments(e * g, np.sqrt(e + s.read_noise_e ** 2) * g)
        n = img.size
        assert img.mean() == pytest.approx(mean, abs=4 * np.sqrt(var / n))
        assert img.var() == pytest.approx(var, rel=5 * np.sqrt(2 / n))


@pytest.mark.parametrize("read_noise_e", [10.0, 20.0, 60.0])
def test_dark_pixels_reach_one_and_two_dn_at_the_analytic_rates(read_noise_e):
    """A zero-radiance image: DN = k where read noise lands in [k - 1/2, k + 1/2) DN.  10 e- is the
    default (4.4e-5 per pixel, sparse draw), 20 e- 2.5 % (sparse), 60 e- 34 % (a normal per pixel)."""
    s = SensorModel(auto_exposure=False, psf_sigma_px=0.0, read_noise_e=read_noise_e)
    shape = (2048, 2048) if read_noise_e == 10.0 else (512, 512)
    img = s.apply(np.zeros(shape), rng=3)
    n = img.size
    sd_dn = read_noise_e * s.max_dn / s.full_well_e
    for k in (1, 2):
        p = ndtr(-(k - 0.5) / sd_dn) - ndtr(-(k + 0.5) / sd_dn)
        count = np.count_nonzero(img == k)
        assert count == pytest.approx(n * p, abs=5 * np.sqrt(n * p) + 3), k
    tiles = SensorModel(auto_exposure=False, psf_sigma_px=0.0, read_noise_e=read_noise_e, noise_stream="tiles")
    if read_noise_e > 10.0:   # the same law as the tile stream: mean DN within a few standard errors
        other = tiles.apply(np.zeros(shape), rng=4).astype(float)
        se = np.sqrt((img.var() + other.var()) / n)
        assert abs(img.mean() - other.mean()) < 5 * se


def test_pixel_stream_crop_equals_the_full_frame_on_signal_and_dark_pixels():
    L = np.zeros((300, 330))
    L[100:180, 120:250] = 0.2
    for read in (10.0, 20.0):
        s = SensorModel(psf_sigma_px=0.0, auto_exposure=False, read_noise_e=read)
        full = s.apply(L, rng=9)
        crop = s.apply(L[37:281, 64:317], rng=9, origin_px=(64, 37))
        np.testing.assert_array_equal(crop, full[37:281, 64:317])
        assert np.count_nonzero(full[L == 0]) > 0 or read == 10.0


def test_tile_stream_is_the_noise_of_the_path_before_issue_16_item_7():
    """``noise_stream="tiles"`` draws exactly what the sensor drew before (checksum from that code)."""
    L = np.zeros((70, 90))
    L[20:50, 30:60] = 0.3
    img = SensorModel(noise_stream="tiles").apply(L, rng=7, origin_px=(33, 65))
    assert hashlib.sha256(img.tobytes()).hexdigest() == \
        "fa24a6334b75af2de8bf880f01d29b26c1f50ac55524eba89faf0c13cebcc2ca"


def test_both_streams_give_the_same_noise_free_image_and_unknown_stream_is_refused():
    L = np.zeros((64, 64))
    L[10:50, 20:40] = np.linspace(0.0, 0.4, 20)
    quiet = {k: SensorModel(shot_noise=False, read_noise_e=0.0, noise_stream=k) for k in ("pixel", "tiles")}
    np.testing.assert_array_equal(quiet["pixel"].apply(L, rng=1), quiet["tiles"].apply(L, rng=2))
    with pytest.raises(ValueError, match="noise_stream"):
        SensorModel(noise_stream="philox")
