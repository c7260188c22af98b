"""Weighted Kabsch/Umeyama rigid fit ``Q ≈ R P + t`` in closed form, batched (003 eq (11)–(13)).

:func:`fit_rigid` minimises 003 eq (12), ``Σ wᵢ ‖Qᵢ − R Pᵢ − t‖²`` (weights ``1/(W_ρ + ε₀)`` of
flag P003-4, docs/papers.md#p003-4), by the closed form of 000 eq (27)–(38).  The moments of every
problem come from one pass over its points (the compiled kernel
:mod:`reconstruction.registration._kabsch_kernel`, or the NumPy reference
:func:`kabsch_flat_numpy`), the rotation from the Horn/QCP kernel of
:mod:`reconstruction.registration.qcp`.  A batch of 10⁴ problems is one call.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from reconstruction._geometry import as_float, check_points, scalar_or_array
from reconstruction.registration import _kabsch_kernel
from reconstruction.registration._kabsch_kernel import MAX_SECOND_MOMENT_M2
from reconstruction.registration.qcp import COINCIDENT_TOL, rotations_from_correlations
from reconstruction.registration.result import KABSCH_REASONS, RigidRegistration

__all__ = ["MAX_SECOND_MOMENT_M2", "check_second_moments", "fit_rigid", "kabsch_flat", "kabsch_flat_numpy",
           "prepare_clouds"]

_CHUNK_COORDS = 38_400  # coordinates per cloud per chunk of the moment pass (300 kB, in cache)
_SUM_GEMM_MAX_N = 4096  # up to this many points, coordinate sums by one GEMM per chunk

#: ``(R (B, 3, 3), t (B, 3), code (B,) int8, npts (B,) int, rms (B,), rows (B, N) bool or None)``
KabschFlat = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]


def _moment_chunks(P: np.ndarray, Q: np.ndarray, w: np.ndarray | None, c: int, pairs: bool,
                   T6: np.ndarray | None, M: np.ndarray | None, S: np.ndarray, sp: np.ndarray,
                   sq: np.ndarray, gp: np.ndarray, gq: np.ndarray) -> None:
    """Raw moments of :func:`_moments`, chunk by chunk, into ``S, sp, sq, gp, gq``."""
    B, N = P.shape[0], P.shape[1]
    if w is None and P.flags.c_contiguous and Q.flags.c_contiguous:
        # views made once: the loop below only slices them
        Pf, Qf = P.reshape(B, 3 * N), Q.reshape(B, 3 * N)
        if pairs:
            P2t = np.swapaxes(P.reshape(B, N // 2, 6), -1, -2)
            Q2 = Q.reshape(B, N // 2, 6)
        for a in range(0, B, c):
            e = min(a + c, B)
            pf, qf = Pf[a:e], Qf[a:e]
            if pairs:
                t6 = np.matmul(P2t[a:e], Q2[a:e], out=T6[:e - a])
                np.add(t6[:, :3, :3], t6[:, 3:, 3:], out=S[a:e])
            else:
                np.matmul(np.swapaxes(P[a:e], -1, -2), Q[a:e], out=S[a:e])
            if M is not None:
                np.matmul(pf, M, out=sp[a:e])
                np.matmul(qf, M, out=sq[a:e])
            else:
                np.sum(P[a:e], axis=1, out=sp[a:e])
                np.sum(Q[a:e], axis=1, out=sq[a:e])
            np.vecdot(pf, pf, out=gp[a:e])
            np.vecdot(qf, qf, out=gq[a:e])
        return
    for a in range(0, B, c):
        e = min(a + c, B)
        k = e - a
        p = np.ascontiguousarray(P[a:e])
        q = np.ascontiguousarray(Q[a:e])
        if w is None:
            pw, qw = p, q
        else:
            ww = w[a:e, :, None]
            pw, qw = p * ww, q * ww
        if pairs:
            t6 = np.matmul(np.swapaxes(pw.reshape(k, N // 2, 6), -1, -2),
                           q.reshape(k, N // 2, 6), out=T6[:k])
            np.add(t6[:, :3, :3], t6[:, 3:, 3:], out=S[a:e])
        else:
            np.matmul(np.swapaxes(pw, -1, -2), q, out=S[a:e])
        pf, qf = p.reshape(k, 3 * N), q.reshape(k, 3 * N)
        pwf, qwf = pw.reshape(k, 3 * N), qw.reshape(k, 3 * N)
        if M is not None:
            np.matmul(pwf, M, out=sp[a:e])
            np.matmul(qwf, M, out=sq[a:e])
        else:
            np.sum(pw, axis=1, out=sp[a:e])
            np.sum(qw, axis=1, out=sq[a:e])
        np.vecdot(pwf, pf, out=gp[a:e])
        np.vecdot(qwf, qf, out=gq[a:e])


def _moments(P: np.ndarray, Q: np.ndarray, w: np.ndarray | None
             ) -> tuple[np.ndarray, ...]:
    """Weighted centroids, centred correlation ``S = Σ w p̃ q̃ᵀ``, total weight and centred second
    moment ``G = Σ w (|p̃|² + |q̃|²)`` of ``(B, N, 3)`` clouds, in one pass over the data.

    The data are read once, in chunks of about 300 kB per cloud: the first product (BLAS) streams
    a chunk into cache and the other raw moments of that chunk are formed while it is there.
    ``S`` comes from one small GEMM per problem on the points taken two at a time
    (``(6, N/2) @ (N/2, 6)``, whose diagonal 3×3 blocks add up to ``Σ p qᵀ``; about twice as fast
    as the ``(3, N) @ (N, 3)`` product, which has too little work per BLAS call), the coordinate
    sums from one GEMM per chunk with a fixed ``(3N, 3)`` 0/1 matrix, and ``Σ |p|²`` from row dot
    products.  Weights scale a chunk of each cloud once.  A problem with a non-finite row gives
    non-finite moments (the caller masks and recomputes).
    """
    B, N = P.shape[0], P.shape[1]
    c = max(1, _CHUNK_COORDS // max(3 * N, 1))
    S = np.empty((B, 3, 3))
    sp = np.empty((B, 3))
    sq = np.empty((B, 3))
    gp = np.empty(B)
    gq = np.empty(B)
    pairs = N % 2 == 0 and N >= 8
    T6 = np.empty((min(c, B), 6, 6)) if pairs else None
    M = np.tile(np.eye(3), (N, 1)) if N <= _SUM_GEMM_MAX_N else None  # (3N, 3): Pf @ M = Σ p
    with np.errstate(invalid="ignore", over="ignore"):  # ±inf input: the caller raises
        _moment_chunks(P, Q, w, c, pairs, T6, M, S, sp, sq, gp, gq)
    g = gp + gq
    sw = np.full(B, float(N)) if w is None else np.sum(w, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        pbar = sp / sw[:, None]
        qbar = sq / sw[:, None]
        S -= sw[:, None, None] * pbar[:, :, None] * qbar[:, None, :]
        offset = sw * (np.vecdot(pbar, pbar) + np.vecdot(qbar, qbar))
        G = g - offset
    # cancellation guard: clouds far from the origin relative to their spread are recentred
    redo = np.nonzero(offset > 1e6 * np.abs(G))[0]
    if redo.size:
        Pc = P[redo] - pbar[redo, None, :]
        Qc = Q[redo] - qbar[redo, None, :]
        wr = np.ones(Pc.shape[:2]) if w is None else w[redo]
        S[redo] = np.swapaxes(Pc * wr[..., None], -1, -2) @ Qc
        G[redo] = np.einsum("bni,bni,bn->b", Pc, Pc, wr) + np.einsum("bni,bni,bn->b", Qc, Qc, wr)
    return pbar, qbar, S, sw, G


def prepare_clouds(P: ArrayLike, Q: ArrayLike, weights: ArrayLike | None, *,
                   names: tuple[str, str] = ("P", "Q"), scan: bool = True
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Checked clouds broadcast to one shape ``(..., N, 3)`` and weights to ``(..., N)``.

    Parameters
    ----------
    P, Q : array_like (..., N, 3)
        Matched clouds, m (NaN rows allowed, ±inf rejected when ``scan``).
    weights : array_like (..., N) or None
        Non-negative finite weights.
    names : tuple of str
        Argument names used in the error messages.
    scan : bool
        Scan the points for infinite values here (else the caller detects them).

    Returns
    -------
    P, Q : ndarray (..., N, 3)
        Read-only broadcast views.
    w : ndarray (..., N) or None
    """
    P = check_points(P, names[0], scan=scan)
    Q = check_points(Q, names[1], scan=scan)
    try:
        shape = np.broadcast_shapes(P.shape, Q.shape)
    except ValueError:
        raise ValueError(f"{names[0]}, {names[1]}: shapes {P.shape} and {Q.shape} do not "
                         "broadcast") from None
    P = np.broadcast_to(P, shape)
    Q = np.broadcast_to(Q, shape)
    if weights is not None:
        w = as_float(weights, "weights")
        if np.any(~np.isfinite(w)) or np.any(w < 0):
            raise ValueError("weights: must be finite and >= 0")
        try:
            w = np.broadcast_to(w, shape[:-1])
        except ValueError:
            raise ValueError(f"weights: shape {w.shape} does not broadcast to {shape[:-1]}") from None
    else:
        w = None
    return P, Q, w


