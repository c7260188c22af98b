"""Scenes that stress matching: the Earth behind the target and glints, against the black sky (issue 16 item 4).

``python -m experiments.studies.earth_scenes`` renders each target at each range in ``attitudes``
random attitudes, each with its own Sun, seen by three cameras looking down at the target with the
Earth behind it (camera A within ``zenith_max_deg`` of the zenith; B at ``cross_view_deg`` from A; C at
the same angle from both), with the Sun at most ``sun_phase_max_deg`` from camera A and at least
``sun_elevation_min_deg`` above the target's local horizontal (the ground behind the target in
daylight), in three scenes with the same attitudes, Sun, cameras and sensor-noise streams:

* ``black``: black sky, the targets' default materials (the rendered mode's default);
* ``earth``: the Earth behind the target and its albedo light (:class:`vision.earth.EarthScene`);
* ``glints``: black sky, glint lobes on MLI and solar cells (:func:`vision.glints.with_glints`).

Per scene it detects SIFT keypoints as the rendered mode does (:func:`vision.rendered.detect_views`)
and matches views A, B (2 views) and A, B, C (3 views) (:func:`vision.features.match_views`), and
counts, per epoch,

* keypoints on the target (within 2 px of a target pixel) and on the background (further away);
* tracks, and **false** tracks: those :func:`vision.rendered.label_tracks` rejects (the body points seen
  through a track's keypoints do not reproject onto each other within 2 px), and among them the
  tracks with a keypoint on the background;
* inter-epoch associations (2 views): camera A's keypoints of the tracks against A's keypoints after
  the target turned by ``epoch_change_deg`` about a random axis (the Sun, the cameras and the Earth
  fixed in H), ratio test without a geometric gate (:func:`vision.features.match_pair`), false when the
  surface points seen through the two keypoints do not reproject onto each other within 2 px.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from attitude.quaternion import matrix_from_quat, quat_from_rotvec, quat_multiply, quat_normalize
from experiments.studies.rendered_calibration import _body_points, _correct
from experiments.sweep import child_seeds
from vision.camera import PinholeCamera, look_at
from vision.earth import EARTH_RADIUS_M, EarthScene
from vision.features import match_pair, match_views
from vision.glints import with_glints
from vision.rendered import detect_views, label_tracks, render_views
from vision.target import Target, fy1_target, load_mesh

__all__ = ["SceneSpec", "SCENES", "measure", "format_table", "scene_figure", "main"]

SCENES = ("black", "earth", "glints")
_COUNTS = ("kp_target", "kp_background", "tracks", "false", "false_background", "epochs", "assoc", "assoc_false")


@dataclass(frozen=True)
class SceneSpec:
    """What the study renders (see the module docstring)."""

    targets: tuple[str, ...] = ("fy1", "topex")
    ranges_m: tuple[float, ...] = (40.0, 80.0)
    attitudes: int = 12
    cross_view_deg: float = 10.0
    zenith_max_deg: float = 40.0
    sun_phase_max_deg: float = 120.0
    sun_elevation_min_deg: float = 10.0
    epoch_change_deg: float = 4.0
    orbit_altitude_km: float = 870.0
    earth_albedo: float = 0.3
    seed: int = 2016
    image_px: int = 1024
    fov_deg: float = 20.0


def _target(name: str) -> Target:
    return fy1_target() if name == "fy1" else load_mesh(name)


def _cameras(g: np.random.Generator, range_m: float, spec: SceneSpec) -> tuple[np.ndarray, np.ndarray]:
    """Poses (3, 4, 4) of cameras A, B, C looking down at the target, and the unit direction to A (H)."""
    zen = np.radians(g.uniform(0.0, spec.zenith_max_deg))
    az = g.uniform(0.0, 2 * np.pi)
    eA = np.array([np.cos(zen), np.sin(zen) * np.cos(az), np.sin(zen) * np.sin(az)])
    up = np.cross(eA, g.normal(size=3))
    up /= np.linalg.norm(up)
    axis = np.cross(eA, g.normal(size=3))
    axis /= np.linalg.norm(axis)
    ang = np.radians(spec.cross_view_deg)
    R_B = matrix_from_quat(quat_from_rotvec(ang * axis))
    R60 = matrix_from_quat(quat_from_rotvec(np.radians(60.0) * eA))
    R_C = matrix_from_quat(quat_from_rotvec(ang * (R60 @ axis)))
    T = [look_at(range_m * (R @ eA), np.zeros(3), R @ up) for R in (np.eye(3), R_B, R_C)]
    return np.stack(T), eA


def _sun(g: np.random.Generator, eA: np.ndarray, spec: SceneSpec) -> np.ndarray:
    """A Sun direction within the phase limit of camera A and at least ``sun_elevation_min_deg`` above the
    target's local horizontal (the ground below in daylight)."""
    while True:
        s = g.normal(size=3)
        s /= np.linalg.norm(s)
        if (np.degrees(np.arccos(np.clip(s @ eA, -1, 1))) <= spec.sun_phase_max_deg
                and s[0] >= np.sin(np.radians(spec.sun_elevation_min_deg))):
            return s


