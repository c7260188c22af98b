"""Docs figures of the formation: the formation in H (3D) and the observer-selection timeline.

Plot functions take ``ax=None`` (a new figure when omitted), return the axes, and compute nothing.
:func:`formation_figure_data` runs the study behind the figures on the six-spacecraft scenario of
the formation issue (:func:`formation.scenarios.six_spacecraft_scenario`): one orbit of CW motion,
the minimum-fuel reconfiguration of three spacecraft into the trailing 3-view geometry (60 m,
10°) within 0.6 orbit, and observer selection (k = 3, Cramér–Rao score of
:func:`formation.quality.crlb_score`) before the reconfiguration, after it with the planner's
drift-free slot states, and after it with circulating slot states
(:func:`formation.execution.circulating_slot_states`).  The docs figures are made with::

    .venv/bin/python -m experiments.scenarios.formation.docs_figures docs/figures

which writes ``formation_3d.png`` and ``formation_selection_timeline.png`` there and prints the
plans' figures, the timelines' summaries and the score comparison (:func:`score_comparison_data`).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.colors import BoundaryNorm, ListedColormap  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from numpy.typing import ArrayLike  # noqa: E402

__all__ = [
    "CATEGORIES",
    "FormationFigureData",
    "SelectionCase",
    "ZOOM_BOX_M",
    "exclusion_categories",
    "draw_formation_figures",
    "formation_3d_figure",
    "formation_figure_data",
    "frustum_corners_H",
    "plot_feasible_count",
    "plot_formation_3d",
    "plot_selection_timeline",
    "score_comparison_data",
    "selection_timeline_figure",
]

#: Timeline categories: (label, colour); the code of a cell is the index.
CATEGORIES: tuple[tuple[str, str], ...] = (
    ("active", "#1b7837"),
    ("feasible, lower quality", "#a6dba0"),
    ("passes own constraints; no feasible set of k", "#bdbdbd"),
    ("range window", "#f4a582"),
    ("pointing", "#b2abd2"),
    ("Sun / eclipse", "#fee08b"),
    ("keep-out", "#d73027"),
    ("pairwise axis angle", "#4393c3"),
    ("pairwise comm range", "#053061"),
)
#: Box of the zoomed 3D panel, m in H.
ZOOM_BOX_M = ((-30.0, 30.0), (-90.0, 25.0), (-30.0, 30.0))
_OWN = (("keep_out", 6), ("sun", 5), ("pointing", 4), ("range", 3))  # priority when several fail


def exclusion_categories(excluded: list[dict[int, str]], active: np.ndarray) -> np.ndarray:
    """Category code ``(T, N)`` of every candidate at every epoch (index into :data:`CATEGORIES`).

    ``excluded`` and ``active`` are a :class:`formation.selection.SelectionTimeline`'s fields.
    """
    act = np.asarray(active, dtype=bool)
    out = np.zeros(act.shape, dtype=int)
    for t, reasons in enumerate(excluded):
        for i, why in reasons.items():
            out[t, i] = _category(why)
    out[act] = 0
    return out


def _category(why: str) -> int:
    if why.startswith("feasible but"):
        return 1
    if "pairwise" in why and "conflicts among the others" not in why:
        what = why.split("pairwise", 1)[1].split("with")[0]
        if "axis_angle" in what:
            return 7
        if "comm" in what:
            return 8
    elif why.startswith("no feasible set"):
        return 2
    for key, code in _OWN:
        if key in why:
            return code
    raise ValueError(f"excluded: unknown exclusion reason {why!r}")


def frustum_corners_H(T_CW: np.ndarray, fov_x_rad: float, fov_y_rad: float, depth_m: ArrayLike) -> np.ndarray:
    """Corners ``(k, 4, 3)`` in H of the camera frusta cut at ``depth_m`` (scalar or ``(k,)``) along the boresight."""
    R_CW = T_CW[:, :3, :3]
    c = -np.einsum("kji,kj->ki", R_CW, T_CW[:, :3, 3])  # camera centres in H
    tx, ty = np.tan(0.5 * fov_x_rad), np.tan(0.5 * fov_y_rad)
    dirs_C = np.array([[tx, ty, 1.0], [tx, -ty, 1.0], [-tx, -ty, 1.0], [-tx, ty, 1.0]])
    d = np.broadcast_to(np.asarray(depth_m, dtype=float), (T_CW.shape[0],))
    return c[:, None, :] + d[:, None, None] * np.einsum("kji,cj->kci", R_CW, dirs_C)


# --------------------------------------------------------------------------------------- data
@dataclass(frozen=True)
class SelectionCase:
    """One selection run over the orbit.

    Attributes
    ----------
    label : str
    category : (T, N) int ndarray
        :data:`CATEGORIES` code per epoch and candidate.
    n_feasible : (T,) int ndarray
        Feasible k-subsets per epoch.
    score_rad : (T,) ndarray
        Predicted attitude-increment RMS error of the active set, rad (inf when none).
    switches : int
    """

    label: str
    category: np.ndarray
    n_feasible: np.ndarray
    score_rad: np.ndarray
    switches: int


@dataclass(frozen=True)
class FormationFigureData:
    """Everything the two formation figures draw (see :func:`formation_figure_data`).

    Positions are relative to the target's centre in H (x radial, y along-track, z orbit normal), m.
    """

    period_s: float
    t_s: np.ndarray  # (T,)
    r_coast_H: np.ndarray  # (N, T, 3) without manoeuvres
    movers: np.ndarray  # (m,)
    transfer_H: np.ndarray  # (m, K, 3) planned transfer (circulating slots)
    hold_H: np.ndarray  # (m, J, 3) after arrival, to the end of the orbit
    impulse_r_H: np.ndarray  # (m, M, 3)
    impulse_dv_H: np.ndarray  # (m, M, 3), m/s
    slots_H: np.ndarray  # (k, 3)
    tf_s: float
    snapshot_s: float
    camera_r_H: np.ndarray  # (k, 3) active observers at the snapshot
    camera_ids: np.ndarray  # (k,)
    frusta_H: np.ndarray  # (k, 4, 3)
    keep_out_radius_m: float
    target_radius_m: float
    cases: tuple[SelectionCase, ...]
    plan_summary: dict


def _sphere_points(m: int, radius_m: float) -> tuple[np.ndarray, np.ndarray]:
    i = np.arange(m) + 0.5
    polar = np.arccos(1.0 - 2.0 * i / m)
    az = np.pi * (1.0 + 5.0**0.5) * i
    u = np.stack([np.cos(az) * np.sin(polar), np.sin(az) * np.sin(polar), np.cos(polar)], -1)
    return radius_m * u, u


def formation_figure_data(*, step_s: float = 20.0, tf_orbits: float = 0.6, n_points: int = 60,
                          pixel_sigma_px: float = 0.5, image_px: int = 1024) -> FormationFigureData:
    """Run the six-spacecraft study (module doc): plans, selection timelines, a snapshot with frusta.

    The Cramér–Rao score sees ``n_points`` points on the target's activity sphere (radius
    ``constraints.target_radius_m``) with self-occlusion, through ``image_px``-pixel cameras
    with the constraints' field of view and ``pixel_sigma_px`` noise.
    """
    from formation.constraints import evaluate
    from formation.execution import circulating_slot_states, states_along_plan
    from formation.quality import camera_poses_at_target, crlb_score
    from formation.reconfiguration import choose_movers, drift_free_slot_states, lower_bound, plan
    from formation.scenarios import six_spacecraft_scenario
    from formation.selection import select_observers
    from orbits.cw import propagate
    from vision.camera import PinholeCamera

    s = six_spacecraft_scenario()
    con = s.constraints
    n = s.n
    t = np.arange(0.0, s.period_s, step_s)
    tf = tf_orbits * s.period_s
    x_coast = propagate(s.x0_H, t, n)  # (N, T, 6)
    cam = PinholeCamera.from_fov(image_px, image_px, fov_x_rad=con.fov_rad)
    X, normals = _sphere_points(n_points, con.target_radius_m)
    score = crlb_score(cam, X, pixel_sigma_px=pixel_sigma_px, normals_H=normals)

    def select(x, label):
        r = np.swapaxes(x[..., :3], 0, 1)
        tl = select_observers(evaluate(con, r), r, 3, score_fn=score)
        return tl, SelectionCase(label, exclusion_categories(tl.excluded, tl.active), tl.n_feasible,
                                 tl.score, tl.switches)

    _, before = select(x_coast, "before reconfiguration (CW coasting)")
    cases = [before]
    summary: dict = {}
    for name, slot_fn in (("drift-free slots", drift_free_slot_states), ("circulating slots", circulating_slot_states)):
        slots = slot_fn(s.slots.r_CT_H, n)
        movers, slot_of = choose_movers(s.x0_H, slots, tf, n)
        others = np.setdiff1d(np.arange(s.x0_H.shape[0]), movers)
        p = plan(s.x0_H[movers], slots[slot_of], n=n, tf_s=tf, assign=False, others_x0_H=s.x0_H[others])
        lb = lower_bound(s.x0_H[movers], slots[slot_of], n=n, tf_s=tf)
        x_after = x_coast.copy()
        x_after[movers] = states_along_plan(s.x0_H[movers], p, t, n=n)
        tl, case = select(x_after, f"after reconfiguration, {name}")
        cases.append(case)
        summary[name] = {"movers": movers.tolist(), "slot_of": slot_of.tolist(), "success": p.ok,
                         "status": p.solver_status, "dv_total_m_s": p.dv_total_m_s, "lower_bound_m_s": lb,
                         "solve_time_s": p.solve_time_s, "rounds": p.rounds,
                         "valid_fraction_after_arrival": float(np.mean(~tl.short[t >= tf])),
                         "min_keep_out_margin_m": float(p.margins["keep_out"].min()),
                         "min_separation_margin_m": float(p.margins["separation"].min())}
    # the 3D figure shows the recommended variant (circulating slots)
    t_hold = np.linspace(tf, s.period_s, 200)
    traj = states_along_plan(s.x0_H[movers], p, np.concatenate([p.t_grid_s, t_hold]), n=n)
    K = p.t_grid_s.size
    node_r = states_along_plan(s.x0_H[movers], p, p.impulse_times_s, n=n)[..., :3]
    k_snap = int(np.searchsorted(t, tf + 0.15 * s.period_s))
    active = np.flatnonzero(tl.active[k_snap])
    cam_r = np.swapaxes(x_after[..., :3], 0, 1)[k_snap, active]
    T_CW = camera_poses_at_target(cam_r)
    frusta = frustum_corners_H(T_CW, cam.fov_x_rad, cam.fov_y_rad, np.linalg.norm(cam_r, axis=-1))
    return FormationFigureData(
        period_s=s.period_s, t_s=t, r_coast_H=x_coast[..., :3], movers=movers,
        transfer_H=traj[:, :K, :3], hold_H=traj[:, K:, :3], impulse_r_H=node_r, impulse_dv_H=p.impulses_H,
        slots_H=s.slots.r_CT_H, tf_s=tf, snapshot_s=float(t[k_snap]), camera_r_H=cam_r, camera_ids=active,
        frusta_H=frusta, keep_out_radius_m=con.keep_out_radius_m, target_radius_m=con.target_radius_m,
        cases=tuple(cases), plan_summary=summary)


def score_comparison_data(*, ranges_m: Sequence[float] = (35.0, 60.0, 140.0),
                          angles_deg: Sequence[float] = (2.0, 10.0, 30.0), n_points: int = 60,
                          pixel_sigma_px: float = 0.5) -> list[dict]:
    """Cramér–Rao score against point DOP for trailing 3-view cones (no occlusion, 1024 px, 20° FoV).

    Points on a 4 m sphere; point DOP with the pixel noise as an angle (σ / f).  Returns one row
    per (range, axis angle) with ``crlb_mdeg`` and ``point_dop_cm``.
    """
    from attitude.quaternion import quat_from_axis_angle
    from formation.geometry import symmetric_views
    from formation.quality import crlb_score
    from formation.selection import point_dop
    from vision.camera import PinholeCamera

    cam = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)
    X, _ = _sphere_points(n_points, 4.0)
    q = quat_from_axis_angle([1.0, 0.0, 0.0], np.pi / 2)
    cases = [(d, g) for d in ranges_m for g in angles_deg]
    r = np.stack([symmetric_views(3, d, g, orientation=q).r_CT_H for d, g in cases])[None]
    crlb = crlb_score(cam, X, pixel_sigma_px=pixel_sigma_px)(r)[0]
    dop = point_dop(r, angular_sigma_rad=pixel_sigma_px / cam.fx)[0]
    return [{"range_m": d, "axis_angle_deg": g, "crlb_mdeg": float(np.degrees(c) * 1e3), "point_dop_cm": float(100 * p)}
            for (d, g), c, p in zip(cases, crlb, dop, strict=True)]


# --------------------------------------------------------------------------------------- plots
def _axes3d(ax):
    if ax is None:
        fig = plt.figure(figsize=(7.0, 6.0), layout="constrained")
        ax = fig.add_subplot(projection="3d")
    return ax


def _sphere_mesh(radius_m: float, n: int = 24):
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, n), np.linspace(0, np.pi, n // 2))
    return radius_m * np.cos(u) * np.sin(v), radius_m * np.sin(u) * np.sin(v), radius_m * np.cos(v)


def plot_formation_3d(r_coast_H: ArrayLike, *, transfer_H: ArrayLike | None = None,
                      hold_H: ArrayLike | None = None, impulse_r_H: ArrayLike | None = None,
                      impulse_dv_H: ArrayLike | None = None, slots_H: ArrayLike | None = None,
                      camera_r_H: ArrayLike | None = None, frusta_H: ArrayLike | None = None,
                      keep_out_radius_m: float = 0.0, target_radius_m: float = 0.0,
                      ids: Sequence[int] | None = None, dv_scale_m_per_m_s: float = 300.0,
                      limits_m: ArrayLike | None = None, ax: Axes | None = None, legend: bool = True) -> Axes:
    """Formation in H: coasting orbits, planned transfers with impulses, slots, cameras and frusta.

    Parameters
    ----------
    r_coast_H : (N, T, 3)
        Unmanoeuvred CW trajectories, m.
    ids : sequence of int, optional
        Spacecraft number of each row of ``r_coast_H`` (its colour and label "SC<id>").
    transfer_H, hold_H : (m, K, 3), optional
        Planned transfer and the motion after arrival.
    impulse_r_H, impulse_dv_H : (m, M, 3), optional
        Where the impulses are applied (m) and the impulses (m/s), drawn as arrows of
        ``dv_scale_m_per_m_s`` metres per m/s (impulses under 1e-4 m/s are not drawn).
    slots_H : (k, 3), optional
    camera_r_H : (k, 3), frusta_H : (k, 4, 3), optional
        Active observers and their frusta corners.
    keep_out_radius_m, target_radius_m : float
        Spheres drawn about the target (0: not drawn).
    limits_m : ((xmin, xmax), (ymin, ymax), (zmin, zmax)), optional
        Box shown with equal scales on the three axes (lines leaving it are cut); default: the
        data's extent, axes not to scale.
    """
    ax = _axes3d(ax)
    box = None if limits_m is None else np.asarray(limits_m, dtype=float)

    def cut(a):  # hide what leaves the box (3D axes do not clip)
        a = np.asarray(a, dtype=float)
        if box is None:
            return a
        inside = np.all((a >= box[:, 0]) & (a <= box[:, 1]), axis=-1, keepdims=True)
        return np.where(inside, a, np.nan)

    r = cut(r_coast_H)
    cmap = plt.get_cmap("tab10")
    ids = list(range(r.shape[0])) if ids is None else list(ids)
    for row, i in enumerate(ids):
        ax.plot(r[row, :, 0], r[row, :, 1], r[row, :, 2], color=cmap(i), lw=0.9, alpha=0.6, label=f"SC{i} coasting")
        ax.scatter(*r[row, 0], color=cmap(i), s=12)
    if transfer_H is not None:
        for j, tr in enumerate(cut(transfer_H)):
            ax.plot(tr[:, 0], tr[:, 1], tr[:, 2], color="k", lw=1.8, label="planned transfer" if j == 0 else None)
    if hold_H is not None:
        for j, h in enumerate(cut(hold_H)):
            ax.plot(h[:, 0], h[:, 1], h[:, 2], color="k", lw=1.2, ls="--", label="after arrival" if j == 0 else None)
    if impulse_r_H is not None and impulse_dv_H is not None:
        p = cut(impulse_r_H).reshape(-1, 3)
        dv = np.asarray(impulse_dv_H).reshape(-1, 3)
        big = (np.linalg.norm(dv, axis=-1) > 1e-4) & np.all(np.isfinite(p), axis=-1)
        if np.any(big):
            a = dv[big] * dv_scale_m_per_m_s
            ax.quiver(p[big, 0], p[big, 1], p[big, 2], a[:, 0], a[:, 1], a[:, 2], color="#d6604d", lw=1.5,
                      arrow_length_ratio=0.25, label=f"impulses ({dv_scale_m_per_m_s:g} m per m/s)")
    if slots_H is not None:
        sl = np.asarray(slots_H)
        ax.scatter(sl[:, 0], sl[:, 1], sl[:, 2], marker="s", s=30, facecolors="none", edgecolors="k", label="slots")
    if keep_out_radius_m > 0:
        ax.plot_wireframe(*_sphere_mesh(keep_out_radius_m), color="#d73027", lw=0.3, alpha=0.5)
        ax.plot([], [], color="#d73027", lw=0.6, label=f"keep-out sphere {keep_out_radius_m:g} m")
    if target_radius_m > 0:
        ax.plot_surface(*_sphere_mesh(target_radius_m, 16), color="0.35", alpha=0.9, lw=0)
    if camera_r_H is not None:
        c = np.asarray(camera_r_H)
        ax.scatter(c[:, 0], c[:, 1], c[:, 2], marker="^", s=45, color="#1b7837", label="active observers")
        if frusta_H is not None:
            for ci, fr in zip(c, np.asarray(frusta_H), strict=True):
                for q in fr:
                    ax.plot(*np.stack([ci, q]).T, color="#1b7837", lw=0.7)
                ring = np.vstack([fr, fr[:1]])
                ax.plot(ring[:, 0], ring[:, 1], ring[:, 2], color="#1b7837", lw=0.7)
    if box is not None:
        ax.set_xlim(*box[0])
        ax.set_ylim(*box[1])
        ax.set_zlim(*box[2])
        ax.set_box_aspect(tuple(box[:, 1] - box[:, 0]), zoom=0.9)
    ax.set_xlabel("x radial [m]")
    ax.set_ylabel("y along-track [m]")
    ax.set_zlabel("z orbit normal [m]")
    if legend:
        ax.legend(fontsize=7, loc="upper left")
    return ax


def plot_selection_timeline(t_s: ArrayLike, category: ArrayLike, *, names: Sequence[str] | None = None,
                            ax: Axes | None = None, period_s: float | None = None, marks_s: Sequence[float] = (),
                            title: str | None = None) -> Axes:
    """Candidates (rows) against time: active, or coloured by why each one was left out.

    ``category (T, N)`` holds :data:`CATEGORIES` codes; ``marks_s`` are times drawn as vertical
    lines (e.g. reconfiguration start and arrival); the time axis is in orbits when ``period_s``
    is given, else in minutes.
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(10.0, 2.4), layout="constrained")
    t = np.asarray(t_s, dtype=float)
    cat = np.asarray(category)
    scale, unit = (period_s, "orbits") if period_s else (60.0, "min")
    edges = np.append(t, t[-1] + (t[-1] - t[-2] if t.size > 1 else 1.0)) / scale
    cmap = ListedColormap([c for _, c in CATEGORIES])
    norm = BoundaryNorm(np.arange(len(CATEGORIES) + 1) - 0.5, len(CATEGORIES))
    ax.pcolormesh(edges, np.arange(cat.shape[1] + 1) - 0.5, cat.T, cmap=cmap, norm=norm)
    names = names if names is not None else [f"SC{i}" for i in range(cat.shape[1])]
    ax.set_yticks(np.arange(cat.shape[1]), names)
    ax.set_ylim(cat.shape[1] - 0.5, -0.5)
    for m in marks_s:
        ax.axvline(m / scale, color="k", lw=1.0, ls="--")
    ax.set_xlim(edges[0], edges[-1])
    ax.set_xlabel(f"time [{unit}]")
    if title:
        ax.set_title(title, fontsize=9, loc="left")
    return ax