def readonly_c(a: np.ndarray) -> np.ndarray:
    """C-contiguous float64 read-only view (a copy only when needed): the compiled kernel then
    sees one array type, whether the caller's arrays are writable or broadcast views."""
    v = np.ascontiguousarray(a, dtype=float).view()
    v.flags.writeable = False
    return v


def kabsch_flat(P: np.ndarray, Q: np.ndarray, w: np.ndarray | None) -> KabschFlat:
    """Weighted Kabsch on flat ``(B, N, 3)`` problems (NaN rows ignored), compiled.

    Returns ``R, t, code, npts, rms, rows``: failure code per problem (0 ok, 1 too few points,
    2 collinear, 3 coincident), usable-point count, weighted RMS residual (m), and the ``(B, N)``
    mask of usable rows (``None`` when every row of every problem is finite).

    The compiled kernel :func:`reconstruction.registration._kabsch_kernel.kabsch_batch` reads
    each problem's points once (weighted raw moments; a second pass, from cache, only for
    problems with NaN rows or clouds far from the origin for their size), then solves the
    rotations of 64 problems at a time with the Horn/QCP kernel
    :func:`reconstruction.registration.qcp.rotations_block`.  It agrees with
    :func:`kabsch_flat_numpy`, the NumPy reference, to rounding, with the same failure codes;
    the rare problems whose quaternion is ill-determined are handed to that reference (which
    solves them by SVD).
    """
    B, N = P.shape[0], P.shape[1]
    Pf = readonly_c(P).reshape(B, 3 * N)
    Qf = readonly_c(Q).reshape(B, 3 * N)
    weighted = w is not None
    W = readonly_c(w if weighted else np.zeros((1, N)))
    R = np.empty((B, 3, 3))
    t = np.empty((B, 3))
    rms = np.empty(B)
    code = np.empty(B, dtype=np.int8)
    npts = np.empty(B, dtype=np.int64)
    flags = np.empty(B, dtype=np.uint8)
    _kabsch_kernel.kabsch_batch(Pf, Qf, W, weighted, R, t, rms, code, npts, flags)
    rows = None
    if np.any(flags):
        if np.any(flags & _kabsch_kernel.FLAG_INF):
            raise ValueError("P, Q: contain infinite values (use NaN for absent points)")
        if np.any(flags & _kabsch_kernel.FLAG_RANGE):
            b = int(np.argmax(flags & _kabsch_kernel.FLAG_RANGE))
            vb = np.all(np.isfinite(P[b]), -1) & np.all(np.isfinite(Q[b]), -1)
            with np.errstate(over="ignore", invalid="ignore"):
                g = float(np.sum(np.where(vb, 1.0 if w is None else w[b], 0.0)
                                 * np.sum(np.where(vb[:, None], P[b] ** 2 + Q[b] ** 2, 0.0), -1)))
            raise_too_large(g, b)
        ib = np.nonzero(flags & _kabsch_kernel.FLAG_NONFINITE_ROWS)[0]
        if ib.size:
            rows = np.ones((B, N), bool) if w is None else w > 0
            rows[ib] &= np.all(np.isfinite(P[ib]), -1) & np.all(np.isfinite(Q[ib]), -1)
        iw = np.nonzero(flags & _kabsch_kernel.FLAG_SVD)[0]
        if iw.size:
            R[iw], t[iw], code[iw], npts[iw], rms[iw], _ = kabsch_flat_numpy(
                P[iw], Q[iw], None if w is None else w[iw])
    return R, t, code, npts, rms, rows