def _count(renders, kps, cam: PinholeCamera, T: np.ndarray, target: Target, q: np.ndarray,
           n_views: int, out: dict[str, float]) -> np.ndarray:
    """Add one epoch's counts to ``out``; returns the indices of camera A's keypoints in tracks."""
    from scipy.ndimage import distance_transform_edt

    views = list(range(n_views))
    on_bg = []
    for i in views:
        dist = distance_transform_edt(~renders[i].mask)
        ij = np.clip(np.rint(kps[i].uv_px).astype(int), 0, np.array(dist.shape[::-1]) - 1)
        bg = dist[ij[:, 1], ij[:, 0]] > 2.0
        on_bg.append(dist)
        out["kp_target"] += float((~bg).sum()) / n_views
        out["kp_background"] += float(bg.sum()) / n_views
    out["epochs"] += 1
    none = np.zeros(0, dtype=np.int64)
    if not all(r.ok for r in renders[:n_views]):
        return none
    obs = match_views([kps[i] for i in views], cam, T[:n_views], ratio=0.6, epipolar_tol_px=1.5)
    if not obs.ok or obs.n_tracks == 0:
        return none
    obs = label_tracks(obs, renders[:n_views], target, q, tol_px=2.0)
    false = obs.feature_id < 0
    bg = np.zeros(obs.n_tracks, dtype=bool)
    for i in views:
        sel = obs.seen[:, i]
        ij = np.clip(np.rint(obs.uv_px[sel, i]).astype(int), 0, np.array(on_bg[i].shape[::-1]) - 1)
        bg[np.nonzero(sel)[0]] |= on_bg[i][ij[:, 1], ij[:, 0]] > 2.0
    out["tracks"] += obs.n_tracks
    out["false"] += float(false.sum())
    out["false_background"] += float((false & bg).sum())
    uvA = obs.uv_px[obs.seen[:, 0], 0]
    d = np.linalg.norm(kps[0].uv_px[:, None, :] - uvA[None, :, :], axis=2)
    return np.unique(np.argmin(d, axis=0)[d.min(axis=0) < 1e-6])


def _associate(rA, kA, idx: np.ndarray, cam: PinholeCamera, T_A: np.ndarray, target: Target, q: np.ndarray,
               q2: np.ndarray, sun: np.ndarray, rng: np.random.Generator, earth, out: dict[str, float]) -> None:
    """Camera A's track keypoints associated with A's keypoints after the target turned to ``q2``."""
    if len(idx) == 0:
        return
    r2 = render_views(cam, T_A[None], target, q2, sun, rng=rng, earth=earth)
    k2 = detect_views(r2)[0]
    if not r2[0].ok or len(k2) < 2:
        return
    kT = kA.subset(idx)
    m = match_pair(kT, k2, ratio=0.6)
    if len(m) == 0:
        return
    XA = _body_points(rA, target, q, kT.uv_px[m[:, 0]])
    X2 = _body_points(r2[0], target, q2, k2.uv_px[m[:, 1]])
    ok = _correct(rA, q, XA, kT.uv_px[m[:, 0]], r2[0], q2, X2, k2.uv_px[m[:, 1]], 2.0)
    out["assoc"] += len(m)
    out["assoc_false"] += float((~ok).sum())


