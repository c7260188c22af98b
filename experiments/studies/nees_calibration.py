"""σ inflation that makes rendered triangulation consistent (part of ``coobs calibrate``).

The σ per SIFT size (least squares on cross-view residuals of correct matches, in
:mod:`experiments.studies.rendered_calibration`) does not give triangulated points whose error
matches their covariance: keypoints that are matched by only some of the cameras are worse than
those matched by all, a wider camera spread adds view-dependent error, and the residuals are
heavy-tailed (a narrow core and a tail of near-misses), so the second moment the NEES needs is not
the one the pair residuals fit.  This step measures it directly: per target, range and random
attitude (with a random Sun) three cameras at ``angles_deg`` from each other (the symmetric
formation of Experiment A) observe the target as the rendered mode does; the tracks are triangulated
with the size σ and the NEES of every correct point is taken against its truth with the truth's own
error accounted for (:mod:`experiments.studies.triangulation_consistency`).  The same three
renders give the two-camera formation (the first two cameras, matched again).  Per range, angle and
track class — ``"2 of 2"`` (two-camera formation), ``"3 of 3"`` and ``"2 of 3"`` (three cameras,
a track matched in all three or in two of them) — the σ² inflation is the mean NEES over 3.

The mean NEES of one epoch depends on its attitude and Sun far more than on the class (1 to 10 at
one range), and the epoch's own epipolar residuals show much of that
(:func:`vision.epoch_variance.epoch_variance_factor`).  So the step also measures, per range, angle
and class, the inflation beyond each epoch's variance factor (``epoch_sigma2_inflation``: the mean
of NEES / factor over 3; the same for increments), and records how much the epochs' mean NEES spread
with the size σ and over their factors (``epoch_log_nees_spread``).

At run time (:meth:`vision.calibration.SiftCalibration.track_sigma_px`) a keypoint's σ is its size
σ times the square root of the epoch's variance factor and of the inflation beyond it of its
track's class, camera spread and image scale: nothing from the truth.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from attitude.quaternion import matrix_from_quat, quat_from_rotvec, quat_multiply, quat_normalize
from experiments.studies.triangulation_consistency import track_nees
from experiments.sweep import child_seeds
from formation.geometry import symmetric_views
from reconstruction.triangulation import triangulate
from vision.calibration import TRACK_CLASSES, SiftCalibration, track_class
from vision.calibration.scale_mixture import spread_for_median
from vision.camera import PinholeCamera
from vision.epoch_variance import epoch_variance_factor
from vision.features import match_views
from vision.rendered import detect_views, label_tracks, render_views
from vision.sensor import SensorModel
from vision.target import Target, fy1_target, load_mesh

__all__ = ["MATERIAL_PRIOR_POINTS", "NeesSpec", "add_triangulation_nees", "increment_nees", "measure_inflation",
           "track_material"]


@dataclass(frozen=True)
class NeesSpec:
    """What the NEES step measures: ``attitudes`` per target and range, formations of three cameras
    ``angles_deg`` apart (and their first two), Sun within ``sun_phase_max_deg`` of the formation axis,
    a second epoch after the target turned ``step_deg`` about a random axis."""

    attitudes: int = 12
    angles_deg: tuple[float, ...] = (10.0, 20.0)
    step_deg: float = 1.0
    sun_phase_max_deg: float = 150.0
    ratio: float = 0.6
    epipolar_tol_px: float = 1.5
    truth_tol_px: float = 2.0

    def __post_init__(self) -> None:
        if int(self.attitudes) < 1:
            raise ValueError(f"attitudes: must be >= 1, got {self.attitudes!r}")
        if not self.angles_deg or not all(0 < a < 90 for a in self.angles_deg):
            raise ValueError(f"angles_deg: need angles in (0, 90), got {self.angles_deg!r}")


def _epoch(cam, T_CW, kps, renders, target, q, cal, spec):
    """Observation, triangulation, NEES and variance factor (of the size σ) of one epoch (None where
    nothing is matched)."""
    obs = match_views(kps, cam, T_CW, ratio=spec.ratio, epipolar_tol_px=spec.epipolar_tol_px)
    if not obs.ok or obs.n_tracks == 0:
        return None
    obs = dataclasses.replace(obs, track_sigma_px=cal.track_sigma_px(obs, inflate=False))
    obs = label_tracks(obs, renders, target, q, tol_px=spec.truth_tol_px)
    tri = triangulate(obs.uv_px, obs.K, obs.T_CW, pixel_sigma_px=obs.sigma_uv_px)
    s2 = epoch_variance_factor(obs.uv_px, obs.K, obs.T_CW, obs.track_sigma_px)
    return obs, tri, track_nees(obs, tri.X_W, tri.valid, tri.views_used, q, target), s2


def increment_nees(a, b, q_a: np.ndarray, q_b: np.ndarray, tol_m: float) -> tuple[np.ndarray, np.ndarray]:
    """NEES of the change between two epochs of the triangulated body points of the same surface
    features, ``Δᵀ (C_a + C_b)⁻¹ Δ`` in the body frame (3 when the two epochs' errors are independent
    and σ is right), and the indices of the pairs' tracks in epoch a.  ``a``, ``b``: (obs, tri) of
    the two epochs; the truth only pairs the tracks (body points within ``tol_m``)."""
    from scipy.spatial import cKDTree

    (oa, ta), (ob, tb) = a, b
    ia = np.nonzero(ta.valid & (oa.feature_id >= 0))[0]
    ib = np.nonzero(tb.valid & (ob.feature_id >= 0))[0]
    if ia.size == 0 or ib.size == 0:
        return np.zeros(0), ia[:0]
    dist, j = cKDTree(ob.X_T_true[ib]).query(oa.X_T_true[ia], distance_upper_bound=tol_m)
    keep = np.isfinite(dist)
    ia, jb = ia[keep], ib[j[keep]]
    Ra, Rb = matrix_from_quat(q_a), matrix_from_quat(q_b)
    d = tb.X_W[jb] @ Rb - ta.X_W[ia] @ Ra
    S = Ra.T @ ta.cov_W[ia] @ Ra + Rb.T @ tb.cov_W[jb] @ Rb
    return np.einsum("mi,mij,mj->m", d, np.linalg.inv(S), d), ia


def track_material(target: Target, X_T: np.ndarray) -> np.ndarray:
    """Material index of the triangle closest to each body point (``-1`` for NaN points)."""
    import open3d as o3d

    X = np.asarray(X_T, dtype=float).reshape(-1, 3)
    out = np.full(len(X), -1, dtype=np.int64)
    ok = np.isfinite(X).all(axis=1)
    if ok.any():
        cp = target.scene.compute_closest_points(o3d.core.Tensor(X[ok].astype(np.float32)))
        out[ok] = target.triangle_material[cp["primitive_ids"].numpy().astype(np.int64)]
    return out


def _material_factor(sums: np.ndarray, table: np.ndarray, prior_points: float) -> np.ndarray:
    """Per material, the NEES summed over (angle, class) over what the class table (mean NEES) predicts
    for the same points, ``sums (A, C, P, 2)`` (sum, count), ``table (A, C)``; with ``prior_points``
    pseudo-points at factor 1 (a material seen little stays near 1; NEES are heavy-tailed, so the mean
    of a few is far from its expectation).  Without them the factors, weighted by the NEES the tables
    predict, average to 1."""
    expected = np.einsum("ac,acp->p", np.nan_to_num(table), sums[..., 1])
    n = sums[..., 1].sum(axis=(0, 1))
    per_point = np.divide(expected, n, out=np.zeros_like(expected), where=n > 0)
    prior = prior_points * per_point
    return np.divide(sums[..., 0].sum(axis=(0, 1)) + prior, expected + prior,
                     out=np.ones_like(expected), where=expected + prior > 0)


#: degrees of freedom of a triangulated point's NEES per track class (a two-view track's first view
#: error along the epipolar line cancels against the truth's: rank 2, :mod:`.triangulation_consistency`)
TRIANGULATION_DOF = np.array([2 if c.startswith("2 ") else 3 for c in TRACK_CLASSES])
#: pseudo-points at factor 1 in each material's σ² factor
MATERIAL_PRIOR_POINTS = 100


def _material_stats(records: list, table: np.ndarray, n_materials: int, dof_of_class: np.ndarray) -> tuple:
    """Of one range's points (``records``: arrays of rows angle index, class, material, NEES; ``table``
    (A, C) the class tables' mean NEES): each material's σ² factor (:func:`_material_factor`) and points;
    the median and mean of 3 NEES / (table × factor), the spread of the errors beyond the tables and
    factors (mean 3, and the χ² median of each point's degrees of freedom ``dof_of_class``, for
    Gaussian errors whose σ is right); and the lognormal scale spread that gives that median
    (:func:`vision.calibration.scale_mixture.spread_for_median`)."""
    r = np.concatenate(records) if records else np.zeros((0, 4))
    a, c, m = (r[:, i].astype(int) for i in range(3))
    on = m >= 0
    sums = np.zeros((*table.shape, n_materials, 2))
    np.add.at(sums, (a[on], c[on], m[on]), np.c_[r[on, 3], np.ones(int(on.sum()))])
    f = _material_factor(sums, table, MATERIAL_PRIOR_POINTS)
    points = sums[..., 1].sum(axis=(0, 1)).astype(int)
    norm = 3.0 * r[on, 3] / (table[a[on], c[on]] * f[m[on]])
    ok = np.isfinite(norm)
    if not ok.any():
        return f, points, np.nan, np.nan, np.nan
    median = float(np.median(norm[ok]))
    dofs = dof_of_class[c[on][ok]]
    spread = spread_for_median(median, {int(k): int(np.sum(dofs == k)) for k in np.unique(dofs)})
    return f, points, median, float(np.mean(norm[ok])), spread


def _sun(g: np.random.Generator, axis: np.ndarray, max_deg: float) -> np.ndarray:
    while True:
        sun = g.normal(size=3)
        sun /= np.linalg.norm(sun)
        if np.degrees(np.arccos(np.clip(sun @ axis, -1, 1))) <= max_deg:
            return sun


class _Sums:
    """Per (angle, class) lists of one range's statistics."""

    def __init__(self, A: int, Cn: int):
        self.v = {k: [[[] for _ in range(Cn)] for _ in range(A)] for k in ("nees", "plain", "inc", "nees_epoch",
                                                                           "inc_epoch")}

    def add(self, key: str, a: int, cls: np.ndarray, values: np.ndarray) -> None:
        for c in range(len(self.v[key][a])):
            self.v[key][a][c].append(values[cls == c])

    def table(self, key: str, fn) -> np.ndarray:
        return np.array([[fn(np.concatenate(c)) if c and sum(x.size for x in c) else np.nan for c in per_a]
                         for per_a in self.v[key]])