def raise_too_large(g: float, b: int) -> None:
    """``ValueError`` for problem ``b`` whose second moment ``g`` exceeds the accepted range."""
    raise ValueError(f"P, Q: coordinates too large: Σ w (|p|² + |q|²) of problem {b} is {g:.3g} m², "
                     f"above {MAX_SECOND_MOMENT_M2:g} m² (the rotation solver would overflow; weights count)")


def check_second_moments(P: np.ndarray, Q: np.ndarray, w: np.ndarray | None) -> None:
    """Refuse flat ``(B, N, 3)`` problems whose raw second moment ``Σ w (|p|² + |q|²)`` over the
    finite rows exceeds :data:`MAX_SECOND_MOMENT_M2` or overflows (``ValueError``, like ±inf)."""
    if P.shape[0] == 0 or P.shape[1] == 0:
        return
    rows = np.all(np.isfinite(P), -1) & np.all(np.isfinite(Q), -1)  # NaN, ±inf: judged elsewhere
    with np.errstate(over="ignore", invalid="ignore"):
        e = np.where(rows, np.sum(P * P + Q * Q, -1), 0.0)
        g = np.sum(e if w is None else np.where(rows, w, 0.0) * e, -1)
    bad = ~(g <= MAX_SECOND_MOMENT_M2)
    if np.any(bad):
        b = int(np.argmax(bad))
        raise_too_large(float(g[b]), b)


