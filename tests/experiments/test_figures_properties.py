"""Properties every figure must have, each able to fail on a defect users reported.

- compared map panels share one colour range, and the colour bar has an arrow when values are clipped;
- cell labels are at least 7 pt with a WCAG contrast of at least 4.5 against their cell;
- every colour map is perceptually uniform (an allow-list written here, independently of the code's);
- every label with a unit writes it as ``[unit]``;
- no legend lies over a data line;
- figures are written as PNG, PDF or SVG by suffix, byte for byte the same when redrawn;
- the closed loop stores the filter's σ (checked against the initial covariance) and truth points
  (checked against the reconstructed cloud).
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.collections import QuadMesh  # noqa: E402
from matplotlib.colors import to_rgb  # noqa: E402
from mpl_toolkits.mplot3d import Axes3D  # noqa: E402

from experiments.plotting import figure_path, save  # noqa: E402
from tests.experiments.figures_data import closed_loop_run, error_map_sweep, fixed_style, tof_run  # noqa: E402

PERCEPTUAL = {"viridis", "viridis_r", "cividis", "cividis_r", "gray", "coolwarm", "RdBu_r"}
UNIT_WORDS = {"s", "m", "mm", "deg", "deg/s", "mdeg", "px", "DN", "%", "µs", "m/s", "mm/s", "orbits", "min"}
BAD_UNIT = re.compile(r"\((?:s|m|mm|deg|deg/s|mdeg|px|DN|%|µs|m/s|mm/s|orbits|min|chief orbits)\)|\s/\s?(?:mm|deg|s)\b")


def _capture(module, monkeypatch) -> list:
    """Record every figure ``module`` saves (through its ``save``) before it is written and closed."""
    figs: list = []
    real = module.save

    def keep(fig, path, **kw):
        figs.append(fig)
        return real(fig, path, **kw)

    monkeypatch.setattr(module, "save", keep)
    return figs


@pytest.fixture(scope="module")
def drawn(tmp_path_factory):
    """All figure types of the tests' datasets, as live Figure objects keyed by file stem."""
    from experiments.scenarios.formation import figures
    from experiments.studies.orbit_figures import cw_error_growth_data, cw_error_growth_figure

    out = tmp_path_factory.mktemp("figs")
    ds = error_map_sweep()
    result: dict = {}
    with fixed_style(), pytest.MonkeyPatch.context() as mp:
        figs = _capture(figures, mp)
        paths = [*figures.error_map_figures(ds, out),
                 *figures.convergence_map_figures(ds, out, frac=ds["filter_fraction_converged"],
                                                  tmed=ds["filter_median_convergence_time_s"],
                                                  name="convergence_maps", title="t"),
                 *figures.closed_loop_figures(closed_loop_run(), out)]
        result.update({p.stem: f for p, f in zip(paths, figs, strict=True)})
        import experiments.plotting as plotting

        figs2 = _capture(plotting, mp)  # tof's plot imports save from the package when it runs
        from experiments.scenarios.tof.figures import plot

        tof_paths = plot(tof_run(), out)
        result.update({p.stem: f for p, f in zip(tof_paths, figs2, strict=True)})
        result["cw_error_growth"] = cw_error_growth_figure(
            cw_error_growth_data(semi_major_m=(25.0, 100.0), orbits=1.0, epochs=21, phases=3))
        for f in result.values():
            FigureCanvasAgg(f).draw()  # a closed figure keeps no drawing canvas
    return result


def _maps(fig) -> list[QuadMesh]:
    """The map panels' meshes (not the colour bars' own)."""
    return [c for ax in fig.axes if ax.get_label() != "<colorbar>" for c in ax.collections if isinstance(c, QuadMesh)]


def test_error_map_panels_share_one_range_and_the_bar_marks_the_clipped_cells(drawn):
    meshes = _maps(drawn["error_maps"])
    assert len(meshes) == 6
    assert {(m.norm.vmin, m.norm.vmax) for m in meshes} == {(0.0, 1.6)}
    # 1.88 and 3.32 deg lie above 1.6: the (single, shared) colour bar shows the arrow
    bars = {id(m.colorbar): m.colorbar for m in meshes if m.colorbar is not None}
    assert len(bars) == 1 and next(iter(bars.values())).extend in ("max", "both")


