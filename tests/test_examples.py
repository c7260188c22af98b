"""The gallery examples (``examples/*.py``) run at their default size, write their figure, and give
numbers that an independent method confirms: SciPy's rotations, SciPy's ODE solver, OpenCV's PnP, a
Kabsch fit by SciPy, the zarr store read without xarray, and the truth the data were simulated from.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import cv2
import nbclient
import nbformat
import numpy as np
import pytest
import zarr
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def run_example(name: str, out_dir: Path, **kwargs):
    """Import ``examples/<name>.py`` as a module and call its ``main`` (the default, small size)."""
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    result = module.main(out_dir=out_dir, **kwargs)
    figure = out_dir / f"{name}.png"
    assert result["figure"] == figure and figure.read_bytes()[:8] == PNG_MAGIC
    return result


EXAMPLE_NAMES = ["closed_loop_from_parts", "sweep_error_maps", "formation_reconfiguration", "tof_pose_000",
                 "rodrigues_pose_001", "cylindrical_pose_004", "crlb_baseline"]


def test_every_example_is_run_here_and_its_gallery_figure_is_committed():
    assert sorted(p.stem for p in EXAMPLES.glob("*.py")) == sorted(EXAMPLE_NAMES)
    for name in EXAMPLE_NAMES:
        assert (EXAMPLES.parent / "docs" / "figures" / "gallery" / f"{name}.png").read_bytes()[:8] == PNG_MAGIC


def test_closed_loop_example_attitude_error_from_scipy_rotations_stays_below_one_degree(tmp_path):
    res = run_example("closed_loop_from_parts", tmp_path)
    est = Rotation.from_quat(res["q_NT_est"], scalar_first=True)
    true = Rotation.from_quat(res["q_NT_true"], scalar_first=True)
    error_deg = np.degrees((est.inv() * true).magnitude())
    assert res["final_attitude_error_deg"] == pytest.approx(error_deg[-1], abs=1e-9)
    assert error_deg.max() < 1.0
    assert res["increments_used"] == res["epochs"] - 1


def test_sweep_example_store_read_by_zarr_matches_the_dataset_and_the_bound_grows_with_distance(tmp_path):
    res = run_example("sweep_error_maps", tmp_path, work_dir=tmp_path / "sweep")
    ds = res["dataset"]
    store = zarr.open_group(str(tmp_path / "sweep" / "sweep.zarr"), mode="r")
    np.testing.assert_array_equal(np.asarray(store["crlb_deg"][:]), ds["crlb_deg"].values)
    np.testing.assert_array_equal(np.asarray(store["distance_m"][:]), [30.0, 80.0])
    assert bool(np.all(np.asarray(store["done"][:]))) and res["failed_trials"] == 0
    crlb = ds["crlb_deg"].median("trial")
    assert np.all(crlb.sel(distance_m=80.0).values > 2.0 * crlb.sel(distance_m=30.0).values)
    assert res["kind_figures"] == ["error_maps.png"]


def test_reconfiguration_example_impulses_integrated_by_solve_ivp_reach_the_slots(tmp_path):
    res = run_example("formation_reconfiguration", tmp_path)
    assert res["ok"], res["failure_reason"]
    assert res["dv_lower_bound_m_s"] * (1 - 1e-9) <= res["dv_total_m_s"] <= 1.05 * res["dv_lower_bound_m_s"]
    n, p = res["n_rad_s"], res["plan"]

    def cw(_t, x):  # Clohessy–Wiltshire equations, written out here
        return [x[3], x[4], x[5], 3 * n**2 * x[0] + 2 * n * x[4], -2 * n * x[3], -(n**2) * x[2]]

    for i, x in enumerate(res["x0_H"].copy()):
        t_prev = 0.0
        for j, t_j in enumerate(p.impulse_times_s):
            if t_j > t_prev:
                x = solve_ivp(cw, (t_prev, t_j), x, rtol=1e-11, atol=1e-9).y[:, -1]
            x = x + np.r_[0.0, 0.0, 0.0, p.impulses_H[i, j]]
            t_prev = t_j
        np.testing.assert_allclose(x[:3], res["slots_H"][i, :3], atol=1e-3)
        np.testing.assert_allclose(x[3:], res["slots_H"][i, 3:], atol=1e-6)
    assert res["min_range_m"] > 20.0


def test_tof_example_pose_matches_the_rendered_pose_and_a_scipy_kabsch_fit_of_its_markers(tmp_path):
    res = run_example("tof_pose_000", tmp_path)
    r = res["result"]
    assert r.ok and r.n_matched == 6
    assert res["position_error_mm"] < 2.0 and res["attitude_error_deg"] < 0.5
    markers_C = np.array([[x, y, 0.0] for x, y in res["plate"].markers_xy_m])[r.labels]
    points_S = r.detections.points_S
    R, _ = Rotation.align_vectors(points_S - points_S.mean(0), markers_C - markers_C.mean(0))
    t = points_S.mean(0) - R.apply(markers_C.mean(0))
    np.testing.assert_allclose(t, res["r_CS_S_true"], atol=3e-3)
    assert np.degrees((R * Rotation.from_matrix(res["R_SC_true"]).inv()).magnitude()) < 1.0


def test_rodrigues_example_agrees_with_opencv_solvepnp_on_every_frame(tmp_path):
    res = run_example("rodrigues_pose_001", tmp_path)
    assert res["frames_ok_switching"] == res["frames"] and res["frames_ok_plain"] < res["frames"]
    f_px = res["focal_length_m"] / res["pixel_size_m"]
    K = np.array([[f_px, 0.0, 0.0], [0.0, f_px, 0.0], [0.0, 0.0, 1.0]])
    for k, xy in enumerate(res["xy_m"]):
        uv = -xy / res["pixel_size_m"]  # 001's x = −f X/Z is OpenCV's u = f X/Z about the principal point
        ok, rvec, tvec = cv2.solvePnP(res["cube_T"], uv, K, None, flags=cv2.SOLVEPNP_ITERATIVE)
        assert ok
        R_cv = cv2.Rodrigues(rvec)[0]
        diff = Rotation.from_matrix(R_cv @ res["R_CT_switching"][k].T).magnitude()
        assert np.degrees(diff) < 0.02
        np.testing.assert_allclose(tvec[:, 0], res["r_TC_C_switching"][k], atol=0.05)
    assert res["max_error_switching_deg"] < 1.0


def test_cylindrical_example_points_lie_within_a_tenth_of_a_millimetre_of_the_truth(tmp_path):
    res = run_example("cylindrical_pose_004", tmp_path)
    assert res["points_ok"] == res["points"] == 20
    error_mm = 1e3 * np.linalg.norm(res["X_measured_W"] - res["X_true_W"], axis=1)
    assert res["rms_error_mm"] == pytest.approx(np.sqrt(np.mean(error_mm**2)))
    assert 0.0 < error_mm.max() < 0.2 and res["attitude_error_deg"] < 0.05


def test_crlb_example_monte_carlo_rms_lies_on_the_bound(tmp_path):
    res = run_example("crlb_baseline", tmp_path)
    ratio = res["monte_carlo_deg"] / res["crlb_deg"]
    wide = res["axis_angle_deg"] >= 5.0
    # 60 trials of a 3-D error: an RMS has a relative spread of about 1/sqrt(360) = 5 %
    assert np.all((ratio[wide] > 0.85) & (ratio[wide] < 1.2)), ratio
    assert np.all(ratio > 0.85), ratio  # nothing beats the bound
    assert res["crlb_deg"][0] > res["crlb_deg"][-1]  # narrow baselines give the weaker bound


def test_an_example_runs_as_a_script_with_out_dir(tmp_path):
    out = subprocess.run([sys.executable, str(EXAMPLES / "rodrigues_pose_001.py"), "--out-dir", str(tmp_path)],
                         capture_output=True, text=True, timeout=120, env={**os.environ, "MPLBACKEND": "Agg"})
    assert out.returncode == 0, out.stderr
    assert "13/13 frames solved with switching" in out.stdout
    assert (tmp_path / "rodrigues_pose_001.png").read_bytes()[:8] == PNG_MAGIC


def test_tour_notebook_runs_top_to_bottom_and_is_stored_without_outputs(tmp_path):
    path = EXAMPLES / "tour.ipynb"
    nb = nbformat.read(path, as_version=4)
    nbformat.validate(nb)
    assert all(not c.get("outputs") and c.get("execution_count") is None for c in nb.cells if c.cell_type == "code")
    nbclient.NotebookClient(nb, timeout=120, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    assert not errors
    last = nb.cells[-1].outputs[-1]["data"]["text/plain"]
    assert last.startswith("array([0.")