def plot_feasible_count(t_s: ArrayLike, n_feasible: ArrayLike, *, score_rad: ArrayLike | None = None,
                        n_subsets: int | None = None, ax: Axes | None = None, period_s: float | None = None,
                        marks_s: Sequence[float] = ()) -> Axes | tuple[Axes, Axes]:
    """Feasible k-subsets per epoch (steps) and, on a second axis, the active set's predicted error (mdeg)."""
    if ax is None:
        _, ax = plt.subplots(figsize=(10.0, 1.4), layout="constrained")
    t = np.asarray(t_s, dtype=float)
    scale, unit = (period_s, "orbits") if period_s else (60.0, "min")
    ax.step(t / scale, n_feasible, where="post", color="k", lw=1.0)
    ax.set_ylabel("feasible sets" + (f"\n(of {n_subsets})" if n_subsets else ""), fontsize=8)
    top = max(int(np.max(n_feasible)), 1)
    ax.set_ylim(-0.15 * top, 1.2 * top)
    ax.yaxis.get_major_locator().set_params(integer=True)
    for m in marks_s:
        ax.axvline(m / scale, color="k", lw=1.0, ls="--")
    ax.set_xlim(t[0] / scale, (t[-1] + (t[-1] - t[-2] if t.size > 1 else 1.0)) / scale)
    ax.set_xlabel(f"time [{unit}]")
    out = ax
    if score_rad is not None:
        s = np.degrees(np.asarray(score_rad, dtype=float)) * 1e3
        tw = ax.twinx()
        fin = s[np.isfinite(s)]
        tw.plot(t / scale, np.where(np.isfinite(s), s, np.nan), color="#1b7837", lw=1.2)
        tw.set_ylabel("active set's\nCRLB [mdeg]", fontsize=8, color="#1b7837")
        if fin.size:
            tw.set_ylim(0, 1.2 * fin.max())
        else:
            tw.set_yticks([])
            tw.text(0.5, 0.5, "no feasible set at any epoch", transform=ax.transAxes, ha="center",
                    va="center", fontsize=8, color="0.3")
        out = (ax, tw)
    return out