def test_convergence_time_rows_share_one_range_spanning_every_row(drawn):
    ds = error_map_sweep()
    meshes = _maps(drawn["convergence_maps"])
    times = [m for m in meshes if m.get_cmap().name == "viridis_r"]
    fractions = [m for m in meshes if m.get_cmap().name == "cividis"]
    assert len(times) == 2 and len(fractions) == 2
    t = ds["filter_median_convergence_time_s"].values
    assert {(m.norm.vmin, m.norm.vmax) for m in times} == {(np.nanmin(t), np.nanmax(t))}
    assert {(m.norm.vmin, m.norm.vmax) for m in fractions} == {(0.0, 1.0)}


def _luminance(rgb) -> float:
    c = np.array(to_rgb(rgb))
    c = np.where(c <= 0.03928, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]


@pytest.mark.parametrize("name", ["error_maps", "convergence_maps"])
def test_cell_labels_are_at_least_7pt_and_contrast_4_5_with_their_cell(drawn, name):
    n = 0
    for ax in drawn[name].axes:
        meshes = [c for c in ax.collections if isinstance(c, QuadMesh)]
        if not meshes:
            continue
        m = meshes[0]
        for txt in ax.texts:
            n += 1
            cell = m.cmap(m.norm(float(txt.get_text())))
            lt, lc = _luminance(txt.get_color()), _luminance(cell)
            contrast = (max(lt, lc) + 0.05) / (min(lt, lc) + 0.05)
            assert txt.get_fontsize() >= 7
            assert contrast >= 4.5, (txt.get_text(), txt.get_color(), cell)
    assert n > 20


def test_every_colour_map_is_perceptually_uniform(drawn):
    for name, fig in drawn.items():
        for ax in fig.axes:
            for m in [*ax.collections, *ax.images]:
                if m.get_array() is not None:
                    assert m.get_cmap().name in PERCEPTUAL, (name, m.get_cmap().name)


def test_every_unit_is_written_in_square_brackets(drawn):
    seen = 0
    for name, fig in drawn.items():
        for ax in fig.axes:
            labels = [ax.get_xlabel(), ax.get_ylabel()] + ([ax.get_zlabel()] if isinstance(ax, Axes3D) else [])
            for lab in filter(None, labels):
                assert not BAD_UNIT.search(lab), (name, lab)
                for unit in re.findall(r"\[([^\]]*)\]", lab):
                    seen += 1
                    assert unit in UNIT_WORDS, (name, lab)
    assert seen > 30


def test_no_legend_lies_over_a_data_line(drawn):
    checked = 0
    for name, fig in drawn.items():
        renderer = fig.canvas.get_renderer()
        legends = [*fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_legend() is not None)]
        for leg in legends:
            box = leg.get_window_extent(renderer)
            for ax in fig.axes:
                if isinstance(ax, Axes3D):
                    continue
                for line in ax.get_lines():
                    xy = np.asarray(line.get_xydata(), dtype=float)
                    if not np.isfinite(xy).all(axis=1).any():
                        continue
                    checked += 1
                    assert not box.overlaps(line.get_window_extent(renderer)), (name, line.get_label())
    assert checked > 50


def test_the_closed_loop_figures_name_the_envelope_and_the_shaded_epochs(drawn):
    for name in ("errors", "errors_axes"):
        texts = {t.get_text() for leg in drawn[name].legends for t in leg.get_texts()}
        assert "target in Earth's shadow" in texts and "no increment used (lit)" in texts
        assert any("3σ" in t for t in texts)
    texts = {t.get_text() for t in drawn["errors"].legends[0].get_texts()}
    assert "convergence threshold" in texts


