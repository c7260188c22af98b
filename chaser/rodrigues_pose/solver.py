"""Gauss–Newton pose of a target from the images of its known feature points, with Gibbs-set switching (001).

Paper 001 (Yue & Hou 2010) estimates the pose of a target whose feature points ``X_T`` are known in
its body frame from their images in one camera, by Gauss–Newton on the image residuals.  The
attitude is a Gibbs vector (classical Rodrigues parameters) ``g`` of one of four parameter sets
``i`` (001 eq 4), switched with the transforms ``T_j`` of 001 eq (5) whenever a component exceeds
1, so the parameterisation never reaches its 180° singularity.  Pose parameters and conventions:
:mod:`chaser.rodrigues_pose.pose`; camera model: :mod:`chaser.rodrigues_pose.projection`.

Iteration (001 §2.3)
--------------------
Predicted camera points ``X̄_C = R(g₀) X_T + t₀`` (14), ``X_r = R(g₀) X_T`` (17), predicted image
``x̄ = −f X̄/Z̄`` (20), residual ``Δb = x − x̄`` (21), Jacobian ``A_j = J_c [2[X_r×] | I]`` (18, 25)
with the corrected projection Jacobian of flag P001-1 (docs/papers.md#p001-1)
``J_c = [[−f/Z̄, 0, f X̄/Z̄²], [0, −f/Z̄, f Ȳ/Z̄²]]``, least squares
``ΔX = (AᵀWA)⁻¹AᵀWΔb`` (28), update ``g ← δg * g`` (10) and ``t ← t + Δt`` (11), switch (5), stop
when ``|δg| < ε₁`` and ``|Δt| < ε₂``.  The least-squares step (28) is solved from the
column-equilibrated normal equations, whose eigenvalues give the rank test of (27).

Every function is vectorised over leading batch axes (independent problems: trials, spacecraft,
random attitudes).  Failures are reported per problem in :attr:`RodriguesPoseResult.failure_reason`
(never raised): fewer than 3 visible points, a rank-deficient system, a point behind the camera, the
fixed parameter set of the non-switching variant crossing its singularity, divergence, or no
convergence within ``max_iterations``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from attitude.gibbs import gibbs_switch, shuster_gibbs_compose
from chaser.rodrigues_pose.pose import FAILURE_REASONS, GibbsPose, RodriguesPoseResult
from chaser.rodrigues_pose.projection import check_positive, predict_image_jacobian

__all__ = ["solve_pose_rodrigues", "track_pose_rodrigues"]

_CODE = {name: k + 1 for k, name in enumerate(FAILURE_REASONS)}
_REASON_NAMES = np.array(("",) + FAILURE_REASONS)


def _compose_switch(dg: np.ndarray, g: np.ndarray, i: np.ndarray, eta: float) -> tuple[np.ndarray, np.ndarray]:
    """001 eq (10) then the switching rule (5), safe where the composed set lands exactly on 180°."""
    den = 1.0 - np.sum(dg * g, -1)
    g_new = np.empty_like(g)
    i_new = i.copy()
    reg = den != 0.0
    if np.any(reg):
        g_new[reg] = shuster_gibbs_compose(dg[reg], g[reg])
        g_new[reg], i_new[reg] = gibbs_switch(g_new[reg], i[reg], eta=eta)
    sing = ~reg
    if np.any(sing):
        # g = num/0 lies on the singular surface of set i; T_j (001 eq 5) of the homogeneous form
        # [num, den] with j = argmax |num_j| is finite: T_1(num/den) = [−den, num3, −num2]/num1, etc.
        num = dg[sing] + g[sing] - np.cross(dg[sing], g[sing])
        d = den[sing]
        j = np.argmax(np.abs(num), -1) + 1
        n1, n2, n3 = num[:, 0], num[:, 1], num[:, 2]
        cand = np.stack([np.stack([-d, n3, -n2], -1), np.stack([-n3, -d, n1], -1),
                         np.stack([n2, -n1, -d], -1)], 0)
        rows = np.arange(d.size)
        out = cand[j - 1, rows] / num[rows, j - 1][:, None]
        ii = i[sing]
        g_new[sing] = out
        i_new[sing] = np.where(ii == 0, j, np.where(j == ii, 0, 6 - j - ii))
    return g_new, i_new


def _as_flat_problem(
    points_T: ArrayLike,
    xy_m: ArrayLike,
    visible: ArrayLike | None,
    weights: ArrayLike | None,
    shape: tuple[int, ...],
) -> tuple[tuple[int, ...], np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Check the data of a solve and flatten it to ``B`` problems: ``(batch shape, P, xy, visible, w)``."""
    P = np.asarray(points_T, dtype=float)
    xy = np.asarray(xy_m, dtype=float)
    if P.ndim < 2 or P.shape[-1] != 3:
        raise ValueError(f"points_T: expected shape (..., M, 3), got {P.shape}")
    if not np.all(np.isfinite(P)):
        raise ValueError("points_T: contains non-finite values")
    if xy.ndim < 2 or xy.shape[-1] != 2:
        raise ValueError(f"xy_m: expected shape (..., M, 2), got {xy.shape}")
    M = P.shape[-2]
    if xy.shape[-2] != M:
        raise ValueError(f"xy_m: {xy.shape[-2]} image points for {M} model points in points_T")
    try:
        full = np.broadcast_shapes(shape, P.shape[:-2], xy.shape[:-2])
    except ValueError:
        raise ValueError(f"xy_m: batch shape {xy.shape[:-2]} does not broadcast with points_T "
                         f"{P.shape[:-2]} and initial {shape}") from None
    if visible is None:
        vis = np.all(np.isfinite(xy), -1)
    else:
        vis = np.asarray(visible)
        if vis.dtype != bool:
            raise ValueError(f"visible: expected a bool array, got dtype {vis.dtype}")
        if vis.shape[-1:] != (M,):
            raise ValueError(f"visible: expected shape (..., {M}), got {vis.shape}")
        vis = vis & np.all(np.isfinite(xy), -1)
    if weights is None:
        w = np.ones(M)
    else:
        w = np.asarray(weights, dtype=float)
        if w.shape[-1:] != (M,) or not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ValueError(f"weights: expected non-negative finite weights of shape (..., {M}), got shape {w.shape}")
    full = np.broadcast_shapes(full, vis.shape[:-1], w.shape[:-1])
    B = int(np.prod(full))
    Pb = np.broadcast_to(P, full + (M, 3)).reshape(B, M, 3)
    xyb = np.nan_to_num(np.broadcast_to(xy, full + (M, 2)).reshape(B, M, 2))
    visb = np.broadcast_to(vis, full + (M,)).reshape(B, M) & (np.broadcast_to(w, full + (M,)).reshape(B, M) > 0)
    wb = np.broadcast_to(w, full + (M,)).reshape(B, M)
    return full, Pb, xyb, visb, wb