def measure_inflation(target: Target, cal: SiftCalibration, ranges_m: tuple[float, ...],
                      seeds: list[list[np.random.SeedSequence]], spec: NeesSpec, camera: PinholeCamera, *,
                      progress: Callable[[], None] | None = None) -> dict:
    """The NEES tables of one target: ``seeds[r]`` holds the attitude seed sequences of range r (the
    NEES step takes the third child of each, so the other calibration draws are unchanged)."""
    A, Cn = len(spec.angles_deg), len(TRACK_CLASSES)
    tabs = {k: [] for k in ("mean", "median", "plain", "inc", "inc_median", "n", "n_inc", "epoch", "inc_epoch",
                            "mat", "mat_inc", "mat_n", "mat_n_inc", "norm_median", "norm_median_inc", "norm_mean",
                            "norm_mean_inc", "spread", "spread_inc")}
    P = len(target.materials)
    per_epoch = []                       # (mean NEES of the size σ, variance factor) of epochs with >= 8 points
    f_px = float(np.sqrt(camera.K[0, 0] * camera.K[1, 1]))
    for range_m in ranges_m:
        acc = _Sums(A, Cn)
        recs = {"nees": [], "inc": []}       # per point: angle index, class, material, NEES
        for ss in seeds[ranges_m.index(range_m)][: int(spec.attitudes)]:
            g = np.random.default_rng(child_seeds(ss, 3)[2])
            q = quat_normalize(g.normal(size=4))
            turn = g.normal(size=3)
            q2 = quat_normalize(quat_multiply(quat_from_rotvec(np.radians(spec.step_deg) * turn / np.linalg.norm(turn)), q))
            for a, ang in enumerate(spec.angles_deg):
                views = symmetric_views(3, float(range_m), float(ang))
                axis = -np.mean(views.T_CW[:, 2, :3], axis=0)  # from the target towards the cameras
                sun = _sun(g, axis / np.linalg.norm(axis), spec.sun_phase_max_deg)
                epochs = []
                for q_e in (q, q2):
                    renders = render_views(camera, views.T_CW, target, q_e, sun, rng=g)
                    epochs.append((renders, detect_views(renders) if sum(x.ok for x in renders) == 3 else None))
                if epochs[0][1] is None:
                    continue
                for n_cam in (3, 2):
                    ea = _epoch(camera, views.T_CW[:n_cam], epochs[0][1][:n_cam], epochs[0][0][:n_cam], target, q,
                                cal, spec)
                    if ea is None:
                        continue
                    obs, tri, res, s2 = ea
                    cls = track_class(res.n_views, n_cam)
                    acc.add("nees", a, cls, res.nees)
                    acc.add("nees_epoch", a, cls, res.nees / s2)
                    acc.add("plain", a, cls, res.nees_plain)
                    mat = track_material(target, obs.X_T_true)                 # every track's surface
                    recs["nees"].append(np.c_[np.full(cls.size, a), cls, mat[res.index], res.nees])
                    if res.nees.size >= 8:
                        per_epoch.append((float(np.mean(res.nees)), s2))
                    eb = None if epochs[1][1] is None else _epoch(camera, views.T_CW[:n_cam], epochs[1][1][:n_cam],
                                                                   epochs[1][0][:n_cam], target, q2, cal, spec)
                    if eb is not None:
                        v, ia = increment_nees((obs, tri), eb[:2], q, q2, float(range_m) / f_px)
                        ci = track_class(tri.views_used[ia].sum(axis=1), n_cam)
                        acc.add("inc", a, ci, v)
                        acc.add("inc_epoch", a, ci, v / s2)
                        recs["inc"].append(np.c_[np.full(v.size, a), ci, mat[ia], v])
            if progress:
                progress()
        tabs["mean"].append(acc.table("nees", np.mean))
        tabs["median"].append(acc.table("nees", np.median))
        tabs["plain"].append(acc.table("plain", np.mean))
        tabs["n"].append(acc.table("nees", np.size))
        tabs["inc"].append(acc.table("inc", np.mean))
        tabs["inc_median"].append(acc.table("inc", np.median))
        tabs["n_inc"].append(acc.table("inc", np.size))
        tabs["epoch"].append(acc.table("nees_epoch", np.mean))
        tabs["inc_epoch"].append(acc.table("inc_epoch", np.mean))
        for key, table, suffix, dof in (("nees", tabs["mean"][-1], "", TRIANGULATION_DOF),
                                        ("inc", tabs["inc"][-1], "_inc", np.full(Cn, 3))):
            f, n, med, mean, spread = _material_stats(recs[key], table, P, dof)
            tabs["mat" + suffix].append(f)
            tabs["mat_n" + suffix].append(n.tolist())
            tabs["norm_median" + suffix].append(med)
            tabs["norm_mean" + suffix].append(mean)
            tabs["spread" + suffix].append(spread)

    def rows(x, nd=4):
        return [[[None if not np.isfinite(v) else round(float(v), nd) for v in c] for c in a] for a in x]

    return {
        "angle_deg": list(spec.angles_deg),
        "classes": list(TRACK_CLASSES),
        "sigma2_inflation": rows(np.array(tabs["mean"]) / 3.0),
        "increment_sigma2_inflation": rows(np.array(tabs["inc"]) / 3.0),
        "epoch_sigma2_inflation": rows(np.array(tabs["epoch"]) / 3.0),
        "epoch_increment_sigma2_inflation": rows(np.array(tabs["inc_epoch"]) / 3.0),
        "epoch_log_nees_spread": _spread(per_epoch),
        "material_sigma2_factor": [[round(float(v), 4) for v in r] for r in tabs["mat"]],
        "material_increment_sigma2_factor": [[round(float(v), 4) for v in r] for r in tabs["mat_inc"]],
        "material_points": tabs["mat_n"],
        "material_increment_pairs": tabs["mat_n_inc"],
        "normalized_nees_median": [round(float(v), 4) for v in tabs["norm_median"]],
        "normalized_nees_mean": [round(float(v), 4) for v in tabs["norm_mean"]],
        "normalized_increment_nees_median": [round(float(v), 4) for v in tabs["norm_median_inc"]],
        "normalized_increment_nees_mean": [round(float(v), 4) for v in tabs["norm_mean_inc"]],
        "error_log_spread": [round(float(v), 4) for v in tabs["spread"]],
        "increment_error_log_spread": [round(float(v), 4) for v in tabs["spread_inc"]],
        "points": np.nan_to_num(np.array(tabs["n"])).astype(int).tolist(),
        "increment_pairs": np.nan_to_num(np.array(tabs["n_inc"])).astype(int).tolist(),
        "nees_mean_size_sigma": rows(tabs["mean"], 3),
        "nees_median_size_sigma": rows(tabs["median"], 3),
        "nees_plain_mean_size_sigma": rows(tabs["plain"], 3),
        "increment_nees_mean_size_sigma": rows(tabs["inc"], 3),
        "increment_nees_median_size_sigma": rows(tabs["inc_median"], 3),
        "spec": {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(spec).items()},
    }


