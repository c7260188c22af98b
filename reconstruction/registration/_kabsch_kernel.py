"""Compiled (Numba) moment pass of the batched Kabsch fit of :mod:`reconstruction.registration`.

:func:`kabsch_batch` reads each problem's points once, for its weighted raw moments (a loop
that vectorises), then treats the problems of a block of ``BLOCK`` together: centred moments,
then the rotation, ``t`` and the RMS residual by the Horn/QCP kernel
:func:`reconstruction.registration.qcp.rotations_block`, in branch-free loops over the problems.
It reproduces, problem by problem, the NumPy reference ``kabsch.kabsch_flat_numpy`` (same
failure codes; NaN rows skipped the same way); the rare problems that the reference hands to an
SVD are flagged for the caller.  Compiled on first use
(a few seconds) and cached on disk (``cache=True``).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from reconstruction.registration.qcp import (
    _COINCIDENT,
    _COLLINEAR,
    _FINITE,
    _G,
    _N_C,
    _N_OUT,
    _PX,
    _PY,
    _PZ,
    _QX,
    _QY,
    _QZ,
    _RECENTRE,
    _RMS,
    _SW,
    _SXX,
    _SXY,
    _SXZ,
    _SYX,
    _SYY,
    _SYZ,
    _SZX,
    _SZY,
    _SZZ,
    _TX,
    _TY,
    _TZ,
    _WEAK,
    BLOCK,
    rotations_block,
)

RECENTRE_RATIO = 1e3  # second pass about the centroids when Σw(|p̄|² + |q̄|²) > RECENTRE_RATIO G

FLAG_NONFINITE_ROWS = 1  # the problem has rows with NaN (skipped)
FLAG_SVD = 2  # the quaternion is ill-determined: the caller refits with the SVD reference
FLAG_INF = 4  # an infinite coordinate was seen: the caller raises
FLAG_RANGE = 8  # Σw(|p|² + |q|²) above MAX_SECOND_MOMENT_M2 (or overflowed): the caller raises

#: Largest accepted raw second moment ``Σ w (|p|² + |q|²)`` of one problem, m²: below it the
#: quartic of the Horn/QCP kernel (``‖S‖⁴``, ``‖adj S‖²``) stays finite; above it (coordinates of
#: about 1e30 m, or squares that overflow) the input is refused as too large.
MAX_SECOND_MOMENT_M2 = 1e60

_JIT = dict(cache=True, nogil=True, error_model="numpy")
# the sums of the fast pass may be reassociated (so that they vectorise); nothing is assumed
# about NaN or inf, which are detected
_FAST = {"reassoc", "contract"}


@numba.njit(fastmath=_FAST, **_JIT)
def _moments_raw(P, Q, W, b, weighted):
    """Raw moments of problem ``b`` over every row (a NaN row shows as NaN in the sums).

    ``P, Q`` flat ``(B, 3N)`` clouds, ``W`` ``(B, N)`` weights when ``weighted``.  Returns
    ``(Σw, Σw p (3), Σw q (3), Σw p qᵀ (9, row-major), Σw (|p|² + |q|²), #(w > 0))``.  Every sum
    has its own accumulator, so that the vectorised loop is not one chain of dependent additions.
    """
    n = P.shape[1] // 3
    sw = 0.0
    npos = 0
    ax = ay = az = bx = by = bz = 0.0
    cxx = cxy = cxz = cyx = cyy = cyz = czx = czy = czz = 0.0
    gx = gy = gz = hx = hy = hz = 0.0
    for i in range(n):
        px = P[b, 3 * i]
        py = P[b, 3 * i + 1]
        pz = P[b, 3 * i + 2]
        qx = Q[b, 3 * i]
        qy = Q[b, 3 * i + 1]
        qz = Q[b, 3 * i + 2]
        if weighted:
            wi = W[b, i]
            sw += wi
            npos += wi > 0.0
            fx, fy, fz = wi * px, wi * py, wi * pz
            kx, ky, kz = wi * qx, wi * qy, wi * qz
        else:
            fx, fy, fz = px, py, pz
            kx, ky, kz = qx, qy, qz
        ax += fx
        ay += fy
        az += fz
        bx += kx
        by += ky
        bz += kz
        gx += fx * px
        gy += fy * py
        gz += fz * pz
        hx += kx * qx
        hy += ky * qy
        hz += kz * qz
        cxx += fx * qx
        cxy += fx * qy
        cxz += fx * qz
        cyx += fy * qx
        cyy += fy * qy
        cyz += fy * qz
        czx += fz * qx
        czy += fz * qy
        czz += fz * qz
    if not weighted:
        sw = float(n)
        npos = n
    g = (gx + gy + gz) + (hx + hy + hz)
    return (sw, ax, ay, az, bx, by, bz, cxx, cxy, cxz, cyx, cyy, cyz, czx, czy, czz, g, npos)


@numba.njit(**_JIT)
def _moments_about(P, Q, W, b, weighted, x0, y0, z0, u0, v0, s0):
    """:func:`_moments_raw` of ``p − (x0, y0, z0)`` and ``q − (u0, v0, s0)``, skipping the rows
    with a non-finite coordinate in either cloud; also returns ``(skipped any, saw an inf)``."""
    n = P.shape[1] // 3
    sw = 0.0
    npos = 0
    ax = ay = az = bx = by = bz = 0.0
    cxx = cxy = cxz = cyx = cyy = cyz = czx = czy = czz = 0.0
    g = 0.0
    skipped = False
    inf = False
    for i in range(n):
        px, py, pz = P[b, 3 * i], P[b, 3 * i + 1], P[b, 3 * i + 2]
        qx, qy, qz = Q[b, 3 * i], Q[b, 3 * i + 1], Q[b, 3 * i + 2]
        if not (math.isfinite(px) and math.isfinite(py) and math.isfinite(pz)
                and math.isfinite(qx) and math.isfinite(qy) and math.isfinite(qz)):
            skipped = True
            if (math.isinf(px) or math.isinf(py) or math.isinf(pz) or math.isinf(qx)
                    or math.isinf(qy) or math.isinf(qz)):
                inf = True
            continue
        wi = W[b, i] if weighted else 1.0
        sw += wi
        npos += wi > 0.0
        dx, dy, dz = px - x0, py - y0, pz - z0
        ex, ey, ez = qx - u0, qy - v0, qz - s0
        g += wi * (dx * dx + dy * dy + dz * dz + ex * ex + ey * ey + ez * ez)
        dx *= wi
        dy *= wi
        dz *= wi
        ax += dx
        ay += dy
        az += dz
        bx += wi * ex
        by += wi * ey
        bz += wi * ez
        cxx += dx * ex
        cxy += dx * ey
        cxz += dx * ez
        cyx += dy * ex
        cyy += dy * ey
        cyz += dy * ez
        czx += dz * ex
        czy += dz * ey
        czz += dz * ez
    return ((sw, ax, ay, az, bx, by, bz, cxx, cxy, cxz, cyx, cyy, cyz, czx, czy, czz, g, npos),
            skipped, inf)


# rows of the per-block scratch arrays (a struct of arrays, so that the loops over the problems of
# a block vectorise): raw moments (as returned by _moments_raw), centred moments, results
_M_G = 16
_N_M = 17


@numba.njit(**_JIT)
def _centre(mo, nb, st):
    """Centroids and moments about them (``S = Σw p qᵀ − Σw p̄ q̄ᵀ``, ``G`` likewise) of the
    ``nb`` problems of a block, from their raw moments ``mo`` into ``st``; flags ``_RECENTRE``
    where that subtraction cancels too many digits."""
    for k in range(nb):
        sw = mo[0, k]
        px, py, pz = mo[1, k] / sw, mo[2, k] / sw, mo[3, k] / sw
        qx, qy, qz = mo[4, k] / sw, mo[5, k] / sw, mo[6, k] / sw
        offset = sw * (px * px + py * py + pz * pz + qx * qx + qy * qy + qz * qz)
        G = mo[_M_G, k] - offset
        st[_RECENTRE, k] = 1.0 if offset > RECENTRE_RATIO * abs(G) else 0.0
        st[_SXX, k] = mo[7, k] - sw * px * qx
        st[_SXY, k] = mo[8, k] - sw * px * qy
        st[_SXZ, k] = mo[9, k] - sw * px * qz
        st[_SYX, k] = mo[10, k] - sw * py * qx
        st[_SYY, k] = mo[11, k] - sw * py * qy
        st[_SYZ, k] = mo[12, k] - sw * py * qz
        st[_SZX, k] = mo[13, k] - sw * pz * qx
        st[_SZY, k] = mo[14, k] - sw * pz * qy
        st[_SZZ, k] = mo[15, k] - sw * pz * qz
        st[_G, k] = G
        st[_SW, k] = sw
        st[_PX, k], st[_PY, k], st[_PZ, k] = px, py, pz
        st[_QX, k], st[_QY, k], st[_QZ, k] = qx, qy, qz


@numba.njit(**_JIT)
def _recentre(P, Q, W, b, weighted, st, k):
    """Redo the centred moments of problem ``b`` (column ``k`` of ``st``) by a second pass over
    its points, about the centroids of the first (clouds far from the origin for their size)."""
    sw = st[_SW, k]
    x0, y0, z0 = st[_PX, k], st[_PY, k], st[_PZ, k]
    u0, v0, s0 = st[_QX, k], st[_QY, k], st[_QZ, k]
    m, _, _ = _moments_about(P, Q, W, b, weighted, x0, y0, z0, u0, v0, s0)
    dx, dy, dz = m[1] / sw, m[2] / sw, m[3] / sw
    ex, ey, ez = m[4] / sw, m[5] / sw, m[6] / sw
    st[_G, k] = m[16] - sw * (dx * dx + dy * dy + dz * dz + ex * ex + ey * ey + ez * ez)
    st[_SXX, k] = m[7] - sw * dx * ex
    st[_SXY, k] = m[8] - sw * dx * ey
    st[_SXZ, k] = m[9] - sw * dx * ez
    st[_SYX, k] = m[10] - sw * dy * ex
    st[_SYY, k] = m[11] - sw * dy * ey
    st[_SYZ, k] = m[12] - sw * dy * ez
    st[_SZX, k] = m[13] - sw * dz * ex
    st[_SZY, k] = m[14] - sw * dz * ey
    st[_SZZ, k] = m[15] - sw * dz * ez
    st[_PX, k], st[_PY, k], st[_PZ, k] = x0 + dx, y0 + dy, z0 + dz
    st[_QX, k], st[_QY, k], st[_QZ, k] = u0 + ex, v0 + ey, s0 + ez


@numba.njit(**_JIT)
def kabsch_batch(P: np.ndarray, Q: np.ndarray, W: np.ndarray, weighted: bool, R: np.ndarray,
                 t: np.ndarray, rms: np.ndarray, code: np.ndarray, npts: np.ndarray,
                 flags: np.ndarray) -> None:
    """Weighted Kabsch fits of ``B`` problems, written into the output arrays.

    Blocks of ``BLOCK`` problems: the raw moments of each problem in one pass over its points
    (:func:`_moments_raw`; the rows with NaN skipped by :func:`_moments_about` where the sums
    come out non-finite), then, for the block together, the centred moments (:func:`_centre`,
    with a second pass for the rare problems that need it), the rotations, ``t`` and the RMS
    (:func:`reconstruction.registration.qcp.rotations_block`).

    Parameters
    ----------
    P, Q : ndarray (B, 3N) float64, C-contiguous
        Flat clouds (rows ``(x, y, z)`` of each point one after the other), m.
    W : ndarray (B, N) float64
        Weights (read only when ``weighted``; pass any ``(1, N)`` array otherwise).
    weighted : bool
    R : ndarray (B, 3, 3), t : ndarray (B, 3), rms : ndarray (B,)
        Outputs (NaN for failures and for problems flagged ``FLAG_SVD``).
    code : ndarray (B,) int8
        0 ok, 1 fewer than 3 usable points, 2 collinear, 3 coincident.
    npts : ndarray (B,) int64
        Usable points (finite in both clouds, w > 0).
    flags : ndarray (B,) uint8
        ``FLAG_NONFINITE_ROWS``, ``FLAG_SVD``, ``FLAG_INF``, ``FLAG_RANGE`` bits.
    """
    B = P.shape[0]
    mo = np.empty((_N_M, BLOCK))
    st = np.empty((_N_C, BLOCK))
    out = np.empty((_N_OUT, BLOCK))
    for a in range(0, B, BLOCK):
        nb = min(BLOCK, B - a)
        for k in range(nb):
            b = a + k
            m = _moments_raw(P, Q, W, b, weighted)
            f = 0
            # any NaN or ±inf coordinate (weighted or not) makes Σw(|p|² + |q|²) non-finite; when
            # it is finite, so are the other sums (Cauchy–Schwarz)
            if not math.isfinite(m[_M_G]):  # the same sums over the finite rows
                m, skipped, inf = _moments_about(P, Q, W, b, weighted, 0.0, 0.0, 0.0, 0.0, 0.0,
                                                 0.0)
                f = (FLAG_NONFINITE_ROWS if skipped else 0) | (FLAG_INF if inf else 0)
            if not m[_M_G] <= MAX_SECOND_MOMENT_M2 and not f & FLAG_INF:
                f |= FLAG_RANGE
            (mo[0, k], mo[1, k], mo[2, k], mo[3, k], mo[4, k], mo[5, k], mo[6, k], mo[7, k],
             mo[8, k], mo[9, k], mo[10, k], mo[11, k], mo[12, k], mo[13, k], mo[14, k], mo[15, k],
             mo[16, k], npts[b]) = m
            flags[b] = f
        _centre(mo, nb, st)
        for k in range(nb):
            if st[_RECENTRE, k] != 0.0:
                _recentre(P, Q, W, a + k, weighted, st, k)
        rotations_block(st, nb, out)
        for k in range(nb):
            b = a + k
            c = 0
            if npts[b] < 3:
                c = 1
            elif out[_COINCIDENT, k] != 0.0:
                c = 3
            elif out[_FINITE, k] == 0.0 or out[_COLLINEAR, k] != 0.0:
                c = 2
            elif out[_WEAK, k] != 0.0:
                flags[b] |= FLAG_SVD
            code[b] = c
            if c == 0 and not flags[b] & FLAG_SVD:
                R[b, 0, 0], R[b, 0, 1], R[b, 0, 2] = out[0, k], out[1, k], out[2, k]
                R[b, 1, 0], R[b, 1, 1], R[b, 1, 2] = out[3, k], out[4, k], out[5, k]
                R[b, 2, 0], R[b, 2, 1], R[b, 2, 2] = out[6, k], out[7, k], out[8, k]
                t[b, 0], t[b, 1], t[b, 2] = out[_TX, k], out[_TY, k], out[_TZ, k]
                rms[b] = out[_RMS, k]
            else:
                for i in range(3):
                    t[b, i] = np.nan
                    for j in range(3):
                        R[b, i, j] = np.nan
                rms[b] = np.nan
