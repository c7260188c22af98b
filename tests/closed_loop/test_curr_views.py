"""The frames' curr views: the smoother's consistency on links whose fit puts a frame's noise into its
two increments with the same sign."""

from __future__ import annotations

import numpy as np

from experiments.studies.smoother_consistency import synthetic_run


def test_symmetric_fit_errors_in_curr_views_keep_the_chain_consistent():
    """Links with frame shares (0.04°), a symmetric fit error per frame (0.03°, entering the increment
    into the frame and the next one alike) and 0.01° of their own, no closure within the 30 s, the
    inertia estimated, seeds 0–9: with the symmetric part held by the frames' curr views the attitude NEES
    averaged over 10–30 s must lie within [2.0, 4.5] (measured 3.37).  Given as part of each link's
    independent remainder instead, the same links give 6.12: the part adds up along the chain, which
    independent links do not know (docs/closed_loop.md, "The fit's symmetric part")."""
    nees = np.stack([synthetic_run(30.0, estimate_inertia=True, seed=s, sigma_deg=0.01, share_deg=0.04,
                                   symmetric_deg=0.03)[2] for s in range(10)])
    assert 2.0 < nees[:, 19:, 0].mean() < 4.5
