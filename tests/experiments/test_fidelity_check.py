"""The fidelity check of issue 16 (experiments.studies.fidelity_check): its ratio interval, its table marks
and one cell of the calibrated geometric mode."""

import numpy as np
import pytest

from experiments.studies.fidelity_check import (
    CheckCell,
    check_cell,
    main,
    markdown_table,
    median_interval,
    median_ratio_interval,
    nees_table,
    paired_ratio_interval,
    paired_table,
    pooled_mean_interval,
    split_table,
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


def test_median_interval_has_the_normal_theory_width():
    """400 standard-normal trials: the 90 % bootstrap interval of the median is ±1.645·√(π/2)/√n = ±0.103
    (asymptotic variance of the sample median, π/(2n)) within 25 %, and holds the median; NaN are dropped."""
    x = np.random.default_rng(3).standard_normal(400)
    m, lo, hi = median_interval(np.r_[x, np.nan, np.inf])
    assert m == np.median(x) and lo <= m <= hi
    assert 0.5 * (hi - lo) == pytest.approx(1.645 * np.sqrt(np.pi / 2.0 / 400), rel=0.25)
    assert all(np.isnan(median_interval([np.nan])))


def test_pooled_mean_interval_is_the_mean_of_all_values_with_the_trials_standard_error():
    """400 trials of 50 values each whose trial means are N(3, 0.5²): the pooled mean is the sum over
    the count exactly, and its 90 % interval is ±1.645 · 0.5 / √400 = ±0.041 within 20 % (the
    trials, not the 20 000 values, set it); trials without values are dropped."""
    rng = np.random.default_rng(8)
    means = rng.normal(3.0, 0.5, 400)
    sums, counts = 50.0 * means, np.full(400, 50.0)
    m, lo, hi = pooled_mean_interval(np.r_[sums, 0.0], np.r_[counts, 0.0])
    assert m == pytest.approx(sums.sum() / counts.sum(), rel=1e-12) and lo <= m <= hi
    assert 0.5 * (hi - lo) == pytest.approx(1.645 * 0.5 / np.sqrt(400), rel=0.2)
    assert all(np.isnan(pooled_mean_interval([0.0], [0.0])))


def test_split_table_counts_the_runs_whose_medians_agree_within_25_percent():
    """Three runs of 20 trials with medians 1, 1.1 and 2: of the six ordered pairs only 1.1/1 and 1/1.1
    are within ±25 %, for every metric (8 of 24 in all); a file of fewer than two runs is refused."""
    rng = np.random.default_rng(4)
    runs = [m * np.exp(rng.normal(0.0, 0.01, 20)) for m in (1.0, 1.1, 2.0)]
    runs = [r * m / np.median(r) for r, m in zip(runs, (1.0, 1.1, 2.0), strict=True)]   # exact medians
    table = split_table(_result(_trials(np.concatenate(runs))), size=20)
    row = table.splitlines()[2]
    assert row.count("(2/6)") == 4 and row.startswith("| 2, 40 m, 10° | 3 | 1–2 (2/6) | 1.000–2.000 (2/6)")
    assert table.splitlines()[-1].endswith("in all 8/24")
    # consecutive runs: the trial order is the seed order, so runs of 20 are the 20-trial files' trials
    assert split_table(_result(_trials(np.ones(40))), size=20).splitlines()[-1].endswith("in all 8/8")
    with pytest.raises(ValueError, match="fewer than two runs of size 30"):
        split_table(_result(_trials(np.ones(40))), size=30)
    with pytest.raises(ValueError, match="size must be >= 1"):
        split_table(_result(_trials(np.ones(40))), size=0)


def test_nees_table_marks_an_ml_ratio_whose_interval_reaches_the_band():
    """ML / CRLB median 1.30: no mark when 40 steady trials put its interval above 1.15, ~ when 6 spread
    trials reach into 0.9-1.15, ✓ for a median inside the band."""
    rng = np.random.default_rng(6)

    def row(values):
        v = np.asarray(values, dtype=float)
        cell = {"n_views": 2, "distance_m": 40.0, "axis_angle_deg": 10.0, "nees_points": 10,
                "ml_failed_steps": 0.0, "ml_over_crlb_increment": float(np.median(v)),
                "ml_over_crlb_increment_pooled": float(np.sqrt(np.mean(v**2))),
                "per_trial": {"ml_over_crlb_increment": list(v)}}
        return nees_table([{"target": "fy1", "cells": [cell]}]).splitlines()[2].split(" | ")[6]

    steady = 1.3 * np.exp(rng.normal(0.0, 0.02, 40))
    spread = 1.3 * np.exp(rng.normal(0.0, 0.6, 6))
    assert row(steady / np.median(steady) * 1.3).startswith("1.30 [1.") and "✓" not in row(steady) and "~" not in row(steady)
    assert "~" in row(spread / np.median(spread) * 1.3)
    assert "✓" in row(np.full(5, 1.0))


def test_nees_table_gives_a_mean_nees_outside_ten_percent_its_interval_over_the_trials():
    """Mean NEES 2.5 (outside 2.7-3.3): with trials spread as N(2.5, 1²) over 10 trials its interval
    reaches 2.7 (~); over 400 steady trials (N(2.5, 0.1²)) it does not (no mark)."""
    rng = np.random.default_rng(9)

    def cell(trial_means):
        m = np.asarray(trial_means, dtype=float)
        m = m - m.mean() + 2.5
        return {"n_views": 2, "distance_m": 80.0, "axis_angle_deg": 10.0, "nees_points": 10 * m.size,
                "nees_mean": 2.5, "nees_median": 1.0, "ml_failed_steps": 0.0,
                "per_trial": {"trial_nees_sum": list(10.0 * m), "trial_nees_count": [10.0] * m.size}}

    def col(c):
        return nees_table([{"target": "fy1", "cells": [c]}]).splitlines()[2].split(" | ")[5]

    spread, steady = col(cell(rng.normal(2.5, 1.0, 10))), col(cell(rng.normal(2.5, 0.1, 400)))
    assert spread.startswith("2.50 / 1.00 [") and spread.endswith("~")
    assert steady.startswith("2.50 / 1.00 [2.4") and "~" not in steady and "✓" not in steady


def test_table_commands_refuse_a_missing_file_and_an_unmatched_cell_with_exit_2(tmp_path, capsys):
    """A result file that is not there, or a geometric cell the rendered file lacks, or a file too short
    to split, or a run size below one trial: one line naming the option, exit code 2, no table printed."""
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
        assert out == "" and "error: --paired-table: " in err.splitlines()[-1]
    # --split-table: a file of one run of 20 trials, and a run size below one trial
    for args, named in ((["--split-table", str(rendered)], "--split-table: "),
                        (["--split-table", str(rendered), "--split-size", "0"], "--split-size: ")):
        with pytest.raises(SystemExit) as exc:
            main(args)
        assert exc.value.code == 2
        out, err = capsys.readouterr()
        assert out == "" and f"error: {named}" in err.splitlines()[-1]


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
