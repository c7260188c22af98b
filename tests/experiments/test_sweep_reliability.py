"""Sweeps that survive worker deaths and refuse, before any work, what they cannot run.

The worker-death tests run a real ``coobs sweep`` in a subprocess and SIGKILL every Dask worker
process (the nanny's children) while cells are running, then open the zarr store: no cell may be
marked done without the metrics its task computed, and the finished dataset must equal an
uninterrupted run's.
"""

from __future__ import annotations

import functools
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import psutil
import pytest
import xarray as xr
from typer.testing import CliRunner

from coobs.cli import app
from experiments.studies.noise_calibration import ATTITUDE_NOISE_CELL
from experiments.sweep import Metric, SweepCell, open_sweep, run_sweep

REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / "experiments" / "configs" / "003_fig5_fig6.toml"
# six cells of Experiment A, a few trials each: about half a second per cell on one core
SMALL = ["--set", "sweep.trials=3", "--set", "error_map.filter_runs=0", "--set", "error_map.steps=4",
         "--set", 'sweep.grid={"formation.distance_m"=[30,50,70],"formation.n_views"=[2,3]}', "--no-figures"]
runner = CliRunner()


def _free_port() -> int:
    """A loopback port nothing listens on (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _done_count(store: Path) -> int:
    try:
        with xr.open_zarr(store, consolidated=False) as ds:
            return int(ds["done"].values.sum())
    except Exception:  # noqa: BLE001 - the store does not exist yet
        return 0


def _worker_processes(pid: int) -> list[psutil.Process]:
    """The Dask worker processes of a ``coobs sweep``: its multiprocessing children (not the tracker)."""
    try:
        kids = psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []
    return [k for k in kids if "spawn_main" in " ".join(k.cmdline())]


def _sweep_killing_every_worker_once(out: Path, workers: int, *extra: str,
                                     env: dict[str, str] | None = None) -> tuple[int, str, int]:
    """Run ``coobs sweep`` in a subprocess; SIGKILL all its workers once the first cell is done.

    Returns ``(exit code, stderr, workers killed)``.
    """
    cmd = [sys.executable, "-m", "coobs", "sweep", str(CONFIG), "--out", str(out),
           "--workers", str(workers), *SMALL, *extra]
    proc = subprocess.Popen(cmd, cwd=REPO, env={**os.environ, **(env or {})}, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while _done_count(out / "sweep.zarr") < 1 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert proc.poll() is None, "the sweep finished before its workers could be killed"
        victims = _worker_processes(proc.pid)
        for w in victims:
            w.send_signal(signal.SIGKILL)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    return proc.returncode, err, len(victims)


def _assert_no_cell_done_without_metrics(ds: xr.Dataset, reference: xr.Dataset) -> None:
    done = ds["done"].values.astype(bool)
    metric = ds["e_dtheta_deg"].values  # shape (distance, views, trial, ...): finite for every good trial
    good = ds["failure_reason"].values == ""
    finite = np.isfinite(metric.reshape(*good.shape, -1)).all(axis=-1)
    assert (finite | ~good)[done].all()
    # a done cell holds the uninterrupted run's rows, its recorded trial failures included (a trial
    # whose every step the evidence checks refuse is a result, not a lost cell)
    assert (ds["failure_reason"].values[done] == reference["failure_reason"].values[done]).all()
    np.testing.assert_array_equal(metric[done], reference["e_dtheta_deg"].values[done])
    assert np.isnan(metric[~done]).all()  # an undone cell keeps the store's NaN


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> xr.Dataset:
    """The small sweep, uninterrupted, on one worker."""
    out = tmp_path_factory.mktemp("reference")
    res = runner.invoke(app, ["sweep", str(CONFIG), "--out", str(out), "--workers", "1", *SMALL])
    assert res.exit_code == 0, res.output
    assert "dashboard: http://127.0.0.1:" in res.output  # printed, on loopback
    return open_sweep(out)


@pytest.mark.slow
@pytest.mark.parametrize("workers", [1])  # the only worker: issue 17's case (2 workers: measured in the note)
def test_killing_every_worker_mid_sweep_reruns_their_cells_and_gives_the_uninterrupted_dataset(
        reference, tmp_path, workers):
    """The nannies restart the killed workers and Dask reruns the lost tasks (each cell travels with
    its task): the command completes, exit 0, with the uninterrupted run's numbers."""
    rc, err, killed = _sweep_killing_every_worker_once(tmp_path, workers)
    assert killed == workers
    assert rc == 0, err
    xr.testing.assert_identical(open_sweep(tmp_path), reference)