def _earth(spec: SceneSpec, seed: np.random.SeedSequence) -> EarthScene:
    return EarthScene(EARTH_RADIUS_M + 1e3 * spec.orbit_altitude_km, np.random.default_rng(seed),
                      albedo=spec.earth_albedo)


def scene_figure(path: str, spec: SceneSpec = SceneSpec(), *, target: str = "fy1", range_m: float = 40.0,
                 attitude: int = 0) -> None:
    """Write camera A's image of one attitude of the study in the three scenes, side by side (PNG, 8 bit)."""
    import cv2

    cam = PinholeCamera.from_fov(spec.image_px, spec.image_px, fov_x_deg=spec.fov_deg)
    s_earth, s_cells = child_seeds(np.random.SeedSequence(spec.seed), 2)
    earth = _earth(spec, s_earth)
    cells = [(t, r) for t in spec.targets for r in spec.ranges_m]
    ss = child_seeds(s_cells, len(cells))[cells.index((target, range_m))]
    s_geo, s_img = child_seeds(child_seeds(ss, spec.attitudes)[attitude], 2)
    g = np.random.default_rng(s_geo)
    q = quat_normalize(g.normal(size=4))
    T, eA = _cameras(g, range_m, spec)
    sun = _sun(g, eA, spec)
    plain = _target(target)
    images = []
    for scene in SCENES:
        tgt = with_glints(plain) if scene == "glints" else plain
        r = render_views(cam, T[:1], tgt, q, sun, rng=np.random.default_rng(s_img).spawn(2)[0],
                         earth=earth if scene == "earth" else None)[0]
        images.append(r.image[r.roi_slices])
    h = min(i.shape[0] for i in images)
    w = min(i.shape[1] for i in images)
    gap = np.full((h, 8), 255, dtype=np.uint8)
    row = [images[0][:h, :w], gap, images[1][:h, :w], gap, images[2][:h, :w]]
    if not cv2.imwrite(str(path), np.hstack(row)):
        raise OSError(f"could not write {path}")


def measure(spec: SceneSpec = SceneSpec(), *, progress=None) -> list[dict]:
    """One row per target, range, scene and view count: the counts of the module docstring, summed over
    the attitudes (``epochs`` of them), with ``cpu_s`` of the cell's rendering and matching."""
    cam = PinholeCamera.from_fov(spec.image_px, spec.image_px, fov_x_deg=spec.fov_deg)
    root = np.random.SeedSequence(spec.seed)
    s_earth, s_cells = child_seeds(root, 2)
    earth = _earth(spec, s_earth)
    rows = []
    cells = [(t, r) for t in spec.targets for r in spec.ranges_m]
    for (name, range_m), ss in zip(cells, child_seeds(s_cells, len(cells)), strict=True):
        plain = _target(name)
        scene_target = {"black": plain, "earth": plain, "glints": with_glints(plain)}
        tally = {(s, n): dict.fromkeys(_COUNTS, 0.0) for s in SCENES for n in (2, 3)}
        cpu = dict.fromkeys(SCENES, 0.0)
        for a, sa in enumerate(child_seeds(ss, spec.attitudes)):
            s_geo, s_img = child_seeds(sa, 2)
            g = np.random.default_rng(s_geo)
            q = quat_normalize(g.normal(size=4))
            T, eA = _cameras(g, range_m, spec)
            sun = _sun(g, eA, spec)
            turn = g.normal(size=3)
            q2 = quat_normalize(quat_multiply(quat_from_rotvec(np.radians(spec.epoch_change_deg) * turn
                                                               / np.linalg.norm(turn)), q))
            for scene in SCENES:
                t0 = time.process_time()
                target = scene_target[scene]
                rngs = np.random.default_rng(s_img).spawn(2)
                e = earth if scene == "earth" else None
                renders = render_views(cam, T, target, q, sun, rng=rngs[0], earth=e)
                kps = detect_views(renders)
                for n in (3, 2):
                    idx = _count(renders, kps, cam, T, target, q, n, tally[scene, n])
                _associate(renders[0], kps[0], idx, cam, T[0], target, q, q2, sun, rngs[1], e, tally[scene, 2])
                cpu[scene] += time.process_time() - t0
            if progress is not None:
                progress(f"{name} {range_m:g} m: attitude {a + 1}/{spec.attitudes}")
        for (scene, n), c in tally.items():
            rows.append({"target": name, "range_m": range_m, "scene": scene, "views": n, **c, "cpu_s": cpu[scene]})
    return rows


