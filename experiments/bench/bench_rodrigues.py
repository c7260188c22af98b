"""001 pose solver benchmarks: solves per second against OpenCV SQPnP at equal accuracy.

Frames come from the Table 1 scenario of 001 (``experiments/configs/001_rodrigues.toml``): the 2 m
cube seen from ≈100 m, 1 px noise, 6–7 visible vertices.  Each of our solves starts from the truth
of the previous 5 s epoch (the warm start the tracker uses); SQPnP is global and needs no guess.
Accuracy of both is printed in the note (RMS position error along the line of sight and worst-axis
attitude error), so the ratio is read at equal accuracy.
"""

from __future__ import annotations

import cv2
import numpy as np

from attitude.quaternion import quat_angle_between, quat_from_matrix, quat_from_rotvec
from chaser.rodrigues_pose import (
    GibbsPose,
    pixels_from_focal_plane,
    project_focal_plane,
    solve_pose_rodrigues,
)
from experiments.bench import BenchRow, best_time, throughput_row
from experiments.scenarios.rodrigues import Config, cube_vertices, truth_001, visible_vertices

F_M, PIXEL_M, CENTRE = 0.2, 7e-6, np.array([1024.0, 1024.0])


def _frames(n: int, rng: int):
    cfg = Config(kind="rodrigues_001")
    t = np.arange(n + 1) * 5.0
    tr = truth_001(cfg, t)
    cube = cube_vertices(2.0)
    xy, _ = project_focal_plane(cube, tr["R_CT"][1:], tr["r_TC_C"][1:], focal_length_m=F_M)
    xy = xy + PIXEL_M * np.random.default_rng(rng).standard_normal(xy.shape)
    vis = visible_vertices(tr["R_CT"][1:], tr["r_TC_C"][1:], 2.0)
    init = GibbsPose.from_quat(quat_from_matrix(tr["R_CT"][:-1]), tr["r_TC_C"][:-1])
    return cube, np.where(vis[..., None], xy, np.nan), vis, init, quat_from_matrix(tr["R_CT"][1:]), tr["r_TC_C"][1:]


def _accuracy(q, r, q_true, r_true) -> tuple[float, float]:
    los = r_true / np.linalg.norm(r_true, axis=-1, keepdims=True)
    along = np.sqrt(np.mean(np.sum((r - r_true) * los, -1) ** 2))
    return float(along), float(np.degrees(np.sqrt(np.mean(quat_angle_between(q, q_true) ** 2))))


def run(*, quick: bool = False) -> list[BenchRow]:
    n = 200 if quick else 1000
    cube, xy, vis, init, q_true, r_true = _frames(n, rng=0)
    K = np.array([[F_M / PIXEL_M, 0, CENTRE[0]], [0, F_M / PIXEL_M, CENTRE[1]], [0, 0, 1.0]])
    uv = [np.ascontiguousarray(pixels_from_focal_plane(xy[k, vis[k]], pixel_size_m=PIXEL_M, principal_point_px=CENTRE))
          for k in range(n)]
    pts = [np.ascontiguousarray(cube[vis[k]]) for k in range(n)]

    def sqpnp():
        return [cv2.solvePnP(pts[k], uv[k], K, None, flags=cv2.SOLVEPNP_SQPNP) for k in range(n)]

    def ours_batch():
        return solve_pose_rodrigues(cube, xy, init, focal_length_m=F_M, visible=vis)

    def ours_single(m):
        return [solve_pose_rodrigues(cube, xy[k], GibbsPose(init.g[k], init.gibbs_set[k], init.r_TC_C[k]),
                                     focal_length_m=F_M, visible=vis[k]) for k in range(m)]

    repeat = 1 if quick else 3
    t_peer = best_time(sqpnp, repeat=repeat)
    t_batch = best_time(ours_batch, repeat=repeat)
    m = min(n, 200)
    t_single = best_time(lambda: ours_single(m), repeat=repeat) * n / m

    res = ours_batch()
    assert res.ok.all()
    cv = sqpnp()
    q_cv = quat_from_rotvec(np.array([s[1].ravel() for s in cv]))
    r_cv = np.array([s[2].ravel() for s in cv])
    a_ours = _accuracy(res.q_CT, res.r_TC_C, q_true, r_true)
    a_cv = _accuracy(q_cv, r_cv, q_true, r_true)
    acc = (f"LOS RMS {a_ours[0]:.3f} m vs {a_cv[0]:.3f} m, attitude RMS {a_ours[1]:.3f} deg vs {a_cv[1]:.3f} deg; "
           f"{np.mean(res.iterations):.1f} iterations")
    peer = "OpenCV solvePnP SOLVEPNP_SQPNP, one call per frame"
    return [
        throughput_row(f"001 pose solve, batch of {n} Table-1 frames (vectorised)", t_batch, t_peer, n,
                       "solves/s", peer, note=acc),
        throughput_row("001 pose solve, one call per frame (the tracker's path)", t_single, t_peer, n,
                       "solves/s", peer, note="single-problem calls are numpy-overhead bound"),
    ]
