"""Stored-result datasets for the figure tests, built from closed forms and one seeded stream.

They have the variables, dimensions and attributes the figure drivers read from real results
(``coobs sweep`` of an error-map cell, ``coobs run`` of the closed loop and of ``tof_000``), with
values chosen to exercise what the figures must show: map values beyond the colour range (1.88°
and 3.32° above 1.6°), convergence times in different ranges for 2 and 3 views, an eclipse and
epochs without a measurement, a cloud with outliers.  A fixed style (:func:`fixed_style`) makes the
drawings reproducible to the pixel on one machine.
"""

from __future__ import annotations

from contextlib import contextmanager

import matplotlib as mpl
import numpy as np
import xarray as xr

from attitude.quaternion import quat_from_rotvec, quat_multiply

SEED = 20240518


@contextmanager
def fixed_style(dpi: int = 60):
    """matplotlib's defaults, no hinting, a fixed SVG salt and ``dpi`` for every saved figure."""
    with mpl.rc_context():
        mpl.rcdefaults()
        mpl.rcParams.update({"text.hinting": "none", "svg.hashsalt": "coobs-tests",
                             "savefig.dpi": dpi, "font.family": "DejaVu Sans", "path.simplify": False})
        yield


def error_map_sweep() -> xr.Dataset:
    """An error-map sweep over (n_views, distance, axis angle) with 5 trials per cell."""
    rng = np.random.default_rng(SEED)
    views, dist, ang = np.array([2, 3]), np.array([20.0, 40.0, 60.0, 80.0]), np.array([5.0, 10.0, 20.0])
    V, D, A = np.meshgrid(views, dist, ang, indexing="ij")
    base = 0.01 * D / np.sqrt(V - 1) / np.sqrt(A / 5.0)          # deg: grows with range, shrinks with baseline
    base[0, -1, 0], base[0, -2, 0] = 3.32, 1.88                   # two cells beyond the 1.6° range
    trial = 1.0 + 0.1 * rng.standard_normal((*base.shape, 5))
    e = base[..., None] * trial
    dims = ("n_views", "distance_m", "axis_angle_deg")
    frac = np.clip(1.2 - base, 0.0, 1.0)
    tconv = np.where(V == 2, 20.0 + 60.0 * base / base.max(), 5.0 + 25.0 * base / base.max())
    tconv[frac == 0] = np.nan
    return xr.Dataset(
        {"e_dtheta_deg": ((*dims, "trial"), e, {"units": "deg"}),
         "step_rms_deg": ((*dims, "trial"), 1.3 * e, {"units": "deg"}),
         "crlb_deg": ((*dims, "trial"), 0.6 * e, {"units": "deg"}),
         "filter_fraction_converged": (dims, frac, {"units": "1"}),
         "filter_median_convergence_time_s": (dims, tconv, {"units": "s"}),
         "done": (dims, np.ones(base.shape, bool))},
        coords={"n_views": views, "distance_m": dist, "axis_angle_deg": ang, "trial": np.arange(5)},
        attrs={"cell": "error_map", "kind": "formation"})