def format_table(rows: Sequence[dict]) -> str:
    """Markdown table: per epoch means, false tracks as a count and a share of the tracks."""
    head = ("| target | range | views | scene | keypoints on target | on background | tracks | false tracks "
            "| false (%) | false with a background view | associations | false associations (%) |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|---|")
    lines = [head]
    for r in sorted(rows, key=lambda r: (r["target"], r["range_m"], r["views"], SCENES.index(r["scene"]))):
        e = max(r["epochs"], 1)
        share = 100.0 * r["false"] / r["tracks"] if r["tracks"] else float("nan")
        lines.append(f"| {r['target']} | {r['range_m']:g} m | {r['views']} | {r['scene']} | {r['kp_target'] / e:.0f} "
                     f"| {r['kp_background'] / e:.0f} | {r['tracks'] / e:.1f} | {r['false'] / e:.1f} | {share:.1f} "
                     f"| {r['false_background'] / e:.1f} | {_assoc(r)} |")
    return "\n".join(lines)


def _assoc(r: dict) -> str:
    if r["views"] != 2:
        return "– | –"
    share = 100.0 * r["assoc_false"] / r["assoc"] if r["assoc"] else float("nan")
    return f"{r['assoc'] / max(r['epochs'], 1):.1f} | {share:.1f}"


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``python -m experiments.studies.earth_scenes [--targets fy1 topex] [--attitudes 12]``."""
    p = argparse.ArgumentParser(prog="python -m experiments.studies.earth_scenes", description=__doc__.splitlines()[0])
    p.add_argument("--targets", nargs="+", default=list(SceneSpec.targets))
    p.add_argument("--ranges", nargs="+", type=float, default=list(SceneSpec.ranges_m))
    p.add_argument("--attitudes", type=int, default=SceneSpec.attitudes)
    p.add_argument("--seed", type=int, default=SceneSpec.seed)
    p.add_argument("--figure", metavar="PNG", help="also write camera A's image of the first attitude of the "
                   "first target and range in the three scenes")
    args = p.parse_args(argv)
    if args.attitudes < 1 or not args.targets or min(args.ranges) <= 0:
        p.error("need --attitudes >= 1, a target and positive ranges")
    spec = SceneSpec(targets=tuple(args.targets), ranges_m=tuple(args.ranges), attitudes=args.attitudes,
                     seed=args.seed)
    if args.figure:
        scene_figure(args.figure, spec, target=spec.targets[0], range_m=spec.ranges_m[0])
    t0 = time.process_time()
    rows = measure(spec, progress=lambda s: print(s, file=sys.stderr, flush=True))
    print(format_table(rows))
    cpu = {s: sum(r["cpu_s"] for r in rows if r["scene"] == s and r["views"] == 2) for s in SCENES}
    print(f"\nCPU time: {time.process_time() - t0:.0f} s in all; per scene "
          + ", ".join(f"{s} {v:.0f} s" for s, v in cpu.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