@pytest.mark.slow
@pytest.mark.parametrize("workers", [2])  # every worker of two (one: measured in the note)
def test_cells_lost_beyond_the_retry_bound_stay_undone_exit_3_and_the_rerun_completes_them(
        reference, tmp_path, workers):
    """No rescheduling allowed (allowed-failures 0, --retries 0): the killed tasks' cells stay undone,
    never recorded as results; the command says how many and exits 3; the same command completes them."""
    rc, err, killed = _sweep_killing_every_worker_once(
        tmp_path, workers, "--retries", "0", env={"DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": "0"})
    assert killed == workers
    assert rc == 3, err
    ds = open_sweep(tmp_path)
    n_undone = int((~ds["done"].values).sum())
    assert 1 <= n_undone < 6
    _assert_no_cell_done_without_metrics(ds, reference)
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"error: {n_undone} of 6 cells not done (KilledWorker")
    assert "run the same command again" in last
    res = runner.invoke(app, ["sweep", str(CONFIG), "--out", str(tmp_path), "--workers", "1", *SMALL])
    assert res.exit_code == 0, res.output
    xr.testing.assert_identical(open_sweep(tmp_path), reference)


def _poisoned_fn(params: dict, seeds: list, *, marker_dir: str) -> dict:
    """A cell that kills its own worker (SIGKILL) at ``x == 2`` while ``marker_dir/poison`` exists,
    counting each attempt in ``marker_dir/attempts``; otherwise one standard normal per trial."""
    marker = Path(marker_dir)
    if params["x"] == 2 and (marker / "poison").exists():
        with open(marker / "attempts", "a") as f:
            f.write("x\n")
        os.kill(os.getpid(), signal.SIGKILL)
    draws = [np.random.default_rng(s).standard_normal() for s in seeds]
    return {"draw": np.asarray(draws) + params["x"]}


@pytest.mark.slow
def test_a_cell_that_kills_its_worker_is_resubmitted_retries_times_then_left_undone(tmp_path):
    """No rescheduling by Dask (allowed-failures 0), one resubmission: the poisoned cell runs exactly
    twice, is never written, and takes no other cell down (one task at a time per worker)."""
    import dask
    import distributed  # noqa: F401 - its config defaults must exist before dask.config.set

    cell = SweepCell(functools.partial(_poisoned_fn, marker_dir=str(tmp_path)), {"draw": Metric("1")},
                     name="poisoned")
    (tmp_path / "poison").touch()
    grid = {"x": [1, 2, 3]}
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        report = run_sweep(cell, grid, trials=2, out=tmp_path / "a", seed=3, workers=1, retries=1)
    assert (tmp_path / "attempts").read_text().count("x") == 2  # first try and one resubmission
    assert report.n_undone == 1 and report.n_computed == 2
    assert report.undone_reason.startswith("KilledWorker")
    ds = open_sweep(tmp_path / "a")
    assert ds["done"].values.tolist() == [True, False, True]
    assert np.isnan(ds["draw"].sel(x=2).values).all() and set(ds["failure_reason"].values.ravel()) == {""}
    (tmp_path / "poison").unlink()
    again = run_sweep(cell, grid, trials=2, out=tmp_path / "a", seed=3, workers=1, processes=False)
    assert again.n_computed == 1 and again.n_undone == 0
    run_sweep(cell, grid, trials=2, out=tmp_path / "b", seed=3, workers=1, processes=False)
    xr.testing.assert_identical(open_sweep(tmp_path / "a"), open_sweep(tmp_path / "b"))


GRID = {"angle_error_deg": [0.2, 0.4], "samples": [100]}


def test_a_cluster_without_workers_ends_the_sweep_with_every_cell_undone_and_the_store_resumable(tmp_path):
    from distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=False, dashboard_address="127.0.0.1:0") as empty:
        t0 = time.monotonic()
        report = run_sweep(ATTITUDE_NOISE_CELL, GRID, trials=2, out=tmp_path / "a", seed=5,
                           scheduler=empty.scheduler_address, no_worker_timeout_s=1.0)
    assert time.monotonic() - t0 < 5.0
    assert report.n_undone == 2 and report.n_computed == 0
    assert report.undone_reason == "no Dask worker for 1 s"
    assert not open_sweep(tmp_path / "a")["done"].values.any()
    run_sweep(ATTITUDE_NOISE_CELL, GRID, trials=2, out=tmp_path / "a", seed=5, processes=False)
    run_sweep(ATTITUDE_NOISE_CELL, GRID, trials=2, out=tmp_path / "b", seed=5, processes=False)
    xr.testing.assert_identical(open_sweep(tmp_path / "a"), open_sweep(tmp_path / "b"))


