"""Horn's quaternion / Theobald's QCP rotation of a rigid fit, compiled (Numba): the one kernel.

The rotation maximising ``tr(R S)`` for the centred correlation ``S = Σ w p̃ q̃ᵀ`` (so that
``q̃ ≈ R p̃``, 003 eq (12)) is the eigenvector of the largest eigenvalue λ of Horn's traceless
symmetric 4×4 matrix N(S).  λ is found by Newton's method on the characteristic quartic of N(S)
(Theobald's QCP) and the eigenvector as a column of adj(N − λI).  A unit quaternion is always a
proper rotation, so this is the determinant-corrected solution ``U diag(1, 1, det UVᵀ) Vᵀ`` of
000 eq (37) (flag P000-10, docs/papers.md#p000-10) at a small fraction of the cost of a 3×3 SVD.

:func:`rotations_block` works on the problems of one block laid out as a struct of arrays (rows
``_SXX`` … ``_SW`` of ``st``), so that its loops over the problems vectorise; the compiled moment
pass of :mod:`reconstruction.registration._kabsch_kernel` fills that layout directly.
:func:`rotations_from_correlations` is the NumPy-facing entry: any ``(B, 3, 3)`` stack of
correlations, with the SVD for the rare problems whose eigenvector is ill-determined.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from reconstruction._geometry import proper_rotation_from_svd

__all__ = ["COINCIDENT_TOL", "COLLINEAR_TOL", "rotations_block", "rotations_from_correlations"]

COLLINEAR_TOL = 1e-9  # rank(S) <= 1 when ‖adj S‖ <= COLLINEAR_TOL ‖S‖²
COINCIDENT_TOL = 1e-9  # no spread when ‖S‖ <= COINCIDENT_TOL G

_JIT = dict(cache=True, nogil=True, error_model="numpy")

# rows of the per-block scratch arrays (a struct of arrays, so that the loops over the problems of
# a block vectorise).  ``st``: centred correlation S (row-major), G = Σw(|p̃|² + |q̃|²), Σw, the
# centroids p̄ and q̄, and one row the caller may use for its own flag.  ``out``: R (rows 0–8,
# row-major), then λ, the quartic's coefficients, the flags, t and the RMS residual.
_SXX, _SXY, _SXZ, _SYX, _SYY, _SYZ, _SZX, _SZY, _SZZ = range(9)
_G, _SW, _PX, _PY, _PZ, _QX, _QY, _QZ, _RECENTRE = range(9, 18)
_N_C = 18
_LAM, _P2, _P1, _P0, _COLLINEAR, _COINCIDENT, _FINITE, _WEAK, _TX, _TY, _TZ, _RMS = range(9, 21)
_N_OUT = 21
BLOCK = 64  # problems per block


@numba.njit(**_JIT)
def rotations_block(st: np.ndarray, nb: int, out: np.ndarray) -> None:
    """Rotation maximising ``tr(R S)``, ``t`` and the RMS residual of the ``nb`` problems in
    ``st`` (rows ``_SXX`` … ``_QZ``), into ``out`` (rows 0–8: R row-major, ``_TX`` … ``_RMS``,
    ``_COLLINEAR``, ``_COINCIDENT``, ``_FINITE``, ``_WEAK``).

    Horn's quaternion, Theobald's QCP (Newton on the characteristic quartic of N(S) from
    ``min(√3 ‖S‖, G/2)``, all problems of the block until every one has converged), the
    eigenvector as the largest column of adj(N − λI) (``_WEAK`` when it is too small to be
    trusted), ``rank(S) <= 1`` flagged ``_COLLINEAR``.  Branch-free loops over the problems, so
    that they vectorise.
    """
    for k in range(nb):
        sxx, sxy, sxz = st[_SXX, k], st[_SXY, k], st[_SXZ, k]
        syx, syy, syz = st[_SYX, k], st[_SYY, k], st[_SYZ, k]
        szx, szy, szz = st[_SZX, k], st[_SZY, k], st[_SZZ, k]
        f2 = (sxx * sxx + sxy * sxy + sxz * sxz + syx * syx + syy * syy + syz * syz
              + szx * szx + szy * szy + szz * szz)
        a00 = syy * szz - syz * szy
        a01 = syz * szx - syx * szz
        a02 = syx * szy - syy * szx
        detS = sxx * a00 + sxy * a01 + sxz * a02
        a10 = sxz * szy - sxy * szz
        a11 = sxx * szz - sxz * szx
        a12 = sxy * szx - sxx * szy
        a20 = sxy * syz - sxz * syy
        a21 = sxz * syx - sxx * syz
        a22 = sxx * syy - sxy * syx
        adjS2 = (a00 * a00 + a01 * a01 + a02 * a02 + a10 * a10 + a11 * a11 + a12 * a12
                 + a20 * a20 + a21 * a21 + a22 * a22)
        out[_COLLINEAR, k] = 0.0 if math.sqrt(adjS2) > COLLINEAR_TOL * f2 else 1.0
        G = st[_G, k]
        out[_COINCIDENT, k] = 1.0 if math.sqrt(f2) <= COINCIDENT_TOL * G else 0.0  # no spread
        out[_FINITE, k] = 1.0 if math.isfinite(f2) and math.isfinite(G) else 0.0
        out[_P2, k] = -2.0 * f2
        out[_P1, k] = -8.0 * detS
        out[_P0, k] = f2 * f2 - 4.0 * adjS2
        lam = math.sqrt(3.0 * f2)
        upper = 0.5 * G * (1.0 + 1e-12)
        out[_LAM, k] = min(lam, upper) if math.isfinite(upper) else lam
    for _ in range(60):
        moving = 0
        for k in range(nb):
            lam = out[_LAM, k]
            p2 = out[_P2, k]
            p1 = out[_P1, k]
            l2 = lam * lam
            fval = (l2 + p2) * l2 + p1 * lam + out[_P0, k]
            fder = (4.0 * l2 + 2.0 * p2) * lam + p1
            step = fval / fder if fder > 0.0 else 0.0
            lam = lam - step
            out[_LAM, k] = lam
            moving += abs(step) > 1e-15 * abs(lam)
        if moving == 0:
            break
    for k in range(nb):
        sxx, sxy, sxz = st[_SXX, k], st[_SXY, k], st[_SXZ, k]
        syx, syy, syz = st[_SYX, k], st[_SYY, k], st[_SYZ, k]
        szx, szy, szz = st[_SZX, k], st[_SZY, k], st[_SZZ, k]
        lam = out[_LAM, k]
        # N(S) − λI (Horn 1987), symmetric
        m00 = sxx + syy + szz - lam
        m11 = sxx - syy - szz - lam
        m22 = syy - sxx - szz - lam
        m33 = szz - sxx - syy - lam
        n01 = syz - szy
        n02 = szx - sxz
        n03 = sxy - syx
        n12 = sxy + syx
        n13 = szx + sxz
        n23 = syz + szy
        s0 = m00 * m11 - n01 * n01
        s1 = m00 * n12 - n01 * n02
        s2 = m00 * n13 - n01 * n03
        s3 = n01 * n12 - m11 * n02
        s4 = n01 * n13 - m11 * n03
        s5 = n02 * n13 - n12 * n03
        k5 = m22 * m33 - n23 * n23
        k4 = n12 * m33 - n13 * n23
        k3 = n12 * n23 - n13 * m22
        k2 = n02 * m33 - n03 * n23
        k1 = n02 * n23 - n03 * m22
        # upper triangle of adj(N − λI) (symmetric, rank 1 = c v vᵀ): its columns are ∝ v
        b00 = m11 * k5 - n12 * k4 + n13 * k3
        b01 = -n01 * k5 + n02 * k4 - n03 * k3
        b02 = n13 * s5 - n23 * s4 + m33 * s3
        b03 = -n12 * s5 + m22 * s4 - n23 * s3
        b11 = m00 * k5 - n02 * k2 + n03 * k1
        b12 = -n03 * s5 + n23 * s2 - m33 * s1
        b13 = n02 * s5 - m22 * s2 + n23 * s1
        b22 = n03 * s4 - n13 * s2 + m33 * s0
        b23 = -n02 * s4 + n12 * s2 - n23 * s0
        b33 = n02 * s3 - n12 * s1 + m22 * s0
        e01, e02, e03 = b01 * b01, b02 * b02, b03 * b03
        e12, e13, e23 = b12 * b12, b13 * b13, b23 * b23
        best = b00 * b00 + e01 + e02 + e03
        w, x, y, z = b00, b01, b02, b03
        nj = b11 * b11 + e01 + e12 + e13
        use = nj > best
        w = b01 if use else w
        x = b11 if use else x
        y = b12 if use else y
        z = b13 if use else z
        best = nj if use else best
        nj = b22 * b22 + e02 + e12 + e23
        use = nj > best
        w = b02 if use else w
        x = b12 if use else x
        y = b22 if use else y
        z = b23 if use else z
        best = nj if use else best
        nj = b33 * b33 + e03 + e13 + e23
        use = nj > best
        w = b03 if use else w
        x = b13 if use else x
        y = b23 if use else y
        z = b33 if use else z
        best = nj if use else best
        l3 = max(lam, 1e-300)
        # an overflowed (inf or NaN) eigenvector norm is weak too: the SVD then solves the problem
        weak = not (math.sqrt(best) > 1e-10 * (l3 * l3 * l3) and best < math.inf) and math.isfinite(lam)
        out[_WEAK, k] = 1.0 if weak else 0.0
        s = 2.0 / best
        xs, ys, zs = x * s, y * s, z * s
        wx, wy, wz = w * xs, w * ys, w * zs
        xx, xy, xz = x * xs, x * ys, x * zs
        yy, yz, zz = y * ys, y * zs, z * zs
        r00, r01, r02 = 1.0 - (yy + zz), xy - wz, xz + wy
        r10, r11, r12 = xy + wz, 1.0 - (xx + zz), yz - wx
        r20, r21, r22 = xz - wy, yz + wx, 1.0 - (xx + yy)
        out[0, k], out[1, k], out[2, k] = r00, r01, r02
        out[3, k], out[4, k], out[5, k] = r10, r11, r12
        out[6, k], out[7, k], out[8, k] = r20, r21, r22
        px, py, pz = st[_PX, k], st[_PY, k], st[_PZ, k]
        out[_TX, k] = st[_QX, k] - (r00 * px + r01 * py + r02 * pz)
        out[_TY, k] = st[_QY, k] - (r10 * px + r11 * py + r12 * pz)
        out[_TZ, k] = st[_QZ, k] - (r20 * px + r21 * py + r22 * pz)
        # residual Σw|q̃ − R p̃|² = G − 2 tr(R S)
        trRS = (r00 * sxx + r01 * syx + r02 * szx + r10 * sxy + r11 * syy + r12 * szy
                + r20 * sxz + r21 * syz + r22 * szz)
        out[_RMS, k] = math.sqrt(max(st[_G, k] - 2.0 * trRS, 0.0) / st[_SW, k])


@numba.njit(**_JIT)
def _rotations_batch(S, G, R, collinear, weak):
    """:func:`rotations_block` over ``B`` problems, ``BLOCK`` at a time: ``S`` ``(B, 9)``
    row-major correlations, ``G`` ``(B,)``; writes ``R`` ``(B, 9)``, ``collinear`` and ``weak``
    ``(B,)`` (with ``Σw = 1`` and zero centroids: ``t`` and the RMS of ``out`` are not used)."""
    B = S.shape[0]
    st = np.zeros((_N_C, BLOCK))
    out = np.empty((_N_OUT, BLOCK))
    st[_SW, :] = 1.0
    for a in range(0, B, BLOCK):
        nb = min(BLOCK, B - a)
        for k in range(nb):
            for i in range(9):
                st[i, k] = S[a + k, i]
            st[_G, k] = G[a + k]
        rotations_block(st, nb, out)
        for k in range(nb):
            for i in range(9):
                R[a + k, i] = out[i, k]
            collinear[a + k] = out[_COLLINEAR, k] != 0.0
            weak[a + k] = out[_WEAK, k] != 0.0


def rotations_from_correlations(S: np.ndarray, G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotations maximising ``tr(R S)`` for a stack of centred correlations ``S = Σ w p̃ q̃ᵀ``.

    Parameters
    ----------
    S : ndarray (B, 3, 3)
        Centred correlations (``q̃ ≈ R p̃``), m².  A problem with a non-finite entry gives NaN.
    G : ndarray (B,)
        Centred second moments ``Σ w (|p̃|² + |q̃|²)``, m²: ``G/2`` bounds λ from above, so that
        Newton's method starts close to the root for good fits (ignored where not finite).

    Returns
    -------
    R : ndarray (B, 3, 3)
        Proper rotations (NaN for non-finite ``S``).  Problems whose quaternion is ill-determined
        are solved by the SVD, ``U diag(1, 1, det UVᵀ) Vᵀ`` (000 eq (37)).
    collinear : ndarray (B,) bool
        ``rank(S) <= 1`` (collinear or coincident points), or ``S`` not finite.
    """
    B = S.shape[0]
    Sf = np.ascontiguousarray(S, dtype=float).reshape(B, 9)
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(Sf @ np.ones(9))  # NaN or ±inf anywhere in the row
    anybad = bool(np.any(bad))
    if anybad:
        Sf = np.where(bad[:, None], 0.0, Sf)
    R = np.empty((B, 9))
    collinear = np.empty(B, dtype=bool)
    weak = np.empty(B, dtype=bool)
    _rotations_batch(Sf, np.ascontiguousarray(G, dtype=float), R, collinear, weak)
    R = R.reshape(B, 3, 3)
    sel = weak & ~bad
    if np.any(sel):
        R[sel] = proper_rotation_from_svd(np.swapaxes(S[sel], -1, -2))
    if anybad:
        R[bad] = np.nan
        collinear = collinear | bad
    return R, collinear
