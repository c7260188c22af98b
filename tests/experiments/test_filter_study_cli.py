"""``coobs filter-study``: a small run writes its summary; bad options exit with code 2."""

import json

from typer.testing import CliRunner

from coobs.cli import app

runner = CliRunner()


def test_filter_study_robust_writes_summary_with_outlier_counts(tmp_path):
    res = runner.invoke(app, ["filter-study", "--only", "robust", "--trials", "3", "--no-figures",
                              "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    s = json.loads((tmp_path / "summary.json").read_text())
    row = s["robust"]["MEKF"]
    assert row["n_trials"] == 3
    assert abs(row["missing_fraction_measured"] - 0.2) < 0.01
    assert row["n_rejected"] >= 0.9 * row["n_outliers"] > 0


def test_filter_study_rejects_unknown_study_with_exit_code_2(tmp_path):
    res = runner.invoke(app, ["filter-study", "--only", "nope", "--out", str(tmp_path)])
    assert res.exit_code == 2
    assert "--only" in res.output
    assert not (tmp_path / "summary.json").exists()
