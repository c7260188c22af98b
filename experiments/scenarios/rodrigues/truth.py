"""The truth of the 001 scenario: relative pose of the cube target in the camera frame, and its visible vertices.

Attitude model (flag P001-5, docs/papers.md#p001-5): each spacecraft's Table 1 angles are 3-2-1
(yaw, pitch, roll) Euler angles of its body B relative to its *orbital reference frame* O, and the
Table 1 rates are constant body rates relative to O, ``R_OB(t) = R_OB(0) exp([ω_B×] t)``.  O turns
with the spacecraft's own Hill frame H (x radial, y along-track, z normal) and is the camera-pointing
frame ``x_O = −z_H``, ``y_O = −x_H`` (nadir, image "down"), ``z_O = y_H`` (along-track, at the target);
the camera frame is the chaser body (boresight z).  Under this reading the relative rotation
target→camera passes 180° at 2228.6 s.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from attitude.quaternion import (
    matrix_from_quat,
    quat_from_matrix,
)
from experiments.scenarios.rodrigues.config import Config
from orbits.hill import hill_frame

__all__ = ["R_HO", "cube_vertices", "visible_vertices", "truth_001", "crossing_times_s"]

#: Orbital reference frame O of the Table 1 Euler angles, in H components (columns x_O, y_O, z_O).
R_HO = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])


def cube_vertices(edge_m: float) -> np.ndarray:
    """The 8 vertices ``(8, 3)`` of a cube centred on the target origin, body frame, m."""
    h = 0.5 * edge_m
    return np.array([[x, y, z] for x in (-h, h) for y in (-h, h) for z in (-h, h)])


def visible_vertices(R_CT: np.ndarray, r_TC_C: np.ndarray, edge_m: float) -> np.ndarray:
    """``(..., 8)``: a vertex is visible if one of its faces has ``n·(c − p) > 0`` (outward normal n, face point p, camera c)."""
    c_T = -np.einsum("...ji,...j->...i", R_CT, r_TC_C)  # camera position in the target frame
    V = cube_vertices(edge_m)
    vis = np.zeros(c_T.shape[:-1] + (8,), bool)
    for k in range(3):
        for s in (-1.0, 1.0):
            vis |= (s * c_T[..., k] - 0.5 * edge_m > 0)[..., None] & (s * V[:, k] > 0)
    return vis


def truth_001(cfg: Config, t_s: np.ndarray) -> dict[str, np.ndarray]:
    """Relative pose truth at epochs ``t_s`` (T,).

    Returns ``R_CT (T,3,3)``, ``r_TC_C (T,3)`` (m), ``R_HC (T,3,3)`` (chaser Hill frame from camera)
    and ``range_m (T,)``.
    """
    r_c, v_c = cfg.chaser.orbit().state_N(t_s)
    r_t, v_t = cfg.target.orbit().state_N(t_s)
    R_NHc = hill_frame(r_c, v_c)
    R_NHt = hill_frame(r_t, v_t)
    R_OS = matrix_from_quat(cfg.chaser.q_OB(t_s))  # camera C = chaser body S
    R_OT = matrix_from_quat(cfg.target.q_OB(t_s))
    R_HC = R_HO @ R_OS
    R_NC = R_NHc @ R_HC
    R_CN = np.swapaxes(R_NC, -1, -2)
    R_CT = R_CN @ R_NHt @ R_HO @ R_OT
    r_TC_C = np.einsum("tij,tj->ti", R_CN, r_t - r_c)
    return {"R_CT": R_CT, "r_TC_C": r_TC_C, "R_HC": R_HC, "range_m": np.linalg.norm(r_t - r_c, axis=-1)}


def crossing_times_s(cfg: Config, t_s: np.ndarray) -> np.ndarray:
    """Times where the relative rotation target→camera passes exactly 180° (scalar part of q_CT = 0).

    The quaternion is made sign-continuous over the epochs; each sign change of its scalar part is
    refined with Brent's method on the continuous truth.
    """
    q = quat_from_matrix(truth_001(cfg, t_s)["R_CT"])
    for k in range(1, len(q)):
        if q[k] @ q[k - 1] < 0:
            q[k] = -q[k]
    out = []
    for k in np.flatnonzero(np.sign(q[:-1, 0]) * np.sign(q[1:, 0]) < 0):
        ref = q[k]

        def w(t, ref=ref):
            qq = quat_from_matrix(truth_001(cfg, np.array([t]))["R_CT"])[0]
            return qq[0] * np.sign(qq @ ref)

        out.append(brentq(w, t_s[k], t_s[k + 1], xtol=1e-6))
    return np.array(out)
