"""Smoke-and-substance test of the orbit figures (experiments.studies.orbit_figures)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from experiments.studies.orbit_figures import cw_error_growth_data, cw_error_growth_figure  # noqa: E402


def test_cw_error_growth_study_scales_with_size_squared_and_draws():
    d = cw_error_growth_data(semi_major_m=(25.0, 50.0), orbits=2.0, epochs=41, phases=4)
    assert d.error_m.shape == (2, 41)
    np.testing.assert_allclose(d.error_m[1, -1] / d.error_m[0, -1], 4.0, rtol=0.02)
    fig = cw_error_growth_figure(d)
    assert len(fig.axes) == 2 and len(fig.axes[0].lines) == 3  # two sizes + the 2 cm line
    plt.close(fig)