def solve_pose_rodrigues(
    points_T: ArrayLike,
    xy_m: ArrayLike,
    initial: GibbsPose,
    *,
    focal_length_m: float,
    visible: ArrayLike | None = None,
    weights: ArrayLike | None = None,
    switching: bool = True,
    eta: float = 0.0,
    eps_attitude: float = 1e-8,
    eps_translation_m: float = 1e-5,
    max_iterations: int = 50,
    rcond: float = 1e-6,
) -> RodriguesPoseResult:
    """Pose of a target from the images of its known feature points (001 §2, eq 6–28).

    Gauss–Newton on the focal-plane residuals with the attitude as a Gibbs vector of one of four
    parameter sets, switched by 001 eq (5) whenever ``max |g_j| > 1 + eta``.  With
    ``switching=False`` this is the non-switching solver the paper compares against: the set of
    ``initial`` is kept, and an update that would carry the rotation through that set's 180°
    singularity (composition denominator ``1 − δg·g <= 0`` in eq 10, where ``g`` passes through
    infinity) ends the solve with ``failure_reason = "gibbs_singular"``.

    Parameters
    ----------
    points_T : (M, 3) or (..., M, 3) array
        Feature points in the target body frame, m.
    xy_m : (..., M, 2) array
        Measured focal-plane coordinates (001 eq 7, ``x = −f X_C/Z_C``), m; NaN for unseen points.
    initial : GibbsPose
        Initial guess (001 §2.3: the previous epoch's solution, with its set index), batch shape
        broadcastable with the data.
    focal_length_m : float
        Focal length ``f``, m.
    visible : (..., M) bool array, optional
        Points to use (default: those with finite ``xy_m``).
    weights : (..., M) array, optional
        Per-point weights, the diagonal of ``W`` in eq (28) for both coordinates (default ``W = I``).
    switching : bool
        Use the four-set switching (default) or keep the initial set.
    eta : float
        Switching hysteresis: switch when ``max |g_j| > 1 + eta`` (0 is the paper's rule).
    eps_attitude : float
        ε₁: stop when ``|δg| < eps_attitude`` (dimensionless, ≈ half the angle in rad) ...
    eps_translation_m : float
        ε₂: ... and ``|Δt| < eps_translation_m``, m.
    max_iterations : int
        Updates allowed before ``"not_converged"``.  Typical solves take 4–6; a cube face seen
        head-on (4 coplanar points) leaves a shallow valley where Gauss–Newton contracts only
        ~0.7 per update and needs up to ~40 (a cap of 20 would end those solves early).
    rcond : float
        Rank test of eq (27): the system is rank-deficient when the smallest singular value of the
        column-equilibrated ``√W A`` is below ``rcond`` times the largest (median 0.67 for a
        cube seen from 100 m, 0.0056 for its worst, face-on view; computed through the normal
        equations, so values below ~1e-7 are not resolved).

    Returns
    -------
    RodriguesPoseResult
        Batch shape = broadcast of the data's and ``initial``'s batch shapes.
    """
    f = check_positive(focal_length_m, "focal_length_m")
    check_positive(eps_attitude, "eps_attitude")
    check_positive(eps_translation_m, "eps_translation_m")
    check_positive(rcond, "rcond")
    if not isinstance(initial, GibbsPose):
        raise ValueError(f"initial: expected a GibbsPose, got {type(initial).__name__}")
    if int(max_iterations) != max_iterations or max_iterations < 1:
        raise ValueError(f"max_iterations: must be a positive integer, got {max_iterations!r}")
    if not np.isfinite(eta) or eta < 0:
        raise ValueError(f"eta: hysteresis must be >= 0, got {eta!r}")
    shape, P, xy, vis, w = _as_flat_problem(points_T, xy_m, visible, weights, initial.shape)
    B, M = vis.shape
    g = np.broadcast_to(initial.g, shape + (3,)).reshape(B, 3).copy()
    i = np.broadcast_to(initial.gibbs_set, shape).reshape(B).astype(int).copy()
    t = np.broadcast_to(initial.r_TC_C, shape + (3,)).reshape(B, 3).copy()
    if np.any((i < 0) | (i > 3)):
        raise ValueError(f"initial: gibbs_set must be in 0..3, got {np.unique(i)!r}")

    code = np.zeros(B, np.int8)  # 0 running/converged, else 1 + index in FAILURE_REASONS
    n_pts = vis.sum(-1)
    code[n_pts < 3] = _CODE["too_few_points"]
    code[(code == 0) & ~np.all(np.isfinite(g), -1)] = _CODE["gibbs_singular"]  # initial set at 180°
    code[(code == 0) & ~np.all(np.isfinite(t), -1)] = _CODE["diverged"]
    done = np.zeros(B, bool)
    iters = np.zeros(B, int)
    switches = np.zeros(B, int)
    wgt_all = (np.sqrt(w) * vis)[..., None]
    limit = 1.0 + eta

    rms = np.full(B, np.nan)
    for _ in range(int(max_iterations)):
        act = np.flatnonzero((code == 0) & ~done)
        if act.size == 0:
            break
        ga, ia, ta, va = g[act], i[act], t[act], vis[act]
        xbar, Z, Aj = predict_image_jacobian(P[act], ga, ia, ta, f)
        wgt = wgt_all[act]
        fail = np.zeros(act.size, np.int8)
        behind = ~(Z > 0) & va
        if behind.any():  # (14): the linearisation is meaningless for a point behind the camera
            fail[behind.any(-1)] = _CODE["behind_camera"]
            xbar = np.where(behind[..., None], 0.0, xbar)
            Aj = np.where(behind[..., None, None], 0.0, Aj)
        res = xy[act] - xbar  # (21), (24)
        db = (res * wgt).reshape(act.size, 2 * M)  # (27)
        A = (Aj * wgt[..., None]).reshape(act.size, 2 * M, 6)  # (25), (27)
        # (28) by the normal equations of the column-equilibrated system; its eigenvalues give the
        # rank test of (27) (squared singular values of the equilibrated √W A).
        At = A.transpose(0, 2, 1)
        N = At @ A
        col = np.sqrt(N.diagonal(0, 1, 2))
        deficient = ~(col > 0).all(-1)
        if deficient.any():
            col = np.where(col > 0, col, 1.0)
        Ns = N / (col[:, :, None] * col[:, None, :])
        lam = np.linalg.eigvalsh(Ns)
        deficient |= ~(lam[:, 0] > (rcond * rcond) * lam[:, -1])
        if deficient.any():
            Ns[deficient] = np.eye(6)  # solved but discarded: keeps the batched solve non-singular
        dX = np.linalg.solve(Ns, (At @ db[..., None]) / col[..., None])[..., 0] / col
        fail[(fail == 0) & deficient] = _CODE["rank_deficient"]
        dg, dt = dX[:, :3], dX[:, 3:]
        den = 1.0 - (dg * ga).sum(-1)  # denominator of (10)
        if not switching:
            fail[(fail == 0) & ~(den > 0.0)] = _CODE["gibbs_singular"]
        fail[(fail == 0) & ~np.isfinite(dX).all(-1)] = _CODE["diverged"]
        good = fail == 0
        if not good.all():
            code[act[~good]] = fail[~good]
            act, ga, ia, ta, dg, dt, den, dX, res, Aj, va = (
                x[good] for x in (act, ga, ia, ta, dg, dt, den, dX, res, Aj, va))
        if act.size == 0:
            continue
        if switching and not (den != 0.0).all():
            g_new, i_new = _compose_switch(dg, ga, ia, eta)
        else:
            g_new, i_new = shuster_gibbs_compose(dg, ga), ia  # (10)
            if switching and (np.abs(g_new) > limit).any():
                g_new, i_new = gibbs_switch(g_new, ia, eta=eta)  # switching rule, (5)
        t_new = ta + dt  # (11)
        finite = np.isfinite(g_new).all(-1) & np.isfinite(t_new).all(-1)
        if not finite.all():
            code[act[~finite]] = _CODE["diverged"]
        g[act], i[act], t[act] = g_new, i_new, t_new
        switches[act] += i_new != ia
        iters[act] += 1
        conv = finite & ((dg * dg).sum(-1) < eps_attitude**2) & ((dt * dt).sum(-1) < eps_translation_m**2)
        if conv.any():
            done[act[conv]] = True
            # residual at the returned pose, to first order in the last update (|ΔX| below ε)
            r_new = (res[conv] - (Aj[conv] @ dX[conv, None, :, None])[..., 0]) * va[conv][..., None]
            rms[act[conv]] = np.sqrt((r_new * r_new).sum((-1, -2)) / (2 * n_pts[act[conv]]))
    code[(code == 0) & ~done] = _CODE["not_converged"]
    ok = code == 0
    rms[~ok] = np.nan
    g[~ok] = np.nan
    t[~ok] = np.nan
    reason = _REASON_NAMES[code]
    pose = GibbsPose(g.reshape(shape + (3,)), i.reshape(shape), t.reshape(shape + (3,)))
    return RodriguesPoseResult(pose, ok.reshape(shape), reason.reshape(shape), iters.reshape(shape),
                               switches.reshape(shape), n_pts.reshape(shape), rms.reshape(shape))


