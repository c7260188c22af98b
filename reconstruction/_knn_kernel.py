"""Compiled (Numba) brute-force k-nearest-neighbour search of descriptors for :mod:`reconstruction.association`.

:func:`knn_l2` returns, for each query row, the ``k`` nearest reference rows in L2 with their
distances computed exactly in double precision (``Σ (a_d − b_d)²`` in a fixed order, then the
square root) and sorted by (distance, index): equal distances keep the index order.  The search is done
in two passes:

1. a float32 Gram pass ``G = A Bᵀ`` (BLAS ``sgemm`` on one thread, a block of query rows at a time)
   ranks the references of each query by ``|b|² − 2 a·b`` and keeps its ``k + MARGIN`` best
   candidates, and the next one;
2. the candidates' exact distances pick and order the ``k`` nearest.

Rounding in pass 1 only affects which candidates are looked at, never the result: every float32 dot
product of ``D`` terms is within ``D·u·|a||b|`` of the exact one (u = 2⁻²⁴, any summation order),
so a reference outside the candidates has an exact squared distance of at least the next one's
approximate value minus ``2 D u (|a|² + max |b|²)``; when the k-th exact candidate is not below
that, the query is searched again exactly over every reference.
"""

from __future__ import annotations

import numba
import numpy as np

from vision._blas import one_blas_thread

#: candidates kept beyond ``k`` in the float32 pass
MARGIN = 4
#: query rows per float32 Gram block (bounds its memory: 1024 × N × 4 bytes)
_BLOCK_ROWS = 1024
_U32 = 2.0 ** -24
_JIT = dict(cache=True, nogil=True, error_model="numpy")


@numba.njit(**_JIT)
def _exact_sq(A, i, B, j):
    """``Σ_d (A[i, d] − B[j, d])²`` in double precision, in a fixed order (four partial sums over
    ``d mod 4``, then ``(s0 + s1) + (s2 + s3)``)."""
    D = A.shape[1]
    e0 = e1 = e2 = e3 = 0.0
    d4 = D - D % 4
    for d in range(0, d4, 4):
        x0 = np.float64(A[i, d]) - np.float64(B[j, d])
        x1 = np.float64(A[i, d + 1]) - np.float64(B[j, d + 1])
        x2 = np.float64(A[i, d + 2]) - np.float64(B[j, d + 2])
        x3 = np.float64(A[i, d + 3]) - np.float64(B[j, d + 3])
        e0 += x0 * x0
        e1 += x1 * x1
        e2 += x2 * x2
        e3 += x3 * x3
    for d in range(d4, D):
        x = np.float64(A[i, d]) - np.float64(B[j, d])
        e0 += x * x
    return (e0 + e1) + (e2 + e3)


@numba.njit(**_JIT)
def _insert(vals, idx, n, v, j):
    """Insert ``(v, j)`` into the first ``n`` entries of ``vals``/``idx``, sorted by (value, index),
    keeping at most ``len(vals)`` of them; returns the new count."""
    cap = vals.shape[0]
    if n == cap and not (v < vals[n - 1] or (v == vals[n - 1] and j < idx[n - 1])):
        return n
    p = n if n < cap else cap - 1
    while p > 0 and (v < vals[p - 1] or (v == vals[p - 1] and j < idx[p - 1])):
        if p < cap:
            vals[p] = vals[p - 1]
            idx[p] = idx[p - 1]
        p -= 1
    vals[p] = v
    idx[p] = j
    return min(n + 1, cap)


@numba.njit(**_JIT)
def _knn_l2(A, B, G, row0, k, dist, nidx):
    """Rows ``row0 .. row0 + len(G)`` of the search, ``G`` their float32 Gram rows against ``B``."""
    D = A.shape[1]
    M = row0 + G.shape[0]
    N = B.shape[0]
    nb = np.empty(N)
    nb_max = 0.0
    for j in range(N):
        s = 0.0
        for d in range(D):
            s += np.float64(B[j, d]) * np.float64(B[j, d])
        nb[j] = s
        nb_max = max(nb_max, s)
    m = min(N, k + MARGIN)
    cap = min(N, m + 1)
    av = np.empty(cap)
    ai = np.empty(cap, np.int64)
    ev = np.empty(N)
    ei = np.empty(N, np.int64)
    kk = min(k, N)
    for i in range(row0, M):
        r = i - row0
        na = 0.0
        for d in range(D):
            na += np.float64(A[i, d]) * np.float64(A[i, d])
        n = 0
        for j in range(cap):
            n = _insert(av, ai, n, nb[j] - 2.0 * np.float64(G[r, j]), j)
        worst = av[cap - 1]
        for j in range(cap, N):
            v = nb[j] - 2.0 * np.float64(G[r, j])
            if v < worst:
                _insert(av, ai, cap, v, j)
                worst = av[cap - 1]
        ne = 0
        for c in range(m):
            ne = _insert(ev, ei, ne, _exact_sq(A, i, B, ai[c]), ai[c])
        if cap > m:  # references left out: is the k-th candidate surely nearer than all of them?
            tol = 4.0 * D * _U32 * (na + nb_max)
            if not ev[kk - 1] < av[m] + na - tol:
                ne = 0
                for j in range(N):
                    ne = _insert(ev, ei, ne, _exact_sq(A, i, B, j), j)
        for c in range(k):
            if c < kk:
                dist[i, c] = np.sqrt(ev[c])
                nidx[i, c] = ei[c]
            else:
                dist[i, c] = np.inf
                nidx[i, c] = -1


def knn_l2(A: np.ndarray, B: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` nearest rows of ``B (N, D)`` for each row of ``A (M, D)`` (float32 descriptors), L2.

    Returns ``dist (M, k)`` float64 (exact to double rounding) and ``nidx (M, k)`` int, nearest
    first, equal distances in index order; past the last reference ``nidx`` is −1 and ``dist`` inf.
    """
    A = np.ascontiguousarray(A, np.float32)
    B = np.ascontiguousarray(B, np.float32)
    dist = np.empty((A.shape[0], int(k)))
    nidx = np.empty((A.shape[0], int(k)), np.int64)
    if A.shape[0] and B.shape[0] and k > 0:
        with one_blas_thread():
            for row0 in range(0, A.shape[0], _BLOCK_ROWS):
                G = A[row0:row0 + _BLOCK_ROWS] @ B.T
                _knn_l2(A, B, G, row0, int(k), dist, nidx)
    else:
        dist[:] = np.inf
        nidx[:] = -1
    return dist, nidx
