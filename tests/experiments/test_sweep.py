"""The sweep engine on a real cell (attitude noise statistics, closed forms known): Dask, zarr, resume."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from experiments.studies.noise_calibration import ATTITUDE_NOISE_CELL
from experiments.sweep import cell_seed_sequences, open_sweep, redraw, run_sweep, sweep_summary

REPO = Path(__file__).resolve().parents[2]
# -1° is an invalid noise level: that cell must become failure rows, not stop the sweep
GRID = {"angle_error_deg": [-1.0, 0.2, 0.4, 0.6, 0.8, 1.0], "samples": [20_000, 40_000]}
TRIALS = 3
SEED = 11


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> xr.Dataset:
    """The whole grid on one Dask worker, uninterrupted."""
    out = tmp_path_factory.mktemp("ref")
    report = run_sweep(ATTITUDE_NOISE_CELL, GRID, trials=TRIALS, out=out, seed=SEED, workers=1)
    assert report.n_computed == 12 and report.n_cells == 12
    return open_sweep(out)


def test_sweep_metrics_match_closed_form_maxwell_statistics(reference):
    good = reference.sel(angle_error_deg=[0.2, 0.4, 0.6, 0.8, 1.0])
    # RMS of the error angle is e; 20 000 samples give a relative std of sqrt(6)/(2*3*sqrt(n)) < 0.3 %
    rel = good.rms_angle_deg / good.expected_rms_deg - 1.0
    assert float(np.abs(rel).max()) < 0.02
    rel_mean = good.mean_angle_deg / good.expected_mean_deg - 1.0
    assert float(np.abs(rel_mean).max()) < 0.02
    np.testing.assert_allclose(good.expected_mean_deg.sel(samples=20_000).values,
                               np.array([0.2, 0.4, 0.6, 0.8, 1.0]) / np.sqrt(3) * np.sqrt(8 / np.pi), rtol=1e-12)


def test_sweep_dataset_layout_units_and_failure_rows(reference):
    ds = reference
    assert list(ds["done"].dims) == ["angle_error_deg", "samples"]
    assert ds.rms_angle_deg.dims == ("angle_error_deg", "samples", "trial")
    assert ds.expected_rms_deg.dims == ("angle_error_deg", "samples")
    assert ds.rms_angle_deg.attrs["units"] == "deg"
    assert ds["angle_error_deg"].attrs["config_key"] == "angle_error_deg"
    assert bool(ds["done"].all())
    bad = ds.sel(angle_error_deg=-1.0)
    assert bool(bad.rms_angle_deg.isnull().all()) and bool(bad.expected_rms_deg.isnull().all())
    reasons = set(bad.failure_reason.values.ravel().tolist())
    assert len(reasons) == 1 and next(iter(reasons)).startswith("ValueError: angle_error_deg")
    assert set(ds.sel(angle_error_deg=0.2).failure_reason.values.ravel().tolist()) == {""}
    summary = sweep_summary(ds)
    assert summary["cells_done"] == 12 and summary["trials_failed"] == 2 * TRIALS
    json.dumps(summary)


def test_trial_seeds_depend_only_on_seed_cell_values_and_trial_number():
    a = cell_seed_sequences(5, {"x": 1.0, "y": 2}, 3)
    b = cell_seed_sequences(5, {"y": 2, "x": 1.0}, 5)  # key order and trial count do not matter
    for s, t in zip(a, b[:3], strict=True):
        assert np.array_equal(s.generate_state(4), t.generate_state(4))
    c = cell_seed_sequences(5, {"x": 1.5, "y": 2}, 3)
    assert not np.array_equal(a[0].generate_state(4), c[0].generate_state(4))
    assert not np.array_equal(a[0].generate_state(4), a[1].generate_state(4))


@pytest.mark.slow
def test_one_and_two_workers_give_identical_datasets(reference, tmp_path):
    report = run_sweep(ATTITUDE_NOISE_CELL, GRID, trials=TRIALS, out=tmp_path, seed=SEED, workers=2)
    assert report.workers == 2
    xr.testing.assert_identical(open_sweep(tmp_path), reference)
    # a second run resumes: nothing left to compute, nothing changes
    again = run_sweep(ATTITUDE_NOISE_CELL, GRID, trials=TRIALS, out=tmp_path, seed=SEED, workers=2)
    assert again.n_computed == 0
    xr.testing.assert_identical(open_sweep(tmp_path), reference)


def test_existing_store_of_another_sweep_is_refused_and_left_untouched(reference, tmp_path):
    grid = {"angle_error_deg": [0.2], "samples": [100]}
    run_sweep(ATTITUDE_NOISE_CELL, grid, trials=2, out=tmp_path, seed=1, workers=1, processes=False)
    before = open_sweep(tmp_path)
    with pytest.raises(ValueError, match="out: .* holds a different sweep"):
        run_sweep(ATTITUDE_NOISE_CELL, grid, trials=3, out=tmp_path, seed=1, workers=1, processes=False)
    xr.testing.assert_identical(open_sweep(tmp_path), before)


def test_bad_arguments_raise_value_error_naming_them(tmp_path):
    with pytest.raises(ValueError, match="trials"):
        run_sweep(ATTITUDE_NOISE_CELL, GRID, trials=0, out=tmp_path)
    with pytest.raises(ValueError, match="grid.samples"):
        run_sweep(ATTITUDE_NOISE_CELL, {"angle_error_deg": [0.1], "samples": []}, trials=1, out=tmp_path)
    with pytest.raises(ValueError, match="not unique"):
        run_sweep(ATTITUDE_NOISE_CELL, {"a.samples": [1], "samples": [2]}, trials=1, out=tmp_path)
    assert not (tmp_path / "sweep.zarr").exists()


_KILLED_SCRIPT = textwrap.dedent(
    """
    import dataclasses
    import sys
    import time
    from experiments.studies.noise_calibration import ATTITUDE_NOISE_CELL
    from experiments.sweep import run_sweep


    def slow(cell_input, seeds):
        # the same numbers, 0.3 s later: on an idle machine the 12 cells can otherwise all finish
        # between the test's last look at the store and the kill
        time.sleep(0.3)
        return ATTITUDE_NOISE_CELL.fn(cell_input, seeds)


    if __name__ == "__main__":
        cell = dataclasses.replace(ATTITUDE_NOISE_CELL, fn=slow)  # same name: the same fingerprint
        run_sweep(cell, {grid!r}, trials={trials}, out=sys.argv[1], seed={seed}, workers=1)
    """
)


def _done_count(store: Path) -> int:
    try:
        with xr.open_zarr(store, consolidated=False) as ds:
            return int(ds["done"].values.sum())
    except Exception:  # the store does not exist yet
        return 0


def test_sigkill_halfway_then_restart_gives_identical_dataset_and_recomputes_no_finished_cell(reference, tmp_path):
    script = tmp_path / "sweep_script.py"
    script.write_text(_KILLED_SCRIPT.format(grid=GRID, trials=TRIALS, seed=SEED))
    out = tmp_path / "out"
    store = out / "sweep.zarr"
    proc = subprocess.Popen([sys.executable, str(script), str(out)], cwd=REPO, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while _done_count(store) < 4 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert proc.poll() is None, "the sweep finished before it could be killed"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        try:  # the Dask worker processes this sweep started (same session)
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    done = open_sweep(out)["done"].values
    n_done = int(done.sum())
    assert 4 <= n_done < 12
    chunk_mtimes = {p: p.stat().st_mtime_ns for p in (store / "rms_angle_deg" / "c").rglob("*") if p.is_file()}
    # resume on thread workers: the stored numbers may not depend on the kind of worker either
    report = run_sweep(ATTITUDE_NOISE_CELL, GRID, trials=TRIALS, out=out, seed=SEED, workers=2, processes=False)
    assert report.n_computed == 12 - n_done
    # the finished cells' chunks were not written again
    flat = np.flatnonzero(done.ravel())
    finished = {f"{i // 2}/{i % 2}/0" for i in flat}
    rewritten = [p for p, m in chunk_mtimes.items()
                 if p.relative_to(store / "rms_angle_deg" / "c").as_posix() in finished and p.stat().st_mtime_ns != m]
    assert rewritten == []
    xr.testing.assert_identical(open_sweep(out), reference)


def test_redraw_draws_figures_from_the_stored_sweep_only(reference, tmp_path):
    store = tmp_path / "sweep.zarr"
    reference.to_zarr(store, consolidated=False)
    paths = redraw(tmp_path)
    names = sorted(p.name for p in paths)
    assert names == ["sweep_expected_mean_deg.png", "sweep_expected_rms_deg.png",
                     "sweep_mean_angle_deg.png", "sweep_rms_angle_deg.png"]
    assert all(p.stat().st_size > 5_000 for p in paths)


def test_common_random_numbers_give_every_cell_the_same_draws(tmp_path):
    """seed_keys=[]: the noise draws do not depend on the cell, so the error angle scales exactly
    with e (the perturbation is linear in σ = e/√3 for the same normal draws)."""
    grid = {"angle_error_deg": [0.5, 1.0], "samples": [500]}
    run_sweep(ATTITUDE_NOISE_CELL, grid, trials=2, out=tmp_path / "crn", seed=4, seed_keys=[], workers=1,
              processes=False)
    crn = open_sweep(tmp_path / "crn").rms_angle_deg
    np.testing.assert_allclose(crn.sel(angle_error_deg=1.0).values, 2 * crn.sel(angle_error_deg=0.5).values,
                               rtol=1e-6)
    run_sweep(ATTITUDE_NOISE_CELL, grid, trials=2, out=tmp_path / "ind", seed=4, workers=1, processes=False)
    ind = open_sweep(tmp_path / "ind").rms_angle_deg
    assert not np.allclose(ind.sel(angle_error_deg=1.0).values, 2 * ind.sel(angle_error_deg=0.5).values,
                           rtol=1e-6)


def test_sweep_on_an_external_scheduler_address_gives_the_reference_dataset(reference, tmp_path):
    """--scheduler ADDRESS: the same sweep on a cluster the caller started (here an in-process one)."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address="127.0.0.1:0") as cluster:
        report = run_sweep(ATTITUDE_NOISE_CELL, GRID, trials=TRIALS, out=tmp_path, seed=SEED,
                           scheduler=cluster.scheduler_address)
    assert report.workers == 2 and report.n_computed == 12
    xr.testing.assert_identical(open_sweep(tmp_path), reference)
