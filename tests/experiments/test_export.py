"""``coobs export`` and ``experiments.export``: every file read back by an independent reader.

One short closed-loop run (the quickstart in the geometric mode, 5 epochs) is exported in the four
formats through the command line; the files are then read by readers that share no code with
the writers (CCSDS: ``ccsds-ndm-py`` and ``oem``; PLY: ``plyfile``; COLMAP: pycolmap's reader)
and compared with the stored dataset, with the orbit mechanics checked by Kepler propagation and
the quaternion convention by the CCSDS direction cosine matrix against SciPy's rotation.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import ccsds_ndm
import numpy as np
import pytest
import xarray as xr
from oem import OrbitEphemerisMessage
from plyfile import PlyData
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from coobs.cli import app
from experiments.export import inertial_states, open_run, write_aem, write_oem
from orbits.cw import mean_motion, propagate
from orbits.hill import hill_frame, hill_from_inertial
from orbits.two_body import R_EARTH_M, propagate_kepler

REPO = Path(__file__).resolve().parents[2]
EPOCH = "2030-06-01T12:00:00.250"
runner = CliRunner()


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    """A stored quickstart run, geometric mode, 4 s (5 epochs)."""
    root = tmp_path_factory.mktemp("export")
    text = (REPO / "experiments/configs/quickstart.toml").read_text()
    text = (text.replace('mode = "rendered"', 'mode = "geometric"')
            .replace("duration_s = 30.0", "duration_s = 4.0").replace("convergence_hold_s = 10.0", "convergence_hold_s = 2.0"))
    assert 'mode = "geometric"' in text and "duration_s = 4.0" in text
    (root / "quick.toml").write_text(text)
    res = runner.invoke(app, ["run", str(root / "quick.toml"), "--out", str(root / "run"), "--no-figures"])
    assert res.exit_code == 0, res.output
    return root / "run"


@pytest.fixture(scope="module")
def ds(run_dir) -> xr.Dataset:
    return open_run(run_dir)


@pytest.fixture(scope="module")
def exported(run_dir) -> Path:
    """The run exported in all four formats by ``coobs export``."""
    out = run_dir.parent / "exported"
    for fmt in ("aem", "oem", "ply", "colmap"):
        res = runner.invoke(app, ["export", str(run_dir), "--to", fmt, "--out", str(out / fmt), "--epoch", EPOCH,
                                  "--time-system", "TAI"])
        assert res.exit_code == 0, res.output
    return out


def _epochs(ds) -> np.ndarray:
    return np.datetime64(EPOCH, "ns") + np.round(ds["time_s"].values * 1e9).astype("timedelta64[ns]")


def _orbit_radius_m(ds) -> float:
    return R_EARTH_M + 1e3 * tomllib.loads(ds.attrs["config_toml"]).get("formation", {}).get("orbit_altitude_km", 870.0)


def _dcm_ccsds(q1, q2, q3, qc) -> np.ndarray:
    """CCSDS ADM direction cosine matrix of (Q1, Q2, Q3, QC): ``v_B = A v_A``."""
    e = np.array([q1, q2, q3])
    ex = np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])
    return (qc**2 - e @ e) * np.eye(3) + 2 * np.outer(e, e) - 2 * qc * ex


@pytest.mark.parametrize("which", ["true", "est"])
def test_aem_read_by_ccsds_ndm_gives_the_attitude_and_rate_of_the_run(ds, exported, which):
    aem = ccsds_ndm.from_file(str(exported / "aem" / f"target_{which}.aem"))
    assert len(aem.segments) == 1
    seg = aem.segments[0]
    seg.validate()
    m = seg.metadata
    assert (m.ref_frame_a, m.ref_frame_b, m.attitude_type, m.angvel_frame, m.time_system) == (
        "EME2000", "SC_BODY_1", "QUATERNION/ANGVEL", "SC_BODY_1", "TAI")
    rows = np.asarray(seg.data.attitude_states_numpy)
    assert [np.datetime64(e, "ns") for e in seg.data.attitude_states_epochs] == list(_epochs(ds))
    q_NT = ds[f"q_NT_{which}"].values
    R_NT = Rotation.from_quat(q_NT[:, [1, 2, 3, 0]]).as_matrix()        # SciPy: scalar last, active
    for row, R in zip(rows, R_NT, strict=True):
        # the CCSDS quaternion maps REF_FRAME_A (N) components to REF_FRAME_B (T): A = R_TN = R_NT^T
        np.testing.assert_allclose(_dcm_ccsds(*row[:4]), R.T, atol=1e-12)
    np.testing.assert_allclose(rows[:, 4:], ds[f"omega_{which}_deg_s"].values, rtol=0, atol=1e-12)


def _read_oem(path: Path) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray]:
    """Metadata, epochs, positions (m) and velocities (m/s) through the ``oem`` package."""
    msg = OrbitEphemerisMessage.open(path)
    assert len(msg.segments) == 1
    states = list(msg.segments[0].states)
    epochs = np.array([np.datetime64(s.epoch.isot, "ns") for s in states])
    r = np.array([s.position for s in states]) * 1e3
    v = np.array([s.velocity for s in states]) * 1e3
    return msg.segments[0].metadata, epochs, r, v


def test_oem_target_is_a_circular_two_body_orbit_whose_hill_frame_is_the_runs(ds, exported):
    meta, epochs, r, v = _read_oem(exported / "oem" / "target.oem")
    assert (meta["OBJECT_NAME"], meta["REF_FRAME"], meta["CENTER_NAME"], meta["TIME_SYSTEM"]) == (
        "TARGET", "EME2000", "EARTH", "TAI")
    np.testing.assert_array_equal(epochs, _epochs(ds))
    a_m = _orbit_radius_m(ds)
    np.testing.assert_allclose(np.linalg.norm(r, axis=1), a_m, rtol=0, atol=1e-6)
    t = ds["time_s"].values
    r_kep, v_kep = propagate_kepler(r[0], v[0], t - t[0])
    np.testing.assert_allclose(r, r_kep, rtol=0, atol=1e-6)
    np.testing.assert_allclose(v, v_kep, rtol=0, atol=1e-9)
    # the frame built from the written states is the truth's R_NH = R_z(n t)
    n = float(mean_motion(a_m))
    R_NH = Rotation.from_rotvec(np.outer(n * t, [0.0, 0.0, 1.0])).as_matrix()
    np.testing.assert_allclose(hill_frame(r, v), R_NH, atol=1e-12)


def test_oem_observers_map_back_to_the_stored_hill_states_and_move_on_two_body_orbits(ds, exported):
    _, _, r_C, v_C = _read_oem(exported / "oem" / "target.oem")
    t = ds["time_s"].values
    for i, name in enumerate(ds["spacecraft"].values):
        path = exported / "oem" / f"{str(name).replace(' ', '_')}.oem"
        meta, epochs, r_D, v_D = _read_oem(path)
        assert meta["OBJECT_NAME"] == str(name)
        np.testing.assert_array_equal(epochs, _epochs(ds))
        # second reader: the same numbers through ccsds-ndm-py
        sv = np.asarray(ccsds_ndm.from_file(str(path)).segments[0].data.state_vector_numpy)
        np.testing.assert_allclose(sv[:, :6] * 1e3, np.hstack([r_D, v_D]), rtol=1e-15, atol=0)
        r_H, v_H = hill_from_inertial(r_C, v_C, r_D, v_D)
        np.testing.assert_allclose(r_H, ds["r_H_m"].values[i], rtol=0, atol=1e-6)
        np.testing.assert_allclose(v_H, ds["v_H_m_s"].values[i], rtol=0, atol=1e-9)
        # station-kept in H is forced, not free flight: it leaves its Kepler orbit by at most
        # ½ a t², a = 3 n² |ρ| the largest CW acceleration the station keeping cancels
        n = float(mean_motion(_orbit_radius_m(ds)))
        r_kep, _ = propagate_kepler(r_D[0], v_D[0], t - t[0])
        bound_m = 0.5 * 3 * n**2 * np.linalg.norm(r_H, axis=1) * (t - t[0]) ** 2 + 1e-6
        assert np.all(np.linalg.norm(r_D - r_kep, axis=1) <= bound_m)
        assert np.linalg.norm(r_D[-1] - r_kep[-1]) > 1e-2 * bound_m[-1]     # and does leave it


def test_oem_of_an_observer_on_a_cw_orbit_follows_kepler(ds, tmp_path):
    """An observer coasting on a Clohessy–Wiltshire orbit is written on its two-body orbit (v_H ≠ 0)."""
    n = float(mean_motion(_orbit_radius_m(ds)))
    t = ds["time_s"].values
    x0 = np.array([[30.0, -20.0, 10.0, 0.05, -0.08, 0.02]] * ds.sizes["spacecraft"])
    x = propagate(x0, t, n)
    moved = ds.assign(r_H_m=(ds["r_H_m"].dims, x[..., :3]), v_H_m_s=(ds["v_H_m_s"].dims, x[..., 3:]))
    name = str(ds["spacecraft"].values[0])
    _, _, r_D, v_D = _read_oem(write_oem(moved, tmp_path / "cw.oem", obj=name, epoch=EPOCH, time_system="TAI"))
    r_kep, v_kep = propagate_kepler(r_D[0], v_D[0], t - t[0])
    np.testing.assert_allclose(r_D, r_kep, rtol=0, atol=1e-4)        # CW linearisation error over 4 s at 40 m
    np.testing.assert_allclose(v_D, v_kep, rtol=0, atol=1e-6)
    np.testing.assert_allclose(inertial_states(moved, name)[0], r_D, rtol=0, atol=1e-6)


def test_ply_read_by_plyfile_holds_the_valid_points_with_their_view_counts(ds, exported):
    v = PlyData.read(str(exported / "ply" / "snapshot_cloud.ply"))["vertex"].data
    valid = ds["snapshot_point_valid"].values
    X = ds["snapshot_X_W_m"].values[valid]
    assert len(v) == int(valid.sum()) > 10
    np.testing.assert_array_equal(np.column_stack([v["x"], v["y"], v["z"]]), X)
    seen = np.isfinite(ds["snapshot_uv_px"].values).all(axis=2)[valid]
    np.testing.assert_array_equal(v["n_views"], seen.sum(axis=1))
    np.testing.assert_array_equal(v["correct"], ds["snapshot_track_correct"].values[valid])


def test_colmap_model_read_by_pycolmap_has_the_cameras_poses_tracks_and_points(ds, exported):
    import pycolmap

    rec = pycolmap.Reconstruction(str(exported / "colmap" / "sparse"))
    cfg = tomllib.loads(ds.attrs["config_toml"])["camera"]
    (cam,) = rec.cameras.values()
    f_px = cfg["width_px"] / 2 / np.tan(np.radians(cfg["fov_deg"]) / 2)
    assert (cam.model.name, cam.width, cam.height) == ("PINHOLE", cfg["width_px"], cfg["height_px"])
    np.testing.assert_allclose(cam.params, [f_px, f_px, cfg["width_px"] / 2, cfg["height_px"] / 2], rtol=1e-12)
    k = int(np.argmin(np.abs(ds["time_s"].values - ds.attrs["snapshot_time_s"])))
    views = ds["snapshot_view"].values
    uv = ds["snapshot_uv_px"].values
    assert rec.num_images() == len(views)
    for image in rec.images.values():
        j = image.image_id - 1
        # the camera sits at the observer's stored position and looks at the target's centre
        np.testing.assert_allclose(image.projection_center(), ds["r_H_m"].values[views[j], k], atol=1e-9)
        np.testing.assert_allclose(image.viewing_direction(), -ds["r_H_m"].values[views[j], k]
                                   / np.linalg.norm(ds["r_H_m"].values[views[j], k]), atol=1e-12)
        xy = np.array([p.xy for p in image.points2D])
        np.testing.assert_allclose(xy, uv[np.isfinite(uv[:, j]).all(axis=1), j] + 0.5, rtol=0, atol=1e-9)
        assert (exported / "colmap" / "images" / image.name).is_file()
    valid = ds["snapshot_point_valid"].values
    pts = np.array([p.xyz for p in rec.points3D.values()])
    assert len(pts) == int(valid.sum())
    np.testing.assert_allclose(np.sort(pts, axis=0), np.sort(ds["snapshot_X_W_m"].values[valid], axis=0), atol=1e-12)
    assert rec.compute_mean_track_length() >= 2
    # what COLMAP recomputes from the model: points reproject onto their keypoints (measured 0.086 px)
    rec.update_point_3d_errors()
    assert rec.compute_mean_reprojection_error() < 1.5
    assert any(p.color.any() for p in rec.points3D.values())


def test_python_writers_refuse_bad_options_naming_them_and_write_nothing(ds, tmp_path):
    cases = [(dict(attitude="both"), "attitude:"), (dict(epoch="yesterday"), "epoch:"),
             (dict(time_system="GMT"), "time_system:"), (dict(ref_frame="ITRF"), "ref_frame:")]
    for kwargs, start in cases:
        with pytest.raises(ValueError, match=f"^{start}"):
            write_aem(ds, tmp_path / "x.aem", **kwargs)
    with pytest.raises(ValueError, match="^obj:"):
        write_oem(ds, tmp_path / "x.oem", obj="nobody")
    with pytest.raises(ValueError, match="v_H_m_s"):
        write_oem(ds.drop_vars("v_H_m_s"), tmp_path / "x.oem", obj=str(ds["spacecraft"].values[0]))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("case", ["no_result", "sweep_folder", "missing", "unknown_format", "bad_epoch", "out_is_file"])
def test_export_bad_input_exits_2_with_one_line_and_writes_nothing(run_dir, tmp_path, case):
    run, fmt, extra = run_dir, "aem", []
    out = tmp_path / "out"
    if case == "no_result":
        run = tmp_path / "empty"
        run.mkdir()
    elif case == "sweep_folder":
        run = tmp_path / "sw"
        (run / "sweep.zarr").mkdir(parents=True)
    elif case == "missing":
        run = tmp_path / "nowhere"
    elif case == "unknown_format":
        fmt = "gltf"
    elif case == "bad_epoch":
        extra = ["--epoch", "2026-13-01T00:00:00"]
    else:
        out.write_text("a file")
    before = sorted(p.name for p in tmp_path.iterdir())
    res = runner.invoke(app, ["export", str(run), "--to", fmt, "--out", str(out), *extra])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), res.output
    expected = {"no_result": "no result.nc", "sweep_folder": "sweep folder", "missing": "no such folder",
                "unknown_format": "--to:", "bad_epoch": "--epoch:", "out_is_file": "--out:"}[case]
    assert expected in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == before