def kabsch_flat_numpy(P: np.ndarray, Q: np.ndarray, w: np.ndarray | None) -> KabschFlat:
    """NumPy reference of :func:`kabsch_flat` (same returns): the moments of :func:`_moments`,
    then :func:`reconstruction.registration.qcp.rotations_from_correlations` on the whole batch."""
    B, N = P.shape[0], P.shape[1]
    check_second_moments(P, Q, w)
    pbar, qbar, S, sw, G = _moments(P, Q, w)
    npts = np.full(B, N) if w is None else np.sum(w > 0, axis=-1)
    rows = None
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(S.reshape(B, 9) @ np.ones(9) + G)  # NaN or ±inf in S or G
    if np.any(bad):
        ib = np.nonzero(bad)[0]
        Pb, Qb = P[ib], Q[ib]
        if np.any(np.isinf(Pb)) or np.any(np.isinf(Qb)):
            raise ValueError("P, Q: contain infinite values (use NaN for absent points)")
        vb = np.all(np.isfinite(Pb), -1) & np.all(np.isfinite(Qb), -1)
        wb = vb.astype(float) if w is None else np.where(vb, w[ib], 0.0)
        Pb = np.where(vb[..., None], Pb, 0.0)
        Qb = np.where(vb[..., None], Qb, 0.0)
        pbar[ib], qbar[ib], S[ib], sw[ib], G[ib] = _moments(Pb, Qb, wb)
        npts[ib] = np.sum(wb > 0, axis=-1)
        rows = np.ones((B, N), bool) if w is None else w > 0
        rows[ib] = wb > 0
    R, collinear = rotations_from_correlations(S, G)
    t = qbar - np.einsum("bij,bj->bi", R, pbar)
    lam = np.einsum("bij,bji->b", R, S)
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt(np.maximum(G - 2.0 * lam, 0.0) / sw)
    # A cloud without spread (all points coincident, up to rounding) leaves S at rounding level,
    # where the relative collinearity test above cannot see it: compare |S| with G.
    coincident = np.sqrt(np.einsum("bij,bij->b", S, S)) <= COINCIDENT_TOL * G
    code = np.zeros(B, dtype=np.int8)
    code[collinear] = 2
    code[coincident] = 3
    code[npts < 3] = 1
    fail = code != 0
    if np.any(fail):
        R[fail] = np.nan
        t[fail] = np.nan
        rms[fail] = np.nan
    return R, t, code, npts, rms, rows