def formation_3d_figure(data: FormationFigureData) -> Figure:
    """Two 3D panels: the whole formation over one orbit, and :data:`ZOOM_BOX_M` about the target
    (equal scales; spacecraft that do not manoeuvre, the transfers' last part, slots, observers)."""
    fig = plt.figure(figsize=(14.0, 7.0), layout="constrained")
    a1 = fig.add_subplot(1, 2, 1, projection="3d")
    a2 = fig.add_subplot(1, 2, 2, projection="3d")
    common = dict(transfer_H=data.transfer_H, hold_H=data.hold_H, impulse_r_H=data.impulse_r_H,
                  impulse_dv_H=data.impulse_dv_H, keep_out_radius_m=data.keep_out_radius_m,
                  target_radius_m=data.target_radius_m)
    plot_formation_3d(data.r_coast_H, ax=a1, dv_scale_m_per_m_s=1000.0, legend=False, **common)
    h, lab = a1.get_legend_handles_labels()
    fig.legend(h, lab, loc="outside lower center", ncol=min(len(h), 6), fontsize=7, frameon=False)
    a1.set_title("one orbit in H (axes not to scale)", fontsize=10)
    a1.view_init(elev=25, azim=-60)
    still = np.setdiff1d(np.arange(data.r_coast_H.shape[0]), data.movers)
    plot_formation_3d(data.r_coast_H[still], ids=still, ax=a2, slots_H=data.slots_H, camera_r_H=data.camera_r_H,
                      frusta_H=data.frusta_H, limits_m=ZOOM_BOX_M, dv_scale_m_per_m_s=300.0, legend=False,
                      **common)
    keep = {"planned transfer", "after arrival", "slots", "active observers"}
    h, lab = a2.get_legend_handles_labels()
    a2.legend([x for x, y in zip(h, lab, strict=True) if y in keep or y.startswith("impulses")],
              [y for y in lab if y in keep or y.startswith("impulses")], fontsize=7, loc="upper left",
              bbox_to_anchor=(0.0, 1.0), frameon=False)
    a2.set_title(f"about the target; observers {', '.join(f'SC{i}' for i in data.camera_ids)} with frusta "
                 f"at t = {data.snapshot_s / data.period_s:.2f} orbit", fontsize=10)
    a2.view_init(elev=20, azim=-35)
    c = data.plan_summary["circulating slots"]
    fig.suptitle(f"Six observers on CW orbits; SC{', SC'.join(map(str, data.movers))} move to the 3-view slots "
                 f"(60 m, 10°) in {data.tf_s / data.period_s:.1f} orbit: Δv {1e3 * c['dv_total_m_s']:.1f} mm/s "
                 f"(convex lower bound {1e3 * c['lower_bound_m_s']:.1f} mm/s)", fontsize=11)
    return fig


