"""Formation plot functions draw the data they are given (Agg backend) and compute nothing else."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.collections import QuadMesh  # noqa: E402

from experiments.scenarios.formation.docs_figures import (  # noqa: E402
    CATEGORIES,
    FormationFigureData,
    SelectionCase,
    exclusion_categories,
    formation_3d_figure,
    frustum_corners_H,
    plot_feasible_count,
    plot_formation_3d,
    plot_selection_timeline,
    selection_timeline_figure,
)
from formation.constraints import ObservationConstraints, evaluate  # noqa: E402
from formation.geometry import look_at  # noqa: E402
from formation.selection import select_observers  # noqa: E402


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def _label(code: int) -> str:
    return CATEGORIES[code][0]


def test_exclusion_categories_follow_the_selection_reasons():
    r = np.array([[[0.0, -60.0, 0.0], [0.0, -500.0, 0.0], [0.0, -10.0, 0.0], [60.0, 0.0, 0.0],
                   [0.0, -70.0, 0.0]]])
    r[0, 4] = [70 * np.sin(0.2), -70 * np.cos(0.2), 0.0]  # 11.5° from SC0: fine with it
    tl = select_observers(evaluate(ObservationConstraints(), r), r, 2)
    cat = exclusion_categories(tl.excluded, tl.active)
    assert [_label(c) for c in cat[0]] == ["active", "range window", "keep-out", "pairwise axis angle", "active"]
    reasons = [{0: "no feasible set of the wanted size (pairwise conflicts among the others)",
                1: "no feasible set of the wanted size (pairwise comm with [3])",
                2: "no feasible set of the wanted size (only 2 candidates pass their own constraints)",
                3: "pointing (margin -0.1 rad); sun (margin -0.2 rad)"}]
    assert [_label(c) for c in exclusion_categories(reasons, np.zeros((1, 4), bool))[0]] == [
        _label(2), "pairwise comm range", _label(2), "Sun / eclipse"]
    with pytest.raises(ValueError, match="excluded"):
        exclusion_categories([{0: "cosmic rays"}], np.zeros((1, 1), bool))


def test_frustum_corners_lie_on_the_image_edges_at_the_given_depth():
    """Camera 60 m behind the target looking along +y: corners at y = 0, |x| = |z| = 60 tan(FoV/2)."""
    T = look_at(np.array([[0.0, -60.0, 0.0]]), np.zeros(3), np.array([0.0, 0.0, 1.0]))
    c = frustum_corners_H(T, np.deg2rad(20.0), np.deg2rad(20.0), 60.0)
    h = 60.0 * np.tan(np.deg2rad(10.0))
    np.testing.assert_allclose(c[0, :, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.abs(c[0, :, [0, 2]]), h, rtol=1e-12)
    assert len({(np.sign(x), np.sign(z)) for x, _, z in c[0]}) == 4


def _figure_data(T: int = 30, N: int = 4) -> FormationFigureData:
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 5400.0, T, endpoint=False)
    ang = 2 * np.pi * t / 5400.0
    r = np.stack([np.stack([20 * np.cos(ang + i), -60.0 - 100 * i + 40 * np.sin(ang + i), 10 * np.sin(ang)], -1)
                  for i in range(N)])
    cam = np.array([[6.0, -60.0, 0.0], [-3.0, -60.0, 5.2], [-3.0, -60.0, -5.2]])
    T_CW = look_at(cam, np.zeros(3), np.array([0.0, 0.0, 1.0]))
    case = SelectionCase("case", rng.integers(0, len(CATEGORIES), (T, N)), rng.integers(0, 3, T),
                         np.where(rng.random(T) < 0.5, 1e-3, np.inf), 2)
    return FormationFigureData(
        period_s=5400.0, t_s=t, r_coast_H=r, movers=np.array([0, 1, 2]), transfer_H=r[:3, :10],
        hold_H=r[:3, 10:], impulse_r_H=r[:3, :6:2], impulse_dv_H=rng.normal(scale=0.01, size=(3, 3, 3)),
        slots_H=cam, tf_s=3000.0, snapshot_s=3500.0, camera_r_H=cam, camera_ids=np.array([0, 1, 2]),
        frusta_H=frustum_corners_H(T_CW, 0.35, 0.35, 60.0), keep_out_radius_m=20.0, target_radius_m=5.0,
        cases=(case, case), plan_summary={"circulating slots": {"dv_total_m_s": 0.18, "lower_bound_m_s": 0.17}})


def test_formation_3d_draws_every_trajectory_frustum_and_impulse():
    d = _figure_data()
    ax = plot_formation_3d(d.r_coast_H, transfer_H=d.transfer_H, hold_H=d.hold_H, impulse_r_H=d.impulse_r_H,
                           impulse_dv_H=d.impulse_dv_H, camera_r_H=d.camera_r_H, frusta_H=d.frusta_H,
                           keep_out_radius_m=20.0, target_radius_m=5.0)
    assert ax.name == "3d"
    xs = [ln.get_data_3d()[0] for ln in ax.lines]
    # 4 coasting + 3 transfers + 3 after arrival + 3 frusta × (4 edges + 1 ring) + 1 legend proxy
    assert len(ax.lines) == 4 + 3 + 3 + 15 + 1
    np.testing.assert_array_equal(xs[0], d.r_coast_H[0, :, 0])
    labels = ax.get_legend_handles_labels()[1]
    assert "planned transfer" in labels and "active observers" in labels
    assert any(lab.startswith("impulses") for lab in labels)


def test_formation_3d_box_cuts_what_leaves_it_and_keeps_equal_scales():
    d = _figure_data()
    ax = plot_formation_3d(d.r_coast_H, limits_m=((-30, 30), (-90, 25), (-30, 30)), legend=False)
    x, y, _ = ax.lines[1].get_data_3d()  # SC1 stays beyond y = -90: nothing drawn
    assert np.all(np.isnan(y))
    np.testing.assert_allclose(ax.get_ylim(), (-90, 25))


def test_selection_timeline_shows_the_category_codes_and_the_counts():
    d = _figure_data()
    case = d.cases[0]
    ax = plot_selection_timeline(d.t_s, case.category, period_s=d.period_s, marks_s=(0.0, d.tf_s))
    mesh = [c for c in ax.collections if isinstance(c, QuadMesh)][0]
    np.testing.assert_array_equal(np.asarray(mesh.get_array()).reshape(case.category.T.shape), case.category.T)
    assert [t.get_text() for t in ax.get_yticklabels()] == ["SC0", "SC1", "SC2", "SC3"]
    ax2, tw = plot_feasible_count(d.t_s, case.n_feasible, score_rad=case.score_rad, n_subsets=4)
    np.testing.assert_array_equal(ax2.lines[0].get_ydata(), case.n_feasible)
    y = tw.lines[0].get_ydata()
    np.testing.assert_allclose(y[np.isfinite(case.score_rad)], np.degrees(1e-3) * 1e3)
    assert np.all(np.isnan(y[~np.isfinite(case.score_rad)]))


def test_docs_figures_assemble_from_stored_data():
    d = _figure_data()
    f1 = formation_3d_figure(d)
    assert len(f1.axes) == 2
    title = f1.get_suptitle()
    assert "Δv 180.0 mm/s" in title and "lower bound 170.0 mm/s" in title
    f2 = selection_timeline_figure(d)
    assert len([a for a in f2.axes if a.get_label() != "<colorbar>"]) >= 4
    assert f2.legends and {t.get_text() for t in f2.legends[0].get_texts()} <= {c[0] for c in CATEGORIES}
