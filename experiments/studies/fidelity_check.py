"""The fidelity check of issue 16: rendered vs fixed-noise vs calibrated geometric mode, cell by cell.

For each cell of the check grid (views × range × line-of-sight angle) every trial of 003 Experiment
A (random initial attitude, then ``steps`` increments of ``error_map.step_deg``; the trials' seeds
are those of ``coobs run``/``coobs sweep`` of the error-map study, so all modes see the same
attitudes) is observed once, triangulated once, and registered twice: with the covariance-aware
maximum-likelihood fit (``ml``) and with the robust Kabsch fit (``ransac``).  Per trial it records
the median tracks per epoch, the per-step RMS error of both fits, the Cramér–Rao bound of each step
with the observation's own σ per track and view (``Observation.sigma_uv_px``), and the
triangulation NEES of every correct point (truth from ``X_T_true``; in the rendered modes with the
truth point's own error accounted for, :mod:`experiments.studies.triangulation_consistency`, the
plain statistic beside it).

``python -m experiments.studies.fidelity_check --help`` runs it, ``--table`` prints the comparison
(``docs/reproduction.md``) and ``--paired-table`` the per-trial ratios of two modes, which the trials'
common attitudes make far steadier than the ratio of two medians; ``--split-table`` how far one
mode's medians over disjoint runs of trials agree with each other (what a number of trials can tell).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from attitude.quaternion import (
    matrix_from_quat,
    quat_from_matrix,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    rotvec_from_quat,
)
from closed_loop import OBSERVERS, REGISTRARS, Frame, GeometricObserver, reconstruct_many
from experiments.studies.triangulation_consistency import track_nees
from experiments.sweep import cell_seed_sequences, child_seeds
from formation.geometry import symmetric_views
from reconstruction.accuracy import attitude_increment_crlb
from reconstruction.triangulation import triangulate_from_observation
from vision.calibration import load_calibration
from vision.camera import PinholeCamera
from vision.target import Target, fy1_target, load_mesh

__all__ = ["MODES", "CheckCell", "check_cell", "median_interval", "median_ratio_interval", "nees_of_frame",
           "paired_ratio_interval", "paired_table", "pooled_mean_interval", "same_surface_points", "split_table",
           "main"]

#: mode name → (observer, noise model)
MODES = {
    "rendered": ("rendered", "calibrated"),
    "rendered_fixed": ("rendered", "fixed"),
    "geometric_fixed": ("geometric", "fixed"),
    "geometric_calibrated": ("geometric", "calibrated"),
}


@dataclass(frozen=True)
class CheckCell:
    """One cell of the check grid; the defaults are those of ``experiments/configs/003_fig5_fig6_rendered.toml``
    (seed 2021, 10 steps of [0.5, 0.5, 0.5] deg, Sun along H = [1, -0.5, 0.6], 1024 px, 20 deg)."""

    target: str = "fy1"
    mode: str = "rendered"
    n_views: int = 3
    distance_m: float = 40.0
    axis_angle_deg: float = 10.0
    trials: int = 20
    steps: int = 10
    step_deg: tuple[float, float, float] = (0.5, 0.5, 0.5)
    seed: int = 2021
    sun_H: tuple[float, float, float] = (1.0, -0.5, 0.6)
    image_px: int = 1024
    fov_deg: float = 20.0


def nees_of_frame(frame: Frame, q_HT: np.ndarray) -> np.ndarray:
    """Triangulation NEES ``(X̂ − X)ᵀ C⁻¹ (X̂ − X)`` of the frame's valid, correct points (3 dof)."""
    obs, tri = frame.obs, frame.tri
    good = np.asarray(tri.valid) & (obs.feature_id >= 0)
    if not good.any():
        return np.zeros(0)
    X_true = obs.X_T_true[good] @ matrix_from_quat(q_HT).T
    d = tri.X_W[good] - X_true
    return np.einsum("mi,mij,mj->m", d, np.linalg.inv(tri.cov_W[good]), d)