def selection_timeline_figure(data: FormationFigureData, *, k: int = 3) -> Figure:
    """For each selection case: the candidates' timeline and the feasible-set count with the score."""
    from math import comb

    n_cases = len(data.cases)
    N = data.r_coast_H.shape[0]
    fig, axes = plt.subplots(2 * n_cases, 1, figsize=(11.0, 2.9 * n_cases + 0.6), layout="constrained",
                             sharex=True, gridspec_kw={"height_ratios": [3, 1.3] * n_cases})
    marks = (0.0, data.tf_s)
    present = set()
    for j, case in enumerate(data.cases):
        marks_j = marks if j > 0 else ()
        plot_selection_timeline(data.t_s, case.category, ax=axes[2 * j], period_s=data.period_s, marks_s=marks_j,
                                title=f"{case.label}: {case.switches} switches")
        plot_feasible_count(data.t_s, case.n_feasible, score_rad=case.score_rad, n_subsets=comb(N, k),
                            ax=axes[2 * j + 1], period_s=data.period_s, marks_s=marks_j)
        present |= set(np.unique(case.category).tolist())
    for a in axes[:-1]:
        a.set_xlabel("")
    handles = [Patch(color=col, label=lab) for code, (lab, col) in enumerate(CATEGORIES) if code in present]
    fig.legend(handles=handles, loc="outside lower center", ncol=min(len(handles), 5), fontsize=8)
    fig.suptitle(f"Observer selection (k = {k}, Cramér–Rao score), six-spacecraft scenario; dashed: "
                 "reconfiguration start and arrival", fontsize=10)
    return fig