def _spread(per_epoch: list) -> dict:
    """How much the epochs' mean NEES spread (standard deviation of its logarithm), with the size σ and
    over each epoch's variance factor; and their correlation."""
    if len(per_epoch) < 3:
        return {"epochs": len(per_epoch)}
    nees, s2 = np.log(np.array(per_epoch)).T
    return {"epochs": len(per_epoch), "size_sigma": round(float(np.std(nees)), 3),
            "over_epoch_factor": round(float(np.std(nees - s2)), 3),
            "correlation": round(float(np.corrcoef(nees, s2)[0, 1]), 3)}


def add_triangulation_nees(data: dict, spec: NeesSpec, *, command: str = "",
                           progress: Callable[[], None] | None = None) -> dict:
    """A calibration dict with each target's ``triangulation_nees`` table measured (and recorded in
    its provenance), using the dict's own σ per size and, from its provenance, the targets, ranges,
    camera and root seed of the run that made it (the attitudes are the first ``spec.attitudes`` of
    that run's, their NEES draws independent of its other draws)."""
    import time

    t0 = time.perf_counter()
    run = data["provenance"]["spec"]
    camera = PinholeCamera.from_fov(int(run["image_px"]), int(run["image_px"]), fov_x_deg=float(run["fov_deg"]))
    names = list(data["targets"])
    per_target = child_seeds(np.random.SeedSequence(int(run["seed"])), len(run["targets"]))
    out = {**data, "format_version": max(3, int(data.get("format_version", 1))), "targets": dict(data["targets"])}
    for name in names:
        ss_t = per_target[list(run["targets"]).index(name)]
        t = out["targets"][name]
        ranges = tuple(float(r) for r in t["ranges_m"])
        seeds = [child_seeds(ss_r, int(spec.attitudes)) for ss_r in child_seeds(ss_t, len(ranges))]
        cal = SiftCalibration.from_dict(data, name)
        out["targets"][name] = {**t, "triangulation_nees": measure_inflation(
            fy1_target() if name == "fy1" else load_mesh(name), cal, ranges, seeds, spec, camera, progress=progress)}
    out["provenance"] = {**data["provenance"], "triangulation_nees": {
        "command": command, "function": "experiments.studies.nees_calibration.add_triangulation_nees",
        "created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "wall_s": round(time.perf_counter() - t0, 1),
        "spec": {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(spec).items()},
        "truth": "experiments.studies.triangulation_consistency (truth point's own error accounted for)",
        "renderer": {"function": "vision.rendered.render_views", "sensor": dataclasses.asdict(SensorModel()),
                     "detector": "vision.rendered.detect_views (sift)", "matching": "vision.features.match_views"}}}
    return out
