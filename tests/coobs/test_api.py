"""The coobs Python API: configs by name, run, plot, sweep errors, version, ``python -m coobs``.

Each result is checked against another path to the same answer: the kind module called directly
on ``load_config`` of the file, the stored files read back with h5py and json, the config folder
listed with ``os.listdir`` and parsed with ``tomllib``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tomllib
from importlib.metadata import version
from pathlib import Path
from xml.etree import ElementTree

import h5py
import numpy as np
import pytest

import coobs
from experiments.config import ConfigError, load_config

CONFIGS = Path(__file__).resolve().parents[2] / "experiments" / "configs"
SMALL = {"observation.mode": "geometric", "time.duration_s": 4.0, "estimator.convergence_hold_s": 1.0}


@pytest.fixture(scope="module")
def small_run():
    return coobs.run("quickstart", overrides=SMALL, progress=False)


def test_configs_lists_every_toml_of_the_config_folder_with_its_title_or_first_comment():
    listing = coobs.configs()
    files = sorted(f[:-5] for f in os.listdir(CONFIGS) if f.endswith(".toml"))
    assert list(listing) == files
    for name, title in listing.items():
        text = (CONFIGS / f"{name}.toml").read_text()
        expected = tomllib.loads(text).get("title") or text.splitlines()[0].lstrip("#").strip()
        assert title == expected
    lines = repr(listing).splitlines()
    assert len(lines) == len(files) and all(line.split()[0] == name for line, name in zip(lines, files, strict=True))


def test_version_is_the_installed_distribution_version():
    assert coobs.__version__ == version("coobs")


def test_run_by_name_with_overrides_equals_the_kind_module_on_the_file(small_run):
    module, cfg = load_config(CONFIGS / "quickstart.toml", SMALL)
    direct = module.run(cfg)
    assert small_run.config == cfg
    np.testing.assert_equal(small_run.summary, direct.summary)  # exact, and NaN (a run not converged) equals NaN
    np.testing.assert_array_equal(small_run.dataset["q_NT_est"].values, direct.dataset["q_NT_est"].values)
    assert small_run.dataset.attrs["kind"] == "formation" and small_run.out is None


def test_stored_config_text_validates_back_to_the_config_that_ran(small_run):
    text = small_run.dataset.attrs["config_toml"]
    assert text.startswith("# written by coobs from quickstart.toml with ")
    assert load_config(tomllib.loads(text))[1] == small_run.config


def test_run_from_a_table_and_from_a_config_object_give_the_run_by_name(small_run):
    table = tomllib.loads((CONFIGS / "quickstart.toml").read_text())
    from_table = coobs.run(table, overrides=SMALL, progress=False)
    from_config = coobs.run(small_run.config, progress=False)
    np.testing.assert_equal(from_table.summary, small_run.summary)  # exact, NaN equal to NaN
    np.testing.assert_equal(from_config.summary, small_run.summary)


def test_run_with_out_writes_files_that_h5py_and_json_read_back(tmp_path):
    calls = []
    res = coobs.run(CONFIGS / "quickstart.toml", overrides=SMALL, out=tmp_path / "r",
                    progress=lambda done, total: calls.append((done, total)))
    assert res.out == tmp_path / "r"
    with h5py.File(tmp_path / "r" / "result.nc", "r") as f:
        np.testing.assert_allclose(f["attitude_error_deg"][()], res.dataset["attitude_error_deg"].values)
        assert f.attrs["kind"] == "formation"
    stored = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert stored["epochs"] == res.summary["epochs"] == 5
    assert calls and calls[-1][0] == calls[-1][1]
    figures = res.plot()
    assert figures and all(p.parent == tmp_path / "r" / "figures" and p.stat().st_size > 0 for p in figures)


def test_plot_in_svg_gives_files_an_xml_parser_reads_and_refuses_an_unknown_format(small_run, tmp_path):
    figures = small_run.plot(tmp_path / "svg", format="svg")
    assert figures and all(p.suffix == ".svg" for p in figures)
    for p in figures:
        assert ElementTree.parse(p).getroot().tag == "{http://www.w3.org/2000/svg}svg"
    with pytest.raises(ValueError, match=r"^format: must be one of png, pdf, svg, got 'bmp'"):
        small_run.plot(tmp_path / "bmp", format="bmp")
    assert not (tmp_path / "bmp").exists()


@pytest.mark.parametrize(("config", "overrides", "message"), [
    ("no_such_config", None, r"^config: no file and no bundled config named 'no_such_config'; bundled: .*quickstart"),
    ("quickstart", {"formation.n_views": 0}, r"^formation\.n_views: "),
    ("quickstart", {"formation.no_such_key": 1}, r"^formation\.no_such_key: unknown key"),
    ("quickstart", ["formation.n_views=2"], r"^overrides: must be a mapping"),
    (42, None, r"^config: must be a TOML file, a bundled config's name, a mapping or a validated config, not int"),
    ({"kind": "nope"}, None, r"^kind: unknown scenario kind 'nope'"),
])
def test_bad_config_is_one_line_naming_the_key_and_nothing_is_written(tmp_path, config, overrides, message):
    with pytest.raises(ConfigError, match=message) as exc:
        coobs.run(config, overrides=overrides, out=tmp_path / "out", progress=False)
    assert "\n" not in str(exc.value)
    assert not (tmp_path / "out").exists()


def test_a_folder_is_not_a_config(tmp_path):
    with pytest.raises(ConfigError, match=r"^config: .* is a folder, not a config file$"):
        coobs.run(tmp_path, progress=False)


def test_progress_must_be_a_bool_or_a_callable():
    with pytest.raises(TypeError, match=r"^progress: "):
        coobs.run("quickstart", overrides=SMALL, progress="yes")


def test_sweep_refuses_a_config_without_sweep_table_and_a_run_folder(tmp_path, small_run):
    with pytest.raises(ConfigError, match=r"^sweep: missing \[sweep\] table"):
        coobs.sweep("quickstart", out=tmp_path / "s", progress=False)
    run_dir = tmp_path / "r"
    run_dir.mkdir()
    (run_dir / "result.nc").write_bytes(b"")
    with pytest.raises(ValueError, match=r"^out: .* holds the results of a run"):
        coobs.sweep("003_fig5_fig6", out=run_dir, progress=False)
    assert not (tmp_path / "s").exists() and sorted(os.listdir(run_dir)) == ["result.nc"]


def test_python_dash_m_coobs_is_the_command_line():
    out = subprocess.run([sys.executable, "-m", "coobs", "--help"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "Usage: coobs" in out.stdout and "sweep" in out.stdout


def test_coobs_configs_command_lists_the_names_kinds_and_titles_of_the_api_listing():
    from typer.testing import CliRunner

    from coobs.cli import app

    result = CliRunner().invoke(app, ["configs"])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    listing = coobs.configs()
    assert [line.split()[0] for line in lines] == list(listing)
    for line, (name, title) in zip(lines, listing.items(), strict=True):
        assert line.endswith(title) and tomllib.loads((CONFIGS / f"{name}.toml").read_text())["kind"] in line
