"""The ``coobs`` command line over the Python API: run by name with ``--set`` and a default folder,
results as a table with units, ``--version``, strict ``summary.json``, and ``coobs plot`` of every
kind of output folder (run, sweep, filter study).

Each output is checked against another path to the same answer: the table's rows against
``summary.json`` read back by ``json``, the redrawn figures against the bytes first drawn, the run
against :func:`coobs.run` with the same overrides.
"""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import pytest
from rich.console import Console
from typer.testing import CliRunner

import coobs
from coobs.cli import app
from coobs.cli._table import split_unit, summary_rows, summary_table
from experiments.results import strict_json, summary_json

runner = CliRunner()
SMALL_SET = ["--set", "observation.mode=geometric", "--set", "time.duration_s=4.0",
             "--set", "estimator.convergence_hold_s=1.0"]
SMALL = {"observation.mode": "geometric", "time.duration_s": 4.0, "estimator.convergence_hold_s": 1.0}


def _refuse_nan(constant: str) -> None:
    raise AssertionError(f"summary.json holds {constant}, which strict JSON has not")


def _strict_load(path: Path) -> dict:
    return json.loads(path.read_text(), parse_constant=_refuse_nan)


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """``coobs run quickstart`` with the small overrides, run in an empty folder (default --out)."""
    cwd = tmp_path_factory.mktemp("cwd")
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(cwd)
        res = runner.invoke(app, ["run", "quickstart", *SMALL_SET, "--no-figures"])
    return cwd, res


def test_run_by_name_writes_into_runs_slash_the_name_by_default(quick_run):
    cwd, res = quick_run
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in (cwd / "runs" / "quickstart").iterdir()) == ["result.nc", "summary.json"]
    assert "results: runs/quickstart/result.nc, runs/quickstart/summary.json" in res.output


def test_run_with_set_gives_the_summary_of_the_api_with_the_same_overrides(quick_run):
    cwd, _ = quick_run
    stored = _strict_load(cwd / "runs" / "quickstart" / "summary.json")
    api = coobs.run("quickstart", overrides=SMALL, progress=False).summary
    assert stored == json.loads(summary_json(api))
    assert stored["observation_mode"] == "geometric" and stored["epochs"] == 5


def test_run_prints_every_summary_entry_as_a_row_with_its_unit_uncut(quick_run):
    cwd, res = quick_run
    summary = _strict_load(cwd / "runs" / "quickstart" / "summary.json")
    assert "…" not in res.output
    lines = res.output.splitlines()
    for key, value in summary.items():
        name, unit = split_unit(key)
        row = next((line for line in lines if f"│ {name} " in line), None)
        assert row is not None, key
        cells = [c.strip() for c in row.strip("│").split("│")]
        assert cells[0] == name and cells[2] == unit
        if isinstance(value, float):
            assert math.isclose(float(cells[1]), value, rel_tol=1e-5)
    assert split_unit("final_rms_attitude_error_deg") == ("final_rms_attitude_error", "deg")
    assert split_unit("final_rms_rate_error_deg_s") == ("final_rms_rate_error", "deg/s")


@pytest.mark.parametrize(("key", "expected"), [
    ("crossing_time_s", ("crossing_time", "s")),
    ("median_solve_time_us", ("median_solve_time", "µs")),
    ("rms_position_error_mm_plane", ("rms_position_error_plane", "mm")),
    ("relative_speed_m_s", ("relative_speed", "m/s")),
    ("reprojection_rms_px", ("reprojection_rms", "px")),
    ("n_failed", ("n_failed", "")),
    ("max_rel_error_60s", ("max_rel_error_60s", "")),
    ("s", ("s", "")),
])
def test_split_unit_reads_the_unit_from_the_key_suffix(key, expected):
    assert split_unit(key) == expected


def test_nested_summaries_flatten_to_paths_with_the_innermost_unit_and_fit_80_columns():
    summary = {"study": "ekf", "cases": {"3 views window": {"median_convergence_time_s": 2.4,
                                                           "final_rms_rate_error_deg_s": 0.00415, "n_failed": 0}},
               "solvers": {"switching": {"first_failure_s": None, "along_los_m": {"rms": 0.0975}}},
               "table1_axis_rms_mm": [0.021, 0.026], "reconfiguration": {}}
    rows = summary_rows(summary)
    assert rows == [("study", "ekf", ""),
                    ("cases / 3 views window / median_convergence_time", "2.4", "s"),
                    ("cases / 3 views window / final_rms_rate_error", "0.00415", "deg/s"),
                    ("cases / 3 views window / n_failed", "0", ""),
                    ("solvers / switching / first_failure", "-", "s"),
                    ("solvers / switching / along_los / rms", "0.0975", "m"),
                    ("table1_axis_rms", "0.021, 0.026", "mm"),
                    ("reconfiguration", "(none)", "")]
    console = Console(width=80, record=True, file=io.StringIO())
    console.print(summary_table(summary))
    text = console.export_text()
    assert "…" not in text and "3 views window" in text and "deg/s" in text


