"""Rendered triangulation NEES with the calibrated σ against the renderer's truth (issue 16).

Three random attitudes of FY-1 at 40 m seen by three cameras 10° apart (the check grid's geometry and
Sun).  Over such attitudes the mean NEES (truth point's own error accounted for) varies from about 2
to 7 around 3 (heavy-tailed keypoint errors, docs/vision.md), so the band is wide; it still fails
when the σ model is off by a factor of two in σ, and the configured 0.5 px gives NEES well below 1.
"""

import numpy as np

from attitude.quaternion import quat_normalize
from experiments.studies.triangulation_consistency import TrackNees, track_nees
from formation.geometry import symmetric_views
from reconstruction.triangulation import triangulate_from_observation
from vision.rendered import observe_renders, render_views


def test_calibrated_sigma_gives_rendered_nees_near_three_where_half_a_pixel_gives_far_below(camera, fy1):
    T = symmetric_views(3, 40.0, 10.0).T_CW
    sun = np.array([1.0, -0.5, 0.6])
    rng = np.random.default_rng(2)
    parts = {"calibrated": [], "fixed": []}
    for _ in range(3):
        q = quat_normalize(rng.normal(size=4))
        renders = render_views(camera, T, fy1, q, sun, rng=rng)
        for model, out in parts.items():
            obs = observe_renders(renders, fy1, q, noise_model=model)
            tri = triangulate_from_observation(obs)
            out.append(track_nees(obs, tri.X_W, tri.valid, tri.views_used, q, fy1))
    cal, fixed = (TrackNees.concat(p) for p in parts.values())
    assert cal.nees.size > 300
    assert 1.5 < cal.nees.mean() < 6.0
    assert fixed.nees.mean() < 1.0
    # the plain statistic against the first view's surface point over-counts three-view tracks
    three = cal.n_views == 3
    assert np.mean(cal.nees_plain[three]) > np.mean(cal.nees[three])