def closed_loop_run(T: int = 60) -> xr.Dataset:
    """A closed-loop run: 60 epochs 1 s apart, eclipse at 20–29 s, no increment at 0 s and 45–47 s,
    a filter converging inside its 3σ, and a 200-point snapshot cloud with 6 far outliers."""
    rng = np.random.default_rng(SEED)
    t = np.arange(T, dtype=float)
    omega_deg_s = np.array([5.0, 5.0, 5.0])
    q_true = quat_from_rotvec(np.radians(t[:, None] * omega_deg_s))
    sigma_att = 2.0 * np.exp(-t / 15.0)[:, None] * np.array([1.0, 0.8, 0.6]) + 0.05
    sigma_rate = 0.3 * np.exp(-t / 20.0)[:, None] * np.array([1.0, 0.9, 0.7]) + 0.005
    eclipse = (t >= 20) & (t < 30)
    ok = ~eclipse & ~np.isin(t, [0.0, 45.0, 46.0, 47.0])
    sigma_att[eclipse] *= 1.5
    att_T = sigma_att * rng.standard_normal((T, 3))
    rate_T = sigma_rate * rng.standard_normal((T, 3))
    q_est = quat_multiply(q_true, quat_from_rotvec(-np.radians(att_T)))
    inc_err = np.where(ok, 0.1 + 0.05 * np.abs(rng.standard_normal(T)), np.nan)
    inc_sig = np.where(ok, 0.15 + 0.02 * np.abs(rng.standard_normal(T)), np.nan)
    S = 3
    active = np.ones((T, S), bool)
    active[eclipse] = False
    X_true = rng.uniform(-1.0, 1.0, (200, 3)) * np.array([0.8, 0.6, 1.5])
    X = X_true + 0.01 * rng.standard_normal((200, 3))
    X[:6] += np.array([[40.0, 0, 0], [0, -35.0, 0], [0, 0, 50.0], [-30.0, 20.0, 0], [0, 25.0, -45.0], [60, 0, 0]])
    sigma_m = 0.004 + 0.01 * np.linalg.norm(X_true, axis=1)
    x = np.linspace(-1.0, 1.0, 48)
    image = (255 * np.clip(1.0 - np.hypot(*np.meshgrid(x, x)), 0, 1)).astype(np.uint8)
    uv = np.stack([rng.uniform(10, 38, (200, S)), rng.uniform(10, 38, (200, S))], -1)
    return xr.Dataset(
        {"q_NT_true": (("time_s", "quat_component"), q_true),
         "q_NT_est": (("time_s", "quat_component"), q_est),
         "omega_true_deg_s": (("time_s", "axis"), np.broadcast_to(omega_deg_s, (T, 3)), {"units": "deg/s"}),
         "omega_est_deg_s": (("time_s", "axis"), omega_deg_s + rate_T, {"units": "deg/s"}),
         "attitude_error_deg": ("time_s", np.linalg.norm(att_T, axis=1), {"units": "deg"}),
         "rate_error_deg_s": ("time_s", np.linalg.norm(rate_T, axis=1), {"units": "deg/s"}),
         "attitude_error_T_deg": (("time_s", "axis"), att_T, {"units": "deg"}),
         "rate_error_T_deg_s": (("time_s", "axis"), rate_T, {"units": "deg/s"}),
         "attitude_sigma_deg": (("time_s", "axis"), sigma_att, {"units": "deg"}),
         "rate_sigma_deg_s": (("time_s", "axis"), sigma_rate, {"units": "deg/s"}),
         "increment_error_deg": ("time_s", inc_err, {"units": "deg"}),
         "increment_sigma_deg": ("time_s", inc_sig, {"units": "deg"}),
         "active": (("time_s", "spacecraft"), active),
         "illumination": ("time_s", np.where(eclipse, 0.0, 1.0), {"units": "1"}),
         "measurement_ok": ("time_s", ok),
         "snapshot_image": (("snapshot_view", "image_y", "image_x"), np.stack([image] * S)),
         "snapshot_uv_px": (("snapshot_track", "snapshot_view", "uv"), uv),
         "snapshot_track_correct": ("snapshot_track", np.arange(200) % 10 != 0),
         "snapshot_X_W_m": (("snapshot_track", "axis"), X, {"units": "m"}),
         "snapshot_point_valid": ("snapshot_track", np.ones(200, bool)),
         "snapshot_X_true_H_m": (("snapshot_track", "axis"), X_true, {"units": "m"}),
         "snapshot_sigma_m": ("snapshot_track", sigma_m, {"units": "m"})},
        coords={"time_s": t, "spacecraft": [f"view {i}" for i in range(S)], "quat_component": ["q0", "q1", "q2", "q3"],
                "axis": ["x", "y", "z"], "snapshot_view": np.arange(S), "uv": ["u", "v"]},
        attrs={"study": "closed_loop", "kind": "formation", "threshold_attitude_deg": 0.5,
               "threshold_rate_deg_s": 0.05, "snapshot_time_s": 30.0})


def tof_run() -> xr.Dataset:
    """A ``tof_000`` run without the example frame and the matching study: the static repeatability
    traces of two range estimators and the sweep of one Euler angle."""
    from experiments.scenarios.tof.experiment import COLUMNS

    rng = np.random.default_rng(SEED)
    est = ["plane", "median"]
    frames = np.arange(30)
    scale = {"x_mm": 1.0, "y_mm": 1.2, "z_mm": 3.0, "pitch_deg": 0.2, "yaw_deg": 0.25, "roll_deg": 0.1}
    data = {c: (("estimator", "frame"), scale[c] * rng.standard_normal((2, frames.size)) + np.array([[0.0], [0.5]]))
            for c in COLUMNS}
    angles = np.array([-20.0, -10.0, 0.0, 10.0, 20.0])
    growth = 0.05 * (1.0 + (angles / 10.0) ** 2)
    att = growth[None, None, :, None] * (1.0 + np.array([0, 1.0])[:, None, None, None]) \
        * rng.standard_normal((2, 3, angles.size, 8))
    data["sweep_attitude_error_deg"] = (("estimator", "sweep_axis", "sweep_angle_deg", "sweep_frame"), att)
    data["sweep_position_error_mm"] = (("estimator", "sweep_axis", "sweep_angle_deg", "sweep_frame"), 20.0 * att)
    return xr.Dataset(data, coords={"estimator": est, "frame": frames, "sweep_axis": ["pitch", "yaw", "roll"],
                                    "sweep_angle_deg": angles, "sweep_frame": np.arange(8)},
                      attrs={"kind": "tof_000"})
