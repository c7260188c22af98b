"""The coobs CLI skeleton: help, version, bench table and JSON, bad input exits with code 2."""

import json

from typer.testing import CliRunner

from coobs.cli import app

runner = CliRunner()


def test_help_lists_the_commands():
    res = runner.invoke(app, ["--help"])
    assert res.exit_code == 0
    for cmd in ("version", "bench", "run", "plot", "tumble"):
        assert cmd in res.output


def test_version_reports_coobs_and_peer_libraries():
    res = runner.invoke(app, ["version"])
    assert res.exit_code == 0
    assert "coobs 0.1.0" in res.output and "open3d" in res.output


def test_bench_attitude_writes_rows_with_ratios(tmp_path):
    out = tmp_path / "bench.json"
    res = runner.invoke(app, ["bench", "--only", "attitude", "--quick", "--out", str(out)])
    assert res.exit_code == 0, res.output
    rows = json.loads(out.read_text())
    assert {r["benchmark"].split(",")[0] for r in rows} == {"quaternion product", "torque-free propagation"}
    for r in rows:
        assert r["figure"] > 0 and r["peer_figure"] > 0
        assert abs(r["ratio"] - r["figure"] / r["peer_figure"]) < 1e-9 * r["ratio"]


def test_bench_unknown_topic_exits_2_naming_the_option(tmp_path):
    res = runner.invoke(app, ["bench", "--only", "nope", "--out", str(tmp_path / "b.json")])
    assert res.exit_code == 2
    assert "--only" in res.output
    assert not (tmp_path / "b.json").exists()


def test_tumble_bad_inertia_exits_2_naming_the_option():
    res = runner.invoke(app, ["tumble", "--inertia-kgm2", "1,1,5"])
    assert res.exit_code == 2
    assert "--inertia-kgm2" in res.output and "triangle inequality" in res.output


def test_tumble_conserves_momentum_in_its_report():
    res = runner.invoke(app, ["tumble", "--duration-s", "60", "--step-s", "30"])
    assert res.exit_code == 0
    drift = float(res.output.split("|L_N| drift: ")[1].split(" ")[0])
    assert drift < 1e-12


def test_figures_unknown_topic_exits_2_naming_the_argument(tmp_path):
    res = runner.invoke(app, ["figures", "nope", "--out", str(tmp_path)])
    assert res.exit_code == 2
    assert "topic" in res.output and "orbits" in res.output
    assert not any(tmp_path.iterdir())