def test_unreachable_scheduler_is_a_value_error_within_the_timeout_and_leaves_nothing(tmp_path):
    address = f"tcp://127.0.0.1:{_free_port()}"
    t0 = time.monotonic()
    with pytest.raises(ValueError, match=r"^scheduler: cannot connect to tcp://127\.0\.0\.1:\d+ "
                                         r"\(no Dask scheduler answered within 1 s\)$"):
        run_sweep(ATTITUDE_NOISE_CELL, GRID, trials=2, out=tmp_path / "out", scheduler=address,
                  connect_timeout_s=1.0)
    assert time.monotonic() - t0 < 4.0
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_cli_unreachable_scheduler_is_one_line_exit_2_within_10_s_and_leaves_nothing(tmp_path):
    t0 = time.monotonic()
    res = runner.invoke(app, ["sweep", str(CONFIG), "--out", str(tmp_path / "out"),
                              "--scheduler", f"tcp://127.0.0.1:{_free_port()}", *SMALL])
    assert time.monotonic() - t0 < 10.0
    assert res.exit_code == 2
    assert res.output.strip().startswith("error: --scheduler: cannot connect to tcp://127.0.0.1:")
    assert len(res.output.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("case", ["existing file", "under a file", pytest.param(
    "proc", marks=pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="no /proc file system"))])
def test_out_that_cannot_hold_a_sweep_is_refused_before_connecting_and_nothing_is_written(tmp_path, case):
    """Checked before the (unreachable) scheduler is even tried, so the error is about ``out``, at once.

    ``/proc`` refuses a new directory even to root (``chmod`` would not stop root)."""
    (tmp_path / "file").write_text("keep me")
    out = {"existing file": tmp_path / "file", "under a file": tmp_path / "file" / "sub",
           "proc": Path("/proc/coobs_test")}[case]
    t0 = time.monotonic()
    with pytest.raises(ValueError, match=r"^out: .*(is a file|is not writable)"):
        run_sweep(ATTITUDE_NOISE_CELL, GRID, trials=2, out=out, scheduler=f"tcp://127.0.0.1:{_free_port()}",
                  connect_timeout_s=3.0)
    assert time.monotonic() - t0 < 1.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]
    assert (tmp_path / "file").read_text() == "keep me"
    assert not (out / "sweep.zarr").exists()


def test_cli_out_file_another_sweep_or_a_run_folder_is_one_line_exit_2_before_any_work(tmp_path):
    (tmp_path / "file").write_text("")
    other = tmp_path / "other"
    run_sweep(ATTITUDE_NOISE_CELL, GRID, trials=2, out=other, seed=1, processes=False)
    run_folder = tmp_path / "run"
    run_folder.mkdir()
    (run_folder / "result.nc").write_bytes(b"")
    unreachable = ["--scheduler", f"tcp://127.0.0.1:{_free_port()}"]
    for out, message in ((tmp_path / "file", "is a file, not a directory"),
                         (other, "holds a different sweep"),
                         (run_folder, "holds the results of a `coobs run`")):
        t0 = time.monotonic()
        res = runner.invoke(app, ["sweep", str(CONFIG), "--out", str(out), *unreachable, *SMALL])
        assert time.monotonic() - t0 < 3.0, out
        assert res.exit_code == 2, res.output
        lines = res.output.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: --out: ") and message in lines[0], lines
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "other", "run"]


@pytest.mark.parametrize("address", ["foo", "127.0.0.1:99999", "127.0.0.1:", 8787])
def test_malformed_dashboard_address_is_a_value_error_naming_it(tmp_path, address):
    with pytest.raises(ValueError, match=r"^dashboard_address: expected HOST:PORT"):
        run_sweep(ATTITUDE_NOISE_CELL, GRID, trials=2, out=tmp_path, dashboard_address=address)
    assert list(tmp_path.iterdir()) == []


def test_local_cluster_scheduler_workers_and_dashboard_listen_on_loopback_only(tmp_path):
    """During a sweep on two worker processes, every listening socket of this process and its
    children is bound to 127.0.0.1."""
    seen: list[str] = []

    def progress(done: int, total: int) -> None:
        me = psutil.Process()
        for proc in (me, *me.children(recursive=True)):
            try:
                conns = proc.net_connections(kind="inet")
            except psutil.Error:
                continue
            seen.extend(c.laddr.ip for c in conns if c.status == psutil.CONN_LISTEN)

    report = run_sweep(ATTITUDE_NOISE_CELL, GRID, trials=2, out=tmp_path, workers=2, progress=progress)
    assert report.n_undone == 0
    # scheduler, its dashboard and the two nannies in this process; each worker's own listeners
    assert len(seen) >= 6 and set(seen) == {"127.0.0.1"}


def test_dashboard_turned_off_leaves_only_loopback_listeners_on_free_ports(tmp_path):
    """``dashboard_address=None``: no dashboard, and the scheduler's remaining HTTP endpoints
    (health, metrics) take a free loopback port rather than 8787 on every interface."""
    seen: list[tuple[str, int]] = []

    def progress(done: int, total: int) -> None:
        conns = psutil.Process().net_connections(kind="inet")
        seen.extend((c.laddr.ip, c.laddr.port) for c in conns if c.status == psutil.CONN_LISTEN)

    run_sweep(ATTITUDE_NOISE_CELL, GRID, trials=2, out=tmp_path, processes=False, dashboard_address=None,
              progress=progress)
    assert seen and {ip for ip, _ in seen} == {"127.0.0.1"} and 8787 not in {port for _, port in seen}