def fit_rigid(P: ArrayLike, Q: ArrayLike, weights: ArrayLike | None = None) -> RigidRegistration:
    """Weighted least-squares rigid fit ``Q ≈ R P + t`` (Kabsch/Umeyama with det correction).

    Minimises 003 eq (12), ``Σ wᵢ ‖Qᵢ − R Pᵢ − t‖²``, by the closed form of 000 eq (29)–(38):
    weighted centroids (30), centred correlation ``B = Σ w (Q̃)(P̃)ᵀ = U D Vᵀ`` (33)–(34),
    ``R = U diag(1, 1, det U Vᵀ) Vᵀ`` (37) and ``t = Q̄ − R P̄`` (38), with the corrections of
    flags P000-10, P003-7 and P003-8 (docs/papers.md#p000-10, #p003-7, #p003-8: 6 DOF, ≥ 3
    non-collinear points).  The rotation is computed with Horn's equivalent quaternion
    eigenproblem in closed form (:mod:`reconstruction.registration.qcp`), by a compiled kernel that
    reads each problem's points once, so a batch of 10⁴ problems is a single fast call.

    Parameters
    ----------
    P : array_like (..., N, 3)
        Source points (e.g. the cloud at epoch t, W frame), m.  NaN rows are ignored.
    Q : array_like (..., N, 3)
        Target points, same order (e.g. the cloud at t + Δt), m.  NaN rows are ignored.
    weights : array_like (..., N), optional
        Non-negative weights wᵢ (for 003 eq 12 use ``1/(W_ρ + ε₀)``, flag P003-4).  Default 1.

    Returns
    -------
    RigidRegistration
        ``method="kabsch"``; ``rms_m`` is the weighted RMS residual; ``cov`` and ``chi2`` are NaN.
        Fewer than 3 usable points (an empty ``(0, 3)`` cloud included) or collinear points give
        ``ok=False`` with the reason and NaN ``R``, ``t``.

    Raises
    ------
    ValueError
        For misshapen input, negative or non-finite weights, ±inf coordinates (NaN marks an
        absent point), and for a problem whose second moment ``Σ w (|p|² + |q|²)`` exceeds
        :data:`MAX_SECOND_MOMENT_M2` (coordinates of about 1e30 m, or whose squares overflow).
    """
    P, Q, w = prepare_clouds(P, Q, weights, scan=False)
    shape = P.shape
    batch, N = shape[:-2], shape[-2]
    B = int(np.prod(batch, dtype=np.int64))
    Pf = P.reshape((B, N, 3))
    Qf = Q.reshape((B, N, 3))
    wf = None if w is None else w.reshape((B, N))
    R, t, code, npts, rms, rows = kabsch_flat(Pf, Qf, wf)
    ok = code == 0
    if rows is None and wf is None:
        inliers = np.repeat(ok, N).reshape(batch + (N,))
    else:
        inliers = ((wf > 0 if rows is None else rows) & ok[:, None]).reshape(batch + (N,))
    # the string dtype fits the reasons present (an all-ok batch gives a small array)
    used = np.bincount(code, minlength=len(KABSCH_REASONS)) > 0
    reason = np.array([r if u else "" for r, u in zip(KABSCH_REASONS, used, strict=True)])[code]
    n_in = np.where(ok, npts, 0)
    return RigidRegistration(
        R=R.reshape(batch + (3, 3)), t=t.reshape(batch + (3,)),
        cov=np.full(batch + (6, 6), np.nan), inliers=inliers,
        n_inliers=n_in.reshape(batch), rms_m=rms.reshape(batch), chi2=np.full(batch, np.nan),
        dof=(3 * n_in - 6).reshape(batch), ok=scalar_or_array(ok.reshape(batch)),
        failure_reason=scalar_or_array(reason.reshape(batch)), method="kabsch",
    )


