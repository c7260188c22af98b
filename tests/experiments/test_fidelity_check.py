"""The fidelity check of issue 16 (experiments.studies.fidelity_check): its ratio interval, its table marks
and one cell of the calibrated geometric mode."""

import numpy as np
import pytest

from experiments.studies.fidelity_check import (
    CheckCell,
    check_cell,
    main,
    markdown_table,
    median_ratio_interval,
    paired_ratio_interval,
    paired_table,
)


def test_ratio_of_medians_is_exact_and_its_interval_holds_it():
    den = np.array([0.2, 0.5, 0.9, 1.3, 2.0, 3.1, 4.4])
    r, lo, hi = median_ratio_interval(2.0 * den, den)
    assert r == pytest.approx(2.0, rel=1e-15) and lo <= 2.0 <= hi
    # non-finite values are dropped; nothing left gives NaN
    r2, _, _ = median_ratio_interval(np.r_[2.0 * den, np.nan, np.inf], den)
    assert r2 == pytest.approx(2.0, rel=1e-15)
    assert all(np.isnan(median_ratio_interval([np.nan], den)))


def test_ninety_percent_interval_covers_equal_medians_about_nine_times_in_ten():
    """Two sets of 20 trials from one log-normal law: the interval of their ratio of medians holds 1 in
    about 90 % of 300 repetitions (percentile bootstrap; between 80 and 99 % accepted)."""
    rng = np.random.default_rng(11)
    hits = 0
    for k in range(300):
        a, b = np.exp(rng.normal(0.0, 0.8, 20)), np.exp(rng.normal(0.0, 0.8, 20))
        _, lo, hi = median_ratio_interval(a, b, seed=k, draws=500)
        hits += lo <= 1.0 <= hi
    assert 0.80 <= hits / 300 <= 0.99


def _result(per_trial: dict) -> dict:
    return {"cells": [{"n_views": 2, "distance_m": 40.0, "axis_angle_deg": 10.0, "per_trial": per_trial}]}


def _trials(values) -> dict:
    v = list(map(float, values))
    return {k: v for k in ("tracks", "ml_step_rms_deg", "ransac_step_rms_deg", "crlb_deg", "ml_failed_steps")}


def test_table_marks_within_25_percent_undecided_and_outside():
    """✓ when the calibrated median is within 25 % of the rendered one; ~ when not but the trials'
    interval reaches into 25 % (few, spread trials); nothing when even the interval is outside."""
    rng = np.random.default_rng(2)
    rendered = _result(_trials(np.exp(rng.normal(0.0, 0.05, 30))))
    fixed = _result(_trials(np.ones(30)))
    close = markdown_table(rendered, fixed, _result(_trials(1.1 * np.exp(rng.normal(0.0, 0.05, 30)))))
    far = markdown_table(rendered, fixed, _result(_trials(3.0 * np.exp(rng.normal(0.0, 0.05, 30)))))
    wide_r = _result(_trials(np.exp(rng.normal(0.0, 1.5, 6))))
    unsure = markdown_table(wide_r, fixed, _result(_trials(1.6 * np.exp(rng.normal(0.0, 1.5, 6)))))
    row = {name: t.splitlines()[2] for name, t in (("close", close), ("far", far), ("unsure", unsure))}
    assert row["close"].count("✓") == 4 and "~" not in row["close"]
    assert "✓" not in row["far"] and "~" not in row["far"]
    assert "✓" not in row["unsure"] and row["unsure"].count("~") == 4


def test_paired_ratio_sees_a_bias_that_the_ratio_of_medians_cannot():
    """The trials share attitudes: a mode at 0.7 of the other in every trial (2 % noise) over trials
    spread by a factor e^0.8.  The paired ratio is 0.7 with an interval within 0.65-0.75 and its table
    marks no cell within 25 %; the ratio of the medians' interval reaches into ±25 % (~)."""
    rng = np.random.default_rng(5)
    base = np.exp(rng.normal(0.0, 0.8, 20))
    cal = 0.7 * base * np.exp(rng.normal(0.0, 0.02, 20))
    r, lo, hi = paired_ratio_interval(cal, base)
    assert r == pytest.approx(0.7, abs=0.02) and 0.65 < lo <= r <= hi < 0.75
    _, mlo, mhi = median_ratio_interval(cal, base)
    assert mlo <= 1.25 and mhi >= 0.75
    table = paired_table(_result(_trials(base)), _result(_trials(cal)))
    assert "✓" not in table.splitlines()[2] and "~" not in table.splitlines()[2]
    assert table.splitlines()[-1] == "within ±25 %: 0; undecided (~): 0; beyond: 4"
    # equal per trial: ratio exactly 1, every metric within; unpaired trials and NaN are dropped
    assert paired_ratio_interval(np.r_[base, 5.0], np.r_[base, np.nan])[:1] == (1.0,)
    assert all(np.isnan(paired_ratio_interval([np.nan], [1.0])))


def test_table_commands_refuse_a_missing_file_and_an_unmatched_cell_with_exit_2(tmp_path, capsys):
    """A result file that is not there, or a geometric cell the rendered file lacks: one line naming
    the option, exit code 2, no table printed."""
    import json

    rendered, other = tmp_path / "r.json", tmp_path / "g.json"
    rendered.write_text(json.dumps(_result(_trials(np.ones(5)))))
    cell = _result(_trials(np.ones(5)))
    cell["cells"][0]["distance_m"] = 80.0
    other.write_text(json.dumps(cell))
    for args in (["--paired-table", str(rendered), str(tmp_path / "none.json")], ["--paired-table", str(rendered), str(other)]):
        with pytest.raises(SystemExit) as exc:
            main(args)
        assert exc.value.code == 2
        out, err = capsys.readouterr()
        assert out == "" and "error: --table/--paired-table: " in err.splitlines()[-1]


def test_a_geometric_cell_is_consistent_with_its_own_noise_model():
    """The calibrated geometric mode draws each keypoint's error with the σ it reports times factors of
    mean 1 over the calibration's points (its surface material's, a heavy-tailed multiplier), so its
    triangulation NEES keeps a mean near 3 (within 15 % over ten thousand points of one cell; the
    cell's surfaces are not the calibration's mix) and has the heavy-tailed shape the calibration
    measured: a median below 0.55 of the mean, where Gaussian errors give 0.69-0.79 (two- and
    three-view points).  Every trial with a few tens of tracks has a bound."""
    res = check_cell(CheckCell(target="fy1", mode="geometric_calibrated", n_views=3, distance_m=40.0,
                               axis_angle_deg=10.0, trials=12, steps=4))
    assert res["nees_points"] > 5000
    assert res["nees_mean"] == pytest.approx(3.0, rel=0.15)
    assert res["nees_median"] < 0.55 * res["nees_mean"]
    p = res["per_trial"]
    tracks, crlb = np.asarray(p["tracks"]), np.asarray(p["crlb_deg"])
    assert len(tracks) == 12 and np.median(tracks) > 20
    assert np.all(np.isfinite(crlb[tracks > 20])) and np.all(crlb[tracks > 20] > 0)