def same_surface_points(prev, curr, *, tol_px: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Correct tracks of two epochs on the same surface point (truth): body points within ``tol_px``
    pixel footprints at the cameras' range; each later track paired at most once."""
    from scipy.spatial import cKDTree

    ia, ib = np.flatnonzero(prev.feature_id >= 0), np.flatnonzero(curr.feature_id >= 0)
    if ia.size == 0 or ib.size == 0:
        return ia[:0], ib[:0]
    range_m = float(np.median(np.linalg.norm(prev.T_CW[:, :3, 3], axis=-1)))
    d, j = cKDTree(curr.X_T_true[ib]).query(prev.X_T_true[ia], distance_upper_bound=tol_px * range_m
                                            / float(np.min(prev.K[:, 0, 0])))
    keep = np.isfinite(d)
    ia, j, d = ia[keep], j[keep], d[keep]
    order = np.lexsort((d, j))
    first = np.ones(order.size, bool)
    first[1:] = j[order][1:] != j[order][:-1]
    return ia[order[first]], ib[j[order[first]]]


def _crlb_rad(prev: Frame, curr: Frame, q_HT: np.ndarray, dR: np.ndarray, sigma_of=None) -> float:
    """Bound of one increment: the points tracked at both epochs, each epoch's views and σ per track and view
    (the observation's; ``sigma_of(obs)`` gives another σ per track and view)."""
    ip, ic = same_surface_points(prev.obs, curr.obs)
    if ip.size < 3:
        return float("nan")
    X_W = prev.obs.X_T_true[ip] @ matrix_from_quat(q_HT).T
    s_prev, s_curr = prev.obs.sigma_uv_px, curr.obs.sigma_uv_px
    if sigma_of is not None:
        s_prev = np.where(prev.obs.seen, sigma_of(prev.obs), s_prev)
        s_curr = np.where(curr.obs.seen, sigma_of(curr.obs), s_curr)
    b = attitude_increment_crlb(X_W, prev.obs.K, prev.obs.T_CW, pixel_sigma_px=s_prev[ip],
                                pixel_sigma_px_next=s_curr[ic], visible=prev.obs.seen[ip],
                                visible_next=curr.obs.seen[ic], R_delta=dR)
    return float(b.rms_angle_rad) if bool(b.ok) else float("nan")


def _target(name: str) -> Target:
    return fy1_target() if name == "fy1" else load_mesh(name)


def check_cell(cell: CheckCell) -> dict:
    """One cell in one mode: per-trial tracks, ML / robust-Kabsch per-step RMS, CRLB, NEES."""
    kind, noise = MODES[cell.mode]
    camera = PinholeCamera.from_fov(cell.image_px, cell.image_px, fov_x_deg=cell.fov_deg)
    observer = OBSERVERS[kind](camera=camera, target=_target(cell.target), noise_model=noise)
    # the Cauchy-kernel ML fit last, so that the other two draw from the registration stream as before it
    regs = {"ml": REGISTRARS["ml"](), "ransac": REGISTRARS["ransac"](), "ml_cauchy": REGISTRARS["ml"](kernel="cauchy")}
    T_CW = symmetric_views(cell.n_views, cell.distance_m, cell.axis_angle_deg).T_CW
    dtheta = np.deg2rad(np.asarray(cell.step_deg, dtype=float))
    dq = quat_from_rotvec(dtheta)
    dR = matrix_from_quat(dq)
    steps = cell.steps
    sun = np.asarray(cell.sun_H, dtype=float)
    sun = sun / np.linalg.norm(sun)
    seeds = cell_seed_sequences(cell.seed, {}, cell.trials)
    cal = load_calibration(observer.target.name) if (kind, noise) == ("rendered", "calibrated") else None
    # the rendered calibrated mode also gives the bound with the increment σ and, as before issue 16's
    # σ inflation, the bound and the NEES with the size σ alone
    # (and, as before the epoch variance factor, with the table's inflation alone)
    sigmas = {} if cal is None else {"_increment": lambda o: cal.track_sigma_px(o, increment=True),
                                     "_size": lambda o: cal.track_sigma_px(o, inflate=False),
                                     "_table": lambda o: cal.track_sigma_px(o, epoch_scale=False)}
    out = {k: [] for k in ("tracks", *(f"{r}_{p}" for r in regs for p in ("step_rms_deg", "failed_steps")), "crlb_deg",
                           *(f"{p}{key}" for key in ("", *sigmas) for p in ("ml_over_crlb", "ml_cauchy_over_crlb")),
                           *(f"crlb_deg{key}" for key in sigmas), "false_track_fraction", "pairs_per_step",
                           "trial_nees_sum", "trial_nees_count")}
    nees = {k: [] for k in ("nees", "nees_plain", "nees_size", "nees_size_plain", "nees_table", "nees_table_plain")}
    for ss in seeds:
        s_att, s_obs, s_reg = child_seeds(ss, 3)
        qs = [quat_normalize(np.random.default_rng(s_att).normal(size=4))]  # as error_map.random_attitudes
        for _ in range(steps):
            qs.append(quat_normalize(quat_multiply(dq, qs[-1])))
        qs = np.array(qs)
        if isinstance(observer, GeometricObserver):
            obs = observer.observe_epochs(np.broadcast_to(T_CW, (steps + 1, *T_CW.shape)), qs,
                                          np.broadcast_to(sun, (steps + 1, 3)), rng=np.random.default_rng(s_obs))
        else:
            rngs = np.random.default_rng(s_obs).spawn(steps + 1)
            obs = [observer.observe(T_CW, qs[k], sun, rng=rngs[k]) for k in range(steps + 1)]
        frames = reconstruct_many(obs)
        first_nees = len(nees["nees"])
        out["tracks"].append(float(np.median([f.obs.n_tracks for f in frames])))
        n_all = sum(f.obs.n_tracks for f in frames)
        out["false_track_fraction"].append(sum(int(np.sum(f.obs.feature_id < 0)) for f in frames) / max(n_all, 1))
        for k, f in enumerate(frames):
            plain = nees_of_frame(f, qs[k])
            nees["nees_plain"].append(plain)
            if kind == "rendered" and f.tri.X_W.size:
                nees["nees"].append(track_nees(f.obs, f.tri.X_W, f.tri.valid, f.tri.views_used, qs[k],
                                               observer.target).nees)
            else:
                nees["nees"].append(plain)
            for key in ("_size", "_table"):
                if key in sigmas and f.obs.ok and f.obs.n_tracks:
                    o = dataclasses.replace(f.obs, track_sigma_px=sigmas[key](f.obs))
                    fs = Frame(obs=o, tri=triangulate_from_observation(o))
                    nees[f"nees{key}_plain"].append(nees_of_frame(fs, qs[k]))
                    nees[f"nees{key}"].append(track_nees(o, fs.tri.X_W, fs.tri.valid, fs.tri.views_used, qs[k],
                                                         observer.target).nees)
        trial_nees = np.concatenate(nees["nees"][first_nees:]) if len(nees["nees"]) > first_nees else np.zeros(0)
        out["trial_nees_sum"].append(float(np.sum(trial_nees)))       # the trial's NEES, for the pooled mean's interval
        out["trial_nees_count"].append(float(trial_nees.size))
        bounds = {"": np.array([_crlb_rad(frames[k - 1], frames[k], qs[k - 1], dR) for k in range(1, steps + 1)])}
        for key, fn in sigmas.items():
            bounds[key] = np.array([_crlb_rad(frames[k - 1], frames[k], qs[k - 1], dR, fn) for k in range(1, steps + 1)])
        out["pairs_per_step"].append(float(np.median([len(same_surface_points(frames[k - 1].obs, frames[k].obs)[0])
                                                      for k in range(1, steps + 1)])))
        reg_rng = np.random.default_rng(s_reg)
        errs = {}
        for name, reg in regs.items():
            e = []
            for k in range(1, steps + 1):
                inc = reg.register(frames[k - 1], frames[k], rng=reg_rng, with_covariance=False)
                e.append(np.linalg.norm(rotvec_from_quat(quat_from_matrix(inc.R_H @ dR.T))) if inc.ok else np.nan)
            errs[name] = np.array(e)
            ok = np.isfinite(errs[name])
            out[f"{name}_failed_steps"].append(float(steps - ok.sum()))
            out[f"{name}_step_rms_deg"].append(float(np.degrees(np.sqrt(np.mean(errs[name][ok] ** 2))))
                                               if ok.any() else float("nan"))
        for key, bound in bounds.items():
            ok = np.isfinite(bound)
            out[f"crlb_deg{key}"].append(float(np.degrees(np.sqrt(np.mean(bound[ok] ** 2)))) if ok.any() else float("nan"))
            for name in ("ml", "ml_cauchy"):
                both = ok & np.isfinite(errs[name])
                out[f"{name}_over_crlb{key}"].append(float(np.sqrt(np.mean(errs[name][both] ** 2)
                                                                   / np.mean(bound[both] ** 2)))
                                                     if both.any() else float("nan"))
    res = {"per_trial": out}
    for key, parts in nees.items():
        v = np.concatenate(parts) if parts else np.zeros(0)
        res[f"{key}_mean"] = float(np.mean(v)) if v.size else float("nan")
        res[f"{key}_median"] = float(np.median(v)) if v.size else float("nan")
        res[f"{key}_points"] = int(v.size)
    return res


def _summary(res: dict) -> dict:
    p = res["per_trial"]
    med = {k: float(np.nanmedian(v)) if np.isfinite(v).any() else float("nan")
           for k, v in ((k, np.asarray(v, dtype=float)) for k, v in p.items())}
    # pooled ML error over pooled bound: RMS over the trials of the per-trial ratios' squares
    for name in (f"{m}_over_crlb{key}" for m in ("ml", "ml_cauchy") for key in ("", "_increment", "_size", "_table")):
        if name not in p:
            continue
        r = np.asarray(p[name], dtype=float)
        med[f"{name}_pooled"] = float(np.sqrt(np.nanmean(r**2))) if np.isfinite(r).any() else float("nan")
    return {**med, **{k: v for k, v in res.items() if k.startswith("nees")}}


def median_ratio_interval(num: Sequence[float], den: Sequence[float], *, level: float = 0.9,
                          draws: int = 2000, seed: int = 0) -> tuple[float, float, float]:
    """Ratio of the medians of two sets of per-trial values and its bootstrap interval (percentile,
    ``level``, the trials of each set resampled independently; non-finite values dropped): what the
    medians of a few trials can tell apart."""
    a = np.asarray(num, dtype=float)
    b = np.asarray(den, dtype=float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if a.size == 0 or b.size == 0 or not np.median(b) > 0:
        return float("nan"), float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    ra = np.median(rng.choice(a, (draws, a.size)), axis=1)
    rb = np.median(rng.choice(b, (draws, b.size)), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = ra / rb
    lo, hi = np.nanquantile(r, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return float(np.median(a) / np.median(b)), float(lo), float(hi)


def paired_ratio_interval(num: Sequence[float], den: Sequence[float], *, level: float = 0.9,
                          draws: int = 2000, seed: int = 0) -> tuple[float, float, float]:
    """Median over the trials of the per-trial ratio ``num[i] / den[i]`` (the same trial's attitudes
    and seeds in both runs; trials where either is not finite or ``den`` is not positive dropped) and
    its bootstrap interval (percentile, ``level``, the trials resampled): the systematic difference
    between two modes, without the spread between the trials that the ratio of two medians carries."""
    a = np.asarray(num, dtype=float)
    b = np.asarray(den, dtype=float)
    n = min(a.size, b.size)
    a, b = a[:n], b[:n]
    ok = np.isfinite(a) & np.isfinite(b) & (b > 0)
    return median_interval(a[ok] / b[ok], level=level, draws=draws, seed=seed)


def median_interval(values: Sequence[float], *, level: float = 0.9, draws: int = 2000,
                    seed: int = 0) -> tuple[float, float, float]:
    """Median of the per-trial ``values`` (non-finite ones dropped) and its bootstrap interval
    (percentile, ``level``, the trials resampled); NaN for all three when nothing is left."""
    r = np.asarray(values, dtype=float)
    r = r[np.isfinite(r)]
    if r.size == 0:
        return float("nan"), float("nan"), float("nan")
    boot = np.median(np.random.default_rng(seed).choice(r, (draws, r.size)), axis=1)
    lo, hi = np.quantile(boot, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return float(np.median(r)), float(lo), float(hi)


#: the metrics compared per cell: result key, column title, number format
_METRICS = (("tracks", "tracks per epoch", "{:.0f}"), ("ml_step_rms_deg", "ML per-step RMS (deg)", "{:.3f}"),
            ("ransac_step_rms_deg", "robust Kabsch per-step RMS (deg)", "{:.3f}"), ("crlb_deg", "CRLB (deg)", "{:.3f}"))


def _cell_of(res: dict, key: tuple) -> dict:
    hit = next((x for x in res["cells"] if (x["n_views"], x["distance_m"], x["axis_angle_deg"]) == key), None)
    if hit is None:
        raise ValueError(f"cell {key} (views, distance_m, axis_angle_deg) is in one result file but not in the "
                         "other: run the same grid")
    return hit


def paired_table(rendered: dict, calibrated: dict) -> str:
    """Per cell of ``calibrated`` and metric: the median per-trial ratio calibrated / rendered and its 90 % bootstrap
    interval (:func:`paired_ratio_interval`); ✓ within ±25 %, ~ not but the interval reaches into it,
    nothing where the trials show a difference beyond 25 %.  Last line: the count of each mark."""
    head = "| views, range, angle | trials | " + " | ".join(m[1] for m in _METRICS) + " |"
    lines = [head, "|---" * (len(_METRICS) + 2) + "|"]
    marks = {"✓": 0, "~": 0, "": 0}
    for g in calibrated["cells"]:                  # the cells run in the geometric mode
        key = (g["n_views"], g["distance_m"], g["axis_angle_deg"])
        c = _cell_of(rendered, key)
        n = min(len(x["per_trial"]["tracks"]) for x in (c, g))
        row = [f"{key[0]}, {key[1]:g} m, {key[2]:g}°", str(n)]
        for k, _, _ in _METRICS:
            r, lo, hi = paired_ratio_interval(g["per_trial"][k][:n], c["per_trial"][k][:n])
            mark = "✓" if abs(r - 1.0) <= 0.25 else "~" if lo <= 1.25 and hi >= 0.75 else ""
            marks[mark] += 1
            row.append(f"{r:.2f} [{lo:.2f}–{hi:.2f}]{' ' + mark if mark else ''}")
        lines.append("| " + " | ".join(row) + " |")
    lines.append(f"\nwithin ±25 %: {marks['✓']}; undecided (~): {marks['~']}; beyond: {marks['']}")
    return "\n".join(lines)


def pooled_mean_interval(sums: Sequence[float], counts: Sequence[float], *, level: float = 0.9, draws: int = 2000,
                         seed: int = 0) -> tuple[float, float, float]:
    """Mean of values pooled over trials (``sums`` and ``counts`` per trial, trials without values
    dropped) and its bootstrap interval (percentile, ``level``, the trials resampled: the values of
    one trial share its attitude and are not independent)."""
    a, n = np.asarray(sums, dtype=float), np.asarray(counts, dtype=float)
    ok = np.isfinite(a) & (n > 0)
    a, n = a[ok], n[ok]
    if a.size == 0:
        return float("nan"), float("nan"), float("nan")
    pick = np.random.default_rng(seed).integers(0, a.size, (draws, a.size))
    boot = a[pick].sum(axis=1) / n[pick].sum(axis=1)
    lo, hi = np.quantile(boot, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return float(a.sum() / n.sum()), float(lo), float(hi)


def split_table(result: dict, size: int = 20) -> str:
    """The sampling floor of the ±25 % criterion, from one result file: per cell and metric, the medians
    of its disjoint runs of ``size`` consecutive trials (other attitudes, the same mode) and how many
    ordered pairs of runs (each run in turn the reference) have a ratio of medians within ±25 %.  Two
    modes compared on ``size`` trials whose attitudes are not shared can do no better than a mode
    against itself.  Last line: the counts per metric and in all."""
    if size < 1:
        raise ValueError(f"size must be >= 1 trial, got {size!r}")
    head = "| views, range, angle | runs | " + " | ".join(m[1] for m in _METRICS) + " |"
    lines = [head, "|---" * (len(_METRICS) + 2) + "|"]
    count = {k: [0, 0] for k, _, _ in _METRICS}
    for c in result["cells"]:
        runs = len(c["per_trial"]["tracks"]) // size
        if runs < 2:
            raise ValueError(f"cell ({c['n_views']}, {c['distance_m']:g} m, {c['axis_angle_deg']:g}°) has "
                             f"{len(c['per_trial']['tracks'])} trials: fewer than two runs of size {size}")
        row = [f"{c['n_views']}, {c['distance_m']:g} m, {c['axis_angle_deg']:g}°", str(runs)]
        for k, _, fmt in _METRICS:
            v = np.asarray(c["per_trial"][k][:runs * size], dtype=float).reshape(runs, size)
            med = np.array([np.median(x[np.isfinite(x)]) if np.isfinite(x).any() else np.nan for x in v])
            ratio = med[:, None] / med[None, :]
            pairs = ~np.eye(runs, dtype=bool)
            hit = int(np.sum(np.abs(ratio[pairs] - 1.0) <= 0.25))
            count[k][0] += hit
            count[k][1] += int(pairs.sum())
            row.append(f"{fmt.format(np.nanmin(med))}–{fmt.format(np.nanmax(med))} ({hit}/{int(pairs.sum())})")
        lines.append("| " + " | ".join(row) + " |")
    total = [sum(v[i] for v in count.values()) for i in (0, 1)]
    lines.append("\nwithin ±25 % of each other: " + "; ".join(f"{t} {count[k][0]}/{count[k][1]}" for k, t, _ in _METRICS)
                 + f"; in all {total[0]}/{total[1]}")
    return "\n".join(lines)


def markdown_table(rendered: dict, fixed: dict, calibrated: dict) -> str:
    """Per cell: rendered / fixed geometric / calibrated geometric medians over the trials the three
    runs have in common (the first ones: the trial seeds do not depend on the count); ✓ where the
    calibrated value is within ±25 % of the rendered one (not for the failed steps); ~ where it is
    not but the 90 % bootstrap interval of the ratio (:func:`median_ratio_interval`) reaches into
    ±25 %: the trials cannot tell."""
    keys = (*_METRICS, ("ml_failed_steps", "ML failed steps", "{:.1f}"),
            ("ml_cauchy_step_rms_deg", "ML, Cauchy kernel, per-step RMS (deg)", "{:.3f}"))
    # result files written before the Cauchy kernel lack its column
    keys = tuple(k for k in keys if all(k[0] in x["per_trial"] for res in (rendered, fixed, calibrated)
                                        for x in res["cells"]))
    head = "| views, range, angle | trials | " + " | ".join(k[1] for k in keys) + " |"
    lines = [head, "|---" * (len(keys) + 2) + "|"]

    def median(cell, k, n):
        v = np.asarray(cell["per_trial"][k][:n], dtype=float)
        return float(np.median(v[np.isfinite(v)])) if np.isfinite(v).any() else float("nan")

    for c in rendered["cells"]:
        key = (c["n_views"], c["distance_m"], c["axis_angle_deg"])
        f, g = _cell_of(fixed, key), _cell_of(calibrated, key)
        n = min(len(x["per_trial"]["tracks"]) for x in (c, f, g))
        row = [f"{key[0]}, {key[1]:g} m, {key[2]:g}°", str(n)]
        for k, _, fmt in keys:
            r, fv, gv = (median(x, k, n) for x in (c, f, g))
            ok = k != "ml_failed_steps" and np.isfinite(r) and r > 0 and np.isfinite(gv) and abs(gv / r - 1.0) <= 0.25
            mark = " ✓" if ok else ""
            if k != "ml_failed_steps" and not ok:
                _, lo, hi = median_ratio_interval(g["per_trial"][k][:n], c["per_trial"][k][:n])
                mark = " ~" if lo <= 1.25 and hi >= 0.75 else ""
            row.append(" / ".join("–" if not np.isfinite(v) else fmt.format(v) for v in (r, fv, gv)) + mark)
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def nees_table(results: list[dict]) -> str:
    """Markdown table of rendered runs' triangulation NEES (mean / median over a cell's correct points)
    with the size σ, the table's inflation and the epoch-scaled σ (the rendered mode's), and ML / CRLB
    with the bound of the increment σ, for the Gaussian ML fit and the Cauchy-kernel one: the median
    over the trials of the per-trial ratio with its 90 % bootstrap interval (:func:`median_interval`)
    and, after it, the RMS over the trials (the tail of bad trials); ✓: mean NEES within 10 % of 3,
    median ML / CRLB within 0.9-1.15; ~: the median not, but its interval reaches into 0.9-1.15.  A
    mean NEES (epoch-scaled σ) outside 10 % of 3 gets the 90 % interval of the pooled mean over the
    trials (:func:`pooled_mean_interval`, result files that record each trial's NEES) and ~ where it
    reaches into 2.7-3.3."""
    lines = ["| target | views, range, angle | points | NEES, size σ | NEES, table σ | NEES, epoch-scaled σ "
             "| ML / CRLB, increment σ (median, RMS) | ML failed steps | Cauchy-kernel ML / CRLB (median, RMS) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for res in results:
        for c in res["cells"]:
            def nees(key, c=c):
                m = c.get(f"{key}_mean", float("nan"))
                text = f"{m:.2f} / {c.get(f'{key}_median', float('nan')):.2f}"
                if abs(m - 3.0) <= 0.3:
                    return text + " ✓"
                if key == "nees" and "trial_nees_sum" in c["per_trial"]:     # the interval of the pooled mean
                    _, lo, hi = pooled_mean_interval(c["per_trial"]["trial_nees_sum"], c["per_trial"]["trial_nees_count"])
                    return text + f" [{lo:.2f}–{hi:.2f}]" + (" ~" if lo <= 3.3 and hi >= 2.7 else "")
                return text

            def ratio(name, c=c):
                r = c.get(f"{name}_over_crlb_increment", float("nan"))
                if not np.isfinite(r):
                    return "–"
                _, lo, hi = median_interval(c["per_trial"].get(f"{name}_over_crlb_increment", [r]))
                mark = " ✓" if 0.9 <= r <= 1.15 else " ~" if lo <= 1.15 and hi >= 0.9 else ""
                return (f"{r:.2f} [{lo:.2f}–{hi:.2f}]{mark}, "
                        f"{c.get(f'{name}_over_crlb_increment_pooled', float('nan')):.2f}")
            lines.append(f"| {res['target']} | {c['n_views']}, {c['distance_m']:g} m, {c['axis_angle_deg']:g}° | "
                         f"{c['nees_points']} | {nees('nees_size')} | {nees('nees_table')} | {nees('nees')} | "
                         f"{ratio('ml')} | {c['ml_failed_steps']:.1f} | {ratio('ml_cauchy')} |")
    return "\n".join(lines)


def _joined(paths: str) -> dict:
    """The cells of the comma-separated result files ``paths`` joined into one result."""
    return {"cells": [c for p in paths.split(",") for c in json.loads(Path(p).read_text(encoding="utf-8"))["cells"]]}


def main(argv: Sequence[str] | None = None) -> None:
    """Run the check grid for one target and mode; write a JSON of per-cell medians and per-trial values."""
    ap = argparse.ArgumentParser(prog="python -m experiments.studies.fidelity_check", description=__doc__.split("\n")[0])
    ap.add_argument("--target", default="fy1", help="fy1 or a bundled mesh (topex)")
    ap.add_argument("--mode", choices=sorted(MODES))
    ap.add_argument("--table", nargs=3, metavar=("RENDERED", "FIXED", "CALIBRATED"),
                    help="print the markdown table of the three modes' result files (each a comma-separated "
                         "list whose cells are joined) instead of running")
    ap.add_argument("--paired-table", nargs=2, metavar=("RENDERED", "CALIBRATED"),
                    help="print the per-trial (paired) ratios of a geometric result file to a rendered one "
                         "(each a comma-separated list whose cells are joined) instead of running")
    ap.add_argument("--split-table", type=Path, metavar="RESULT",
                    help="print how far the medians of disjoint runs of --split-size trials of one result file "
                         "agree (the sampling floor of the ±25 %% criterion) instead of running")
    ap.add_argument("--split-size", type=int, default=20, help="trials per run of --split-table (default 20)")
    ap.add_argument("--nees-table", nargs="+", metavar="RENDERED",
                    help="print the triangulation NEES table of rendered result files instead of running")
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--views", default="2,3")
    ap.add_argument("--distances-m", default="40,80")
    ap.add_argument("--angles-deg", default="10,20")
    ap.add_argument("--out", type=Path)
    a = ap.parse_args(argv)
    try:
        if a.table:
            print(markdown_table(*(_joined(arg) for arg in a.table)))
            return
        if a.paired_table:
            print(paired_table(*(_joined(arg) for arg in a.paired_table)))
            return
        if a.split_table:
            if a.split_size < 1:
                ap.error(f"--split-size: must be at least 1 trial, got {a.split_size}")
            print(split_table(json.loads(a.split_table.read_text(encoding="utf-8")), a.split_size))
            return
    except (OSError, ValueError) as exc:     # a missing or unreadable file, cells in one file only
        opt = "--table" if a.table else "--paired-table" if a.paired_table else "--split-table"
        ap.error(f"{opt}: {exc}")
    if a.nees_table:
        print(nees_table([json.loads(Path(p).read_text(encoding="utf-8")) for p in a.nees_table]))
        return
    if a.mode is None or a.out is None:
        ap.error("--mode and --out are required (or --table)")
    cells = [(int(n), float(d), float(g)) for n in a.views.split(",") for d in a.distances_m.split(",")
             for g in a.angles_deg.split(",")]
    results = {"target": a.target, "mode": a.mode, "trials": a.trials, "cells": []}
    for n, d, g in cells:
        t0 = time.perf_counter()
        res = check_cell(CheckCell(target=a.target, mode=a.mode, n_views=n, distance_m=d, axis_angle_deg=g,
                                   trials=a.trials))
        cell = {"n_views": n, "distance_m": d, "axis_angle_deg": g, "wall_s": round(time.perf_counter() - t0, 1),
                **_summary(res), "per_trial": res["per_trial"]}
        results["cells"].append(cell)
        print(json.dumps({k: v for k, v in cell.items() if k != "per_trial"}), flush=True)
        a.out.parent.mkdir(parents=True, exist_ok=True)
        a.out.write_text(json.dumps(results, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