def test_version_option_prints_the_distribution_version():
    res = runner.invoke(app, ["--version"])
    assert res.exit_code == 0
    assert res.output.strip() == f"coobs {coobs.__version__}"


@pytest.mark.parametrize(("args", "message"), [
    (["run", "quickstart", "--set", "formation.n_views"], "--set: expected KEY=VALUE"),
    (["run", "quickstart", "--set", "formation.n_views=0"], "formation.n_views: "),
    (["run", "no_such_config"], "config: no file and no bundled config named 'no_such_config'"),
    (["run", "configs/no_such_file.toml"], "config: file not found: 'configs/no_such_file.toml'"),
])
def test_run_bad_name_or_set_exits_2_in_one_line_and_writes_nothing(tmp_path, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    res = runner.invoke(app, args)
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {message}"), res.output
    assert list(tmp_path.iterdir()) == []


def test_strict_json_writes_null_for_nan_and_infinity_and_plain_numbers_for_numpy():
    np = pytest.importorskip("numpy")
    value = {"a": float("nan"), "b": [np.float64("inf"), np.int64(3)], "c": np.array([1.5, np.nan]),
             "d": (np.bool_(True), -math.inf), "e": {"f": Path("x")}}
    assert strict_json(value) == {"a": None, "b": [None, 3], "c": [1.5, None], "d": [True, None], "e": {"f": "x"}}
    assert json.loads(summary_json(value), parse_constant=_refuse_nan)["c"] == [1.5, None]


def test_a_quick_sweep_writes_a_strict_summary(tmp_path):
    coobs.sweep("003_fig5_fig6", out=tmp_path / "s", processes=False, progress=False,
                overrides={"sweep.trials": 2, "error_map.filter_runs": 0, "error_map.steps": 3,
                           "sweep.grid": {"formation.distance_m": [40], "formation.n_views": [2, 3]}})
    summary = _strict_load(tmp_path / "s" / "summary.json")
    assert summary["cells_done"] == summary["cells"] == 2


@pytest.fixture(scope="module")
def filter_study(tmp_path_factory):
    out = tmp_path_factory.mktemp("fs") / "filter_study"
    res = runner.invoke(app, ["filter-study", "--only", "expbc", "--only", "increments", "--trials", "2",
                              "--out", str(out)])
    return out, res


def test_filter_study_tables_carry_units_in_headers_that_are_not_cut(filter_study):
    _, res = filter_study
    assert res.exit_code == 0, res.output
    assert "…" not in res.output
    text = " ".join(res.output.split())
    for header in ("[s]", "[deg]", "[deg/s]", "converged", "fraction"):
        assert header in text, header


def test_filter_study_summary_is_strict_json_with_null_for_the_unconverged(filter_study):
    out, _ = filter_study
    summary = _strict_load(out / "summary.json")
    assert summary["trials"] == 2 and set(summary) >= {"expbc", "increments"}


def test_plot_redraws_a_filter_study_folder_to_the_same_bytes(filter_study):
    out, _ = filter_study
    first = {p.name: p.read_bytes() for p in (out / "figures").glob("*.png")}
    assert sorted(first) == ["expbc.png", "expbc_nees.png", "increments_nees.png"]
    for p in (out / "figures").glob("*.png"):
        p.unlink()
    res = runner.invoke(app, ["plot", str(out)])
    assert res.exit_code == 0, res.output
    assert {p.name: p.read_bytes() for p in (out / "figures").glob("*.png")} == first
    assert [Path(p).name for p in coobs.plot(out, out / "svg", format="svg")] == [
        "expbc.svg", "expbc_nees.svg", "increments_nees.svg"]


def test_plot_redraws_a_run_folder_and_refuses_a_folder_without_results(quick_run, tmp_path):
    cwd, _ = quick_run
    res = runner.invoke(app, ["plot", str(cwd / "runs" / "quickstart")])
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in (cwd / "runs" / "quickstart" / "figures").glob("*.png"))
    res = runner.invoke(app, ["plot", str(tmp_path)])
    assert res.exit_code == 2 and res.output.startswith("error: out: no result.nc or sweep.zarr in ")
