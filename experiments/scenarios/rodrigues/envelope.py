"""The working envelope of the 001 pose solver: range × target size × pixel noise, beside OpenCV.

One cell is one (range, cube edge, pixel noise) point of an ``envelope`` config
(:class:`experiments.scenarios.rodrigues.config.EnvelopeConfig`).  Each trial draws a uniformly
random static attitude of the cube on the boresight, one noisy frame of its visible vertices
(001 eq 6–7, back-face culling, inside the image), and solves it with

* ``rodrigues``: :func:`chaser.rodrigues_pose.solve_pose_rodrigues` (four-set switching) from a
  perturbed truth (a tracker's previous epoch),
* ``opencv_sqpnp``: ``cv2.solvePnP(..., SOLVEPNP_SQPNP)`` (global, no guess),
* ``opencv_iterative``: ``cv2.solvePnP(..., SOLVEPNP_ITERATIVE, useExtrinsicGuess=True)`` from the
  same perturbed truth as ours,

and the Cramér–Rao bound of that frame (:func:`chaser.rodrigues_pose.pose_crlb`) beside them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import cv2
import numpy as np
import xarray as xr

from attitude.quaternion import (
    matrix_from_quat,
    quat_from_matrix,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    rotvec_from_quat,
)
from chaser.rodrigues_pose import (
    FAILURE_REASONS,
    GibbsPose,
    pixels_from_focal_plane,
    pose_crlb,
    project_focal_plane,
    solve_pose_rodrigues,
)
from experiments.scenarios.rodrigues.config import Config
from experiments.scenarios.rodrigues.opencv_pnp import solve_pnp
from experiments.scenarios.rodrigues.truth import cube_vertices, visible_vertices
from experiments.sweep import Metric, SweepCell, cell_seed_sequences, child_seeds

__all__ = ["sweep_cell", "ENVELOPE_SOLVERS", "ENVELOPE_REASONS", "GROSS_MAHALANOBIS", "envelope_trials", "envelope_sweep_cell",
           "envelope_statistics", "envelope_run"]

#: Solvers of the envelope, in dataset order.
ENVELOPE_SOLVERS = ("rodrigues", "opencv_sqpnp", "opencv_iterative")
#: Failure reasons of the ``failed`` metric: the solver's own; OpenCV returning no pose
#: (``opencv_failed``) or raising (``opencv_error``: SQPnP asserts that the normalised image points have a
#: variance of at least 1e-5, so it refuses a target subtending less than about 0.5°).
ENVELOPE_REASONS = FAILURE_REASONS + ("opencv_failed", "opencv_error")
#: A returned pose whose Mahalanobis distance ``√(eᵀ F e)`` under the bound exceeds this is a gross
#: error (a wrong minimum): for an efficient Gaussian estimator ``P(χ²₆ > 36) ≈ 3e-6``.
GROSS_MAHALANOBIS = 6.0


def envelope_trials(cfg: Config, seeds: Sequence[np.random.SeedSequence]) -> dict[str, np.ndarray]:
    """One envelope cell: one random attitude and frame per seed, three solvers and the bound.

    Three streams per trial (children of its seed): the attitude, the image noise, the initial guess.

    Returns
    -------
    dict
        Per trial and solver: ``along_los_error_m`` (signed, along ``u = r_TC_C/|r_TC_C|``),
        ``across_los_error_m`` (norm), ``attitude_error_deg`` (angle of ``R̂_CT R_CTᵀ``),
        ``mahalanobis`` (``√(eᵀ F e)`` of ``e = [φ, δr]`` under the Fisher information ``F``),
        ``failed`` (one-hot over :data:`ENVELOPE_REASONS`); per trial: ``crlb_along_los_m``,
        ``crlb_across_los_m``, ``crlb_attitude_deg``, ``n_points``; ``failure_reason`` all ``""``
        (a solver's failure is a row of ``failed``, so that the other solvers' numbers stay).
    """
    n = len(seeds)
    env, cam = cfg.envelope, cfg.camera
    f = cam.focal_length_mm * 1e-3
    pix = cam.pixel_size_um * 1e-6
    centre = np.array([cam.width_px / 2.0, cam.height_px / 2.0])
    K = np.array([[f / pix, 0.0, centre[0]], [0.0, f / pix, centre[1]], [0.0, 0.0, 1.0]])
    edge = cfg.target_model.cube_edge_m
    cube = cube_vertices(edge)

    streams = [[np.random.default_rng(s) for s in child_seeds(ss, 3)] for ss in seeds]
    q_CT = quat_normalize(np.array([a.standard_normal(4) for a, _, _ in streams]))
    R_CT = matrix_from_quat(q_CT)
    r_TC_C = np.broadcast_to([0.0, 0.0, env.range_m], (n, 3)).copy()
    xy, depth = project_focal_plane(cube, R_CT, r_TC_C, focal_length_m=f)
    uv_true = pixels_from_focal_plane(xy, pixel_size_m=pix, principal_point_px=centre)
    in_image = np.all((uv_true >= 0) & (uv_true <= [cam.width_px, cam.height_px]), -1)
    vis = visible_vertices(R_CT, r_TC_C, edge) & (depth > 0) & in_image
    sigma_m = cam.noise_px * pix
    xy = xy + sigma_m * np.array([b.standard_normal((8, 2)) for _, b, _ in streams])
    xy = np.where(vis[..., None], xy, np.nan)
    uv = pixels_from_focal_plane(xy, pixel_size_m=pix, principal_point_px=centre)

    axes = np.array([c.standard_normal(3) for _, _, c in streams])
    shift = np.array([c.standard_normal(3) for _, _, c in streams])  # drawn after the axis, same stream
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    shift /= np.linalg.norm(shift, axis=1, keepdims=True)
    q0 = quat_multiply(quat_from_rotvec(np.radians(env.initial_attitude_error_deg) * axes), q_CT)
    r0 = r_TC_C + env.initial_position_error_frac * env.range_m * shift

    S = len(ENVELOPE_SOLVERS)
    R_est = np.full((n, S, 3, 3), np.nan)
    r_est = np.full((n, S, 3), np.nan)
    reason = np.full((n, S), "", dtype=object)
    res = solve_pose_rodrigues(cube, xy, GibbsPose.from_quat(q0, r0), focal_length_m=f, visible=vis,
                               eps_attitude=cfg.solver.eps_attitude, eps_translation_m=cfg.solver.eps_translation_m,
                               max_iterations=cfg.solver.max_iterations, eta=cfg.solver.eta)
    R_est[:, 0], r_est[:, 0], reason[:, 0] = res.R_CT, res.r_TC_C, res.failure_reason
    R0 = matrix_from_quat(q0)
    for k in range(n):
        P, u = cube[vis[k]], np.ascontiguousarray(uv[k, vis[k]])
        for s, flag, guess in ((1, cv2.SOLVEPNP_SQPNP, None),
                               (2, cv2.SOLVEPNP_ITERATIVE, (cv2.Rodrigues(R0[k])[0], r0[k].reshape(3, 1)))):
            rvec, tvec, why = solve_pnp(flag, P, u, K, guess)
            if why == "":
                R_est[k, s], r_est[k, s] = cv2.Rodrigues(rvec)[0], tvec.ravel()
            reason[k, s] = why

    ok = reason == ""
    u_los = r_TC_C / np.linalg.norm(r_TC_C, axis=1, keepdims=True)
    dr = r_est - r_TC_C[:, None, :]
    along = np.einsum("nsi,ni->ns", dr, u_los)
    across = np.linalg.norm(dr - along[..., None] * u_los[:, None, :], axis=-1)
    phi = np.full((n, S, 3), np.nan)
    phi[ok] = rotvec_from_quat(quat_from_matrix((R_est @ R_CT[:, None].swapaxes(-1, -2))[ok]))
    bound = pose_crlb(cube, R_CT, r_TC_C, focal_length_m=f, pixel_sigma_m=sigma_m, visible=vis)
    e = np.concatenate([phi, dr], -1)  # (n, S, 6)
    C = np.where(bound.ok[:, None, None], bound.covariance, np.eye(6))
    d2 = np.einsum("nsi,nsi->ns", e, np.linalg.solve(C[:, None], np.nan_to_num(e)[..., None])[..., 0])
    mahal = np.where(ok & bound.ok[:, None], np.sqrt(np.maximum(d2, 0.0)), np.nan)
    failed = np.stack([(reason == r) for r in ENVELOPE_REASONS], -1).astype(float)
    return {
        "along_los_error_m": along,
        "across_los_error_m": across,
        "attitude_error_deg": np.degrees(np.linalg.norm(phi, axis=-1)),
        "mahalanobis": mahal,
        "failed": failed,
        "crlb_along_los_m": bound.sigma_along_los_m,
        "crlb_across_los_m": bound.sigma_across_los_m,
        "crlb_attitude_deg": np.degrees(bound.sigma_attitude_rad),
        "n_points": vis.sum(-1).astype(float),
        "failure_reason": np.full(n, "", dtype=object),
    }


def envelope_sweep_cell(cfg: Config) -> SweepCell:
    """The sweep cell of the envelope (:func:`envelope_trials`) with its metrics."""
    del cfg
    return SweepCell(
        fn=envelope_trials,
        metrics={
            "along_los_error_m": Metric("m", ("solver",), long_name="position error along the line of sight"),
            "across_los_error_m": Metric("m", ("solver",), long_name="position error across the line of sight"),
            "attitude_error_deg": Metric("deg", ("solver",), long_name="attitude error angle"),
            "mahalanobis": Metric("1", ("solver",), long_name="sqrt(e^T F e) of the pose error under the bound"),
            "failed": Metric("1", ("solver", "reason"), long_name="solver failed, by reason (one-hot)"),
            "crlb_along_los_m": Metric("m", long_name="Cramer-Rao sigma along the line of sight"),
            "crlb_across_los_m": Metric("m", long_name="Cramer-Rao RMS across the line of sight"),
            "crlb_attitude_deg": Metric("deg", long_name="Cramer-Rao RMS attitude angle"),
            "n_points": Metric("1", long_name="visible cube vertices in the image"),
        },
        coords={"solver": np.array(ENVELOPE_SOLVERS, dtype=object), "reason": np.array(ENVELOPE_REASONS, dtype=object)},
        name="envelope",
    )


def sweep_cell(cfg: Config) -> SweepCell:
    """The sweep cell named by ``cfg.sweep.cell`` (only ``"envelope"``); ``ValueError`` otherwise."""
    name = cfg.sweep.cell if cfg.sweep is not None else ""
    if name != "envelope":
        raise ValueError(f"unknown cell {name!r}; known: envelope")
    return envelope_sweep_cell(cfg)


def envelope_statistics(ds: xr.Dataset) -> xr.Dataset:
    """Per cell and solver, reduced over ``trial``: RMS errors, their bounds, the ratios, failure and gross rates.

    The RMS of each error and the RMS of its per-trial bound (``√mean σ²``) are taken over the trials
    where the solver returned a pose and the bound exists; ``ratio_*`` is their quotient (1 for an
    efficient estimator).  ``failure_rate`` counts the trials without a pose, ``gross_rate`` the
    returned poses with ``mahalanobis > GROSS_MAHALANOBIS`` (of all trials).
    """
    got = ds["failed"].sum("reason") == 0
    use = got & np.isfinite(ds["crlb_attitude_deg"])
    out = {}
    for err, crlb, name in (("along_los_error_m", "crlb_along_los_m", "along_los"),
                            ("across_los_error_m", "crlb_across_los_m", "across_los"),
                            ("attitude_error_deg", "crlb_attitude_deg", "attitude")):
        rms = np.sqrt((ds[err] ** 2).where(use).mean("trial"))
        bnd = np.sqrt((ds[crlb] ** 2).where(use).mean("trial"))
        out[f"rms_{name}"] = rms.assign_attrs(units=ds[err].attrs.get("units", ""))
        out[f"crlb_{name}"] = bnd.assign_attrs(units=ds[err].attrs.get("units", ""))
        out[f"ratio_{name}"] = (rms / bnd).assign_attrs(units="1")
    out["failure_rate"] = (1.0 - got.mean("trial")).assign_attrs(units="1")
    out["gross_rate"] = (ds["mahalanobis"] > GROSS_MAHALANOBIS).mean("trial").assign_attrs(units="1")
    out["failures"] = ds["failed"].sum("trial").assign_attrs(units="1")
    out["median_n_points"] = ds["n_points"].median("trial").assign_attrs(units="1")
    return xr.Dataset(out)


def envelope_run(cfg: Config, *, progress: Callable[[int, int], None] | None = None) -> tuple[xr.Dataset, dict]:
    """The ``envelope`` study: one cell at the config's point with ``envelope.trials`` attitudes."""
    cell = envelope_sweep_cell(cfg)
    seeds = cell_seed_sequences(cfg.seed, {}, cfg.envelope.trials)
    if progress:
        progress(0, 1)
    raw = envelope_trials(cfg, seeds)
    if progress:
        progress(1, 1)
    data = {}
    for name, m in cell.metrics.items():
        data[name] = (("trial", *m.dims), np.asarray(raw[name], dtype=float),
                      {"units": m.units, "long_name": m.long_name})
    ds = xr.Dataset(data, coords={"trial": np.arange(cfg.envelope.trials), **cell.coords},
                    attrs={"study": "envelope", "range_m": cfg.envelope.range_m,
                           "cube_edge_m": cfg.target_model.cube_edge_m, "noise_px": cfg.camera.noise_px})
    st = envelope_statistics(ds)
    summary = {"range_m": cfg.envelope.range_m, "cube_edge_m": cfg.target_model.cube_edge_m,
               "noise_px": cfg.camera.noise_px, "trials": cfg.envelope.trials, "solvers": {}}
    for s in ENVELOPE_SOLVERS:
        d = st.sel(solver=s)
        summary["solvers"][s] = {
            **{k: float(d[k]) for k in ("rms_along_los", "rms_across_los", "rms_attitude", "crlb_along_los",
                                        "crlb_across_los", "crlb_attitude", "ratio_along_los", "ratio_across_los",
                                        "ratio_attitude", "failure_rate", "gross_rate")},
            "failures": {r: int(d["failures"].sel(reason=r)) for r in ENVELOPE_REASONS
                         if int(d["failures"].sel(reason=r))},
        }
    return ds, summary