def test_the_cloud_has_a_labelled_colour_bar_truth_and_limits_not_set_by_outliers(drawn):
    fig = drawn["reconstructed_cloud"]
    ax = next(a for a in fig.axes if isinstance(a, Axes3D))
    sc = ax.collections[0]
    assert sc.colorbar is not None and sc.colorbar.ax.get_ylabel() == "triangulation σ [mm]"
    assert [t.get_text() for t in ax.get_legend().get_texts()][1] == "truth"
    # the 6 outliers lie 35–60 m out; the target spans ±1.5 m: the axes stay within a few metres
    for lo, hi in (ax.get_xlim(), ax.get_ylim(), ax.get_zlim()):
        assert hi - lo < 5.0


@pytest.mark.parametrize("fmt", ["png", "pdf", "svg"])
def test_save_writes_the_format_of_the_suffix_and_redraws_the_same_bytes(tmp_path, fmt):
    def draw(path: Path) -> bytes:
        fig, ax = plt.subplots(figsize=(3.0, 2.0))
        ax.plot([0, 1, 2], [0, 1, 4], label="y [m]")
        return save(fig, path, dpi=50).read_bytes()

    a, b = draw(tmp_path / f"a.{fmt}"), draw(tmp_path / f"b.{fmt}")
    assert a == b
    if fmt == "png":
        assert mpimg.imread(tmp_path / "a.png").shape[:2] == (100, 150)
    elif fmt == "pdf":
        assert a.startswith(b"%PDF-") and a.rstrip().endswith(b"%%EOF")
    else:
        assert ET.parse(tmp_path / "a.svg").getroot().tag == "{http://www.w3.org/2000/svg}svg"


def test_an_unknown_format_is_a_one_line_error_naming_it(tmp_path):
    from experiments.scenarios.formation.figures import closed_loop_figures

    with pytest.raises(ValueError, match=r"^format: must be one of png, pdf, svg, got 'jpg'$"):
        figure_path(tmp_path, "x", "jpg")
    with pytest.raises(ValueError, match=r"^format: .*'eps'$"):
        closed_loop_figures(closed_loop_run(), tmp_path, format="eps")
    assert not any(tmp_path.iterdir())


def test_plot_draws_every_figure_as_pdf(tmp_path):
    from experiments.scenarios.formation.kind import plot

    paths = plot(closed_loop_run(), tmp_path, format="pdf")
    assert len(paths) == 6 and all(p.suffix == ".pdf" and p.read_bytes().startswith(b"%PDF-") for p in paths)


def test_closed_loop_stores_the_filters_sigma_and_truth_points_that_match_the_cloud():
    """σ at the first epoch is the initial covariance (rate σ = σ_ω; EKF attitude σ = 2 σ_q), later
    finite and positive; the truth points lie within a few σ of the reconstructed ones."""
    from experiments.config import load_config
    from experiments.scenarios.formation.closed_loop import closed_loop

    _, cfg = load_config(Path(__file__).resolve().parents[2] / "experiments" / "configs" / "quickstart.toml",
                         overrides={"observation.mode": "geometric", "time.duration_s": 4.0, "time.dt_s": 0.5,
                                    "estimator.convergence_hold_s": 2.0})
    ds, _ = closed_loop(cfg, np.random.SeedSequence(5))
    e = cfg.estimator
    np.testing.assert_allclose(ds["rate_sigma_deg_s"].values[0], e.sigma_omega_deg_s, rtol=1e-9)
    sigma_q = e.sigma_q_known if e.initial_attitude_known else e.sigma_q
    np.testing.assert_allclose(ds["attitude_sigma_deg"].values[0], np.degrees(2 * sigma_q), rtol=1e-6)
    assert np.all(np.isfinite(ds["attitude_sigma_deg"].values)) and np.all(ds["rate_sigma_deg_s"].values > 0)
    ok = ds["snapshot_point_valid"].values & ds["snapshot_track_correct"].values
    miss = np.linalg.norm(ds["snapshot_X_W_m"].values[ok] - ds["snapshot_X_true_H_m"].values[ok], axis=1)
    assert ok.sum() > 20
    assert np.median(miss / ds["snapshot_sigma_m"].values[ok]) < 3.0 and np.median(miss) < 0.1
