"""Bad configs and output folders at the command line: exit code 2, one line on stderr, nothing written or computed."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from experiments.results import ScenarioResult, check_output_dir, write_result

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = ROOT / "experiments" / "configs"
TOF = CONFIGS / "000_tof_700mm.toml"  # about a minute of computing: a check after it would show in the time


def coobs(*args: str) -> tuple[subprocess.CompletedProcess, float]:
    """Run ``python -m coobs ARGS`` in the repository root; returns the process and its wall time, s."""
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "coobs", *map(str, args)], cwd=ROOT, capture_output=True,
                          text=True, timeout=120, env={**os.environ, "MPLBACKEND": "Agg"})
    return proc, time.perf_counter() - t0


def one_error_line(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and len(lines[0]) <= 307, proc.stderr
    assert "Traceback" not in proc.stderr
    return lines[0].removeprefix("error: ")


def test_binary_config_file_exits_2_naming_the_config(tmp_path):
    binary = tmp_path / "binary.toml"
    binary.write_bytes(np.random.default_rng(0).integers(0, 256, 2048, dtype=np.uint8).tobytes())
    proc, _ = coobs("run", binary, "--out", tmp_path / "out")
    assert one_error_line(proc).startswith("config: ")
    assert not (tmp_path / "out").exists()


def test_list_valued_kind_exits_2_in_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('kind = ["formation"]\n')
    proc, _ = coobs("run", bad, "--out", tmp_path / "out")
    assert one_error_line(proc).startswith("kind: must be a string")
    assert not (tmp_path / "out").exists()


def test_inline_tables_nested_400_deep_exit_2_in_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('kind = "formation"\nx = ' + "{a = " * 400 + "1" + "}" * 400 + "\n")
    proc, _ = coobs("run", bad, "--out", tmp_path / "out")
    assert one_error_line(proc) == "config: tables and arrays nested deeper than 16 levels"
    assert not (tmp_path / "out").exists()


def test_sweep_set_into_a_value_exits_2_naming_the_key(tmp_path):
    proc, _ = coobs("sweep", CONFIGS / "003_ekf.toml", "--out", tmp_path / "out", "--set", "seed.x=1")
    assert one_error_line(proc).startswith("seed.x: seed is a value, not a table")
    assert not (tmp_path / "out").exists()


def test_run_into_a_file_exits_2_before_computing(tmp_path):
    a_file = tmp_path / "a_file"
    a_file.write_text("keep me\n")
    for out in (a_file, a_file / "sub"):
        proc, wall_s = coobs("run", TOF, "--out", out)
        msg = one_error_line(proc)
        assert msg.startswith("--out: '/") and msg.endswith(" is a file, not a folder"), msg
        assert wall_s < 15.0  # the TOF scenario itself takes about a minute
    assert a_file.read_text() == "keep me\n"


def test_run_into_a_folder_that_cannot_be_written_exits_2_before_computing():
    proc, wall_s = coobs("run", TOF, "--out", "/proc/self/coobs-out")  # no one may create folders there
    assert one_error_line(proc).startswith("--out: cannot write in '/proc/self'")
    assert wall_s < 15.0


def _write_run(out: Path, config_toml: str) -> None:
    ds = xr.Dataset({"x": ("t", np.arange(3.0))}, attrs={"kind": "tof_000", "config_toml": config_toml})
    write_result(ScenarioResult(ds, {"n": 3}), out)


def test_output_folder_of_the_same_config_may_be_rewritten_another_needs_force(tmp_path):
    out = tmp_path / "run"
    _write_run(out, 'kind = "tof_000"\n')
    before = sorted(p.name for p in tmp_path.rglob("*"))
    check_output_dir(out, config_toml='kind = "tof_000"\n')
    with pytest.raises(ValueError, match=r"^out: .* holds the results of another run; .* --force"):
        check_output_dir(out, config_toml='kind = "tof_000"\nseed = 1\n')
    check_output_dir(out, config_toml='kind = "tof_000"\nseed = 1\n', force=True)
    (out / "sweep.zarr").mkdir()
    with pytest.raises(ValueError, match=r"^out: .* holds sweep.zarr of another command"):
        check_output_dir(out, config_toml='kind = "tof_000"\n', foreign=("sweep.zarr",))
    (out / "sweep.zarr").rmdir()
    check_output_dir(tmp_path / "new" / "deeper", config_toml="")
    assert sorted(p.name for p in tmp_path.rglob("*")) == before  # the checks wrote nothing


def test_run_into_another_runs_folder_exits_2_unless_forced(tmp_path):
    out = tmp_path / "run"
    _write_run(out, 'kind = "tof_000"\n')
    proc, wall_s = coobs("run", TOF, "--out", out)
    assert one_error_line(proc).startswith("--out: ") and "--force" in proc.stderr
    assert wall_s < 15.0
    assert xr.load_dataset(out / "result.nc", engine="h5netcdf").attrs["config_toml"] == 'kind = "tof_000"\n'


def test_plot_of_a_folder_with_an_unreadable_result_exits_2(tmp_path):
    (tmp_path / "result.nc").write_text("not netCDF\n")
    proc, _ = coobs("plot", tmp_path)
    assert one_error_line(proc).startswith("out: result.nc in ")