def track_pose_rodrigues(
    points_T: ArrayLike,
    xy_m: ArrayLike,
    initial: GibbsPose,
    *,
    focal_length_m: float,
    visible: ArrayLike | None = None,
    **options: Any,
) -> RodriguesPoseResult:
    """Solve a sequence of epochs, each warm-started from the last successful solution (001 §2.3).

    After a failed epoch (too few points, rank deficiency, ...) the next epoch starts again from the
    last pose that succeeded, so one bad frame does not end the track.  For the non-switching variant
    a singular crossing is not recoverable this way: every later update from the last good pose has
    to cross the same singularity, as in the paper, where the program stops at 2228.6 s.

    Parameters
    ----------
    points_T : (M, 3) or (..., M, 3) array
        Feature points in the target body frame, m (fixed over time).
    xy_m : (K, ..., M, 2) array
        Measured focal-plane coordinates, epoch axis first, m; NaN for unseen points.
    initial : GibbsPose
        Initial guess for the first epoch.
    focal_length_m : float
    visible : (K, ..., M) bool array, optional
    **options
        Keyword options of :func:`solve_pose_rodrigues` (``switching``, ``eps_attitude``, ...).

    Returns
    -------
    RodriguesPoseResult
        With the epoch axis first, ``(K, ...)``.
    """
    xy = np.asarray(xy_m, dtype=float)
    if xy.ndim < 3 or xy.shape[-1] != 2:
        raise ValueError(f"xy_m: expected shape (K, ..., M, 2), got {xy.shape}")
    vis = None if visible is None else np.asarray(visible)
    if vis is not None and vis.shape[:1] != xy.shape[:1]:
        raise ValueError(f"visible: expected {xy.shape[0]} epochs on axis 0, got shape {vis.shape}")
    current = initial
    out = []
    for k in range(xy.shape[0]):
        res = solve_pose_rodrigues(points_T, xy[k], current, focal_length_m=focal_length_m,
                                   visible=None if vis is None else vis[k], **options)
        if res.pose.shape != current.shape:
            current = GibbsPose(*(np.broadcast_to(a, res.pose.shape + a.shape[len(current.shape):]).copy()
                                  for a in (current.g, current.gibbs_set, current.r_TC_C)))
        current = res.pose.where(res.ok, current)
        out.append(res)
    stack = [np.stack([getattr(r, name) for r in out]) for name in
             ("ok", "failure_reason", "iterations", "switches", "n_points", "residual_rms_m")]
    pose = GibbsPose(np.stack([r.pose.g for r in out]), np.stack([r.pose.gibbs_set for r in out]),
                     np.stack([r.pose.r_TC_C for r in out]))
    return RodriguesPoseResult(pose, *stack)