def draw_formation_figures(out_dir: Path, data: FormationFigureData, *, format: str = "png") -> list[Path]:
    """Write ``formation_3d`` and ``formation_selection_timeline`` into ``out_dir`` as ``format``
    (``"png"``, ``"pdf"`` or ``"svg"``); returns the paths."""
    from experiments.plotting import figure_path, save

    return [save(formation_3d_figure(data), figure_path(out_dir, "formation_3d", format), dpi=110),
            save(selection_timeline_figure(data), figure_path(out_dir, "formation_selection_timeline", format),
                 dpi=110)]


def main(argv: list[str] | None = None) -> None:  # pragma: no cover - documented script
    """Draw the docs figures into ``argv[0]`` (default ``docs/figures``) as ``argv[1]`` (default ``png``)
    and print their numbers."""
    args = sys.argv[1:] if argv is None else argv
    out = Path(args[0] if args else "docs/figures")
    out.mkdir(parents=True, exist_ok=True)
    data = formation_figure_data()
    for path in draw_formation_figures(out, data, format=args[1] if len(args) > 1 else "png"):
        print(f"wrote {path}")
    for variant, summary in data.plan_summary.items():
        print(variant, {k: (round(v, 6) if isinstance(v, float) else v) for k, v in summary.items()})
    for case in data.cases:
        ok = np.isfinite(case.score_rad)
        spans = np.flatnonzero(np.diff(ok.astype(int))) + 1
        print(f"{case.label}: a feasible set at {100 * ok.mean():.1f} % of epochs, changes at "
              f"{np.round(data.t_s[spans] / data.period_s, 3).tolist()} orbit, {case.switches} switches, "
              f"CRLB {np.degrees(case.score_rad[ok]).min() * 1e3 if ok.any() else np.nan:.1f}–"
              f"{np.degrees(case.score_rad[ok]).max() * 1e3 if ok.any() else np.nan:.1f} mdeg")
    print("| range (m) | axis angle (°) | CRLB (mdeg) | point DOP (cm) |\n|---|---|---|---|")
    for row in score_comparison_data():
        print(f"| {row['range_m']:.0f} | {row['axis_angle_deg']:.0f} | {row['crlb_mdeg']:.1f} | "
              f"{row['point_dop_cm']:.2f} |")


if __name__ == "__main__":  # pragma: no cover
    main()
