"""Residual statistics of a rigid fit ``r = Q − R P − t``: RMS, information, Mahalanobis gate.

With per-point covariances ``C_P``, ``C_Q`` of both clouds the residual has covariance
``C_Q + R C_P Rᵀ`` (first order), the weight of the chi-square gate of RANSAC and of the
maximum-likelihood cost.
"""

from __future__ import annotations

import numpy as np

from reconstruction._geometry import check_covariances, sym3_inv

__all__ = ["COVARIANCE_RTOL", "check_covariance_pair", "mahalanobis2", "residual_information", "residual_rms"]


def residual_rms(P: np.ndarray, Q: np.ndarray, R: np.ndarray, t: np.ndarray,
                 mask: np.ndarray) -> np.ndarray:
    """RMS Euclidean residual ``‖Q − R P − t‖`` over the rows in ``mask``, m.

    Parameters
    ----------
    P, Q : ndarray (..., N, 3)
        Matched clouds, m.
    R : ndarray (..., 3, 3)
    t : ndarray (..., 3)
        Motion, m.
    mask : ndarray (..., N) bool
        Rows to include.

    Returns
    -------
    ndarray (...,)
        RMS residual, m (NaN where ``mask`` is empty).
    """
    r = Q - (P @ np.swapaxes(R, -1, -2)) - t[..., None, :]
    e2 = np.sum(r * r, axis=-1)
    n = np.sum(mask, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sqrt(np.sum(np.where(mask, e2, 0.0), axis=-1) / n)


def residual_information(R: np.ndarray, cov_P: np.ndarray, cov_Q: np.ndarray) -> np.ndarray:
    """Information ``(C_Q + R C_P Rᵀ)⁻¹`` of the residual ``Q − R P − t``.

    Parameters
    ----------
    R : ndarray (..., 3, 3)
        Rotation taking P's frame to Q's.
    cov_P, cov_Q : ndarray (..., N, 3, 3)
        Per-point covariances of P (in P's frame) and Q, m².

    Returns
    -------
    ndarray (..., N, 3, 3)
        Inverse residual covariances, m⁻².
    """
    Rb = R[..., None, :, :]
    C = cov_Q + Rb @ cov_P @ np.swapaxes(Rb, -1, -2)
    Winv, _ = sym3_inv(C)
    return Winv


def mahalanobis2(r: np.ndarray, W: np.ndarray) -> np.ndarray:
    """Squared Mahalanobis norm ``rᵀ W r`` of residuals ``r`` (..., 3) with information ``W``
    (..., 3, 3); returns (...,)."""
    return np.einsum("...i,...ij,...j->...", r, W, r)


#: Relative tolerance of the symmetry and positive semi-definiteness tests of the covariances.
COVARIANCE_RTOL = 1e-9


def _psd_mask(C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(psd, pd)`` masks of symmetric 3×3 matrices ``C (..., 3, 3)`` (NaN matrices pass both).

    Symmetric to ``COVARIANCE_RTOL`` of the largest entry, and every principal minor at least
    ``−COVARIANCE_RTOL`` times that entry to the minor's order (Sylvester's test for positive
    semi-definiteness, with rounding allowed for); ``pd`` also asks for a positive determinant.
    """
    nan = np.isnan(C).any(axis=(-2, -1))
    C = np.where(nan[..., None, None], np.eye(3), C)
    s = np.max(np.abs(C), axis=(-2, -1))
    tol = COVARIANCE_RTOL * s
    a, b, c = C[..., 0, 0], C[..., 0, 1], C[..., 0, 2]
    d, e, f = C[..., 1, 1], C[..., 1, 2], C[..., 2, 2]
    sym_ok = np.max(np.abs(C - np.swapaxes(C, -1, -2)), axis=(-2, -1)) <= tol
    m1 = np.minimum(np.minimum(a, d), f) >= -tol
    m2 = np.minimum(np.minimum(a * d - b * b, a * f - c * c), d * f - e * e) >= -tol * s
    det = a * (d * f - e * e) - b * (b * f - c * e) + c * (b * e - c * d)
    psd = (sym_ok & m1 & m2 & (det >= -tol * s * s)) | nan
    return psd, (psd & (det > 0)) | nan


def _refuse(C: np.ndarray, bad: np.ndarray, name: str, what: str) -> None:
    idx = tuple(int(i) for i in np.argwhere(bad)[0])
    Cb = np.broadcast_to(C, bad.shape + (3, 3))[idx]
    ev = np.linalg.eigvalsh(0.5 * (Cb + Cb.T))
    raise ValueError(f"{name}: {what} at index {idx} (eigenvalues [{', '.join(f'{v:.3g}' for v in ev)}], "
                     f"asymmetry {np.max(np.abs(Cb - Cb.T)):.3g})")


def check_covariance_pair(cov_P: np.ndarray | None, cov_Q: np.ndarray | None,
                          shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray] | None:
    """Checked per-point covariances of both clouds (both or neither; ``None`` for neither).

    Each matrix must be symmetric positive semi-definite (to :data:`COVARIANCE_RTOL`), and at
    every point at least one of the two positive definite, so that the residual covariance
    ``C_Q + R C_P Rᵀ`` is invertible whatever ``R``.  A matrix with a NaN entry marks an absent
    point (ignored like a NaN point); ±inf, an asymmetric, indefinite or negative-definite
    matrix, or two singular ones at one point, raise ``ValueError`` naming the argument, the
    first offending index and its eigenvalues.

    Parameters
    ----------
    cov_P, cov_Q : array_like (..., N, 3, 3) or None
        Per-point covariances, m².
    shape : tuple of int
        Shape ``(..., N, 3)`` of the point clouds they must broadcast to.
    """
    if (cov_P is None) != (cov_Q is None):
        raise ValueError("cov_P, cov_Q: give both per-point covariances or neither")
    if cov_P is None:
        return None
    cP = check_covariances(cov_P, "cov_P", shape)
    cQ = check_covariances(cov_Q, "cov_Q", shape)
    psd_P, pd_P = _psd_mask(cP)
    psd_Q, pd_Q = _psd_mask(cQ)
    if not psd_P.all():
        _refuse(cP, ~psd_P, "cov_P", "not symmetric positive semi-definite")
    if not psd_Q.all():
        _refuse(cQ, ~psd_Q, "cov_Q", "not symmetric positive semi-definite")
    neither = ~(pd_P | pd_Q)
    if np.any(neither):
        _refuse(cP, np.broadcast_to(neither, np.broadcast_shapes(neither.shape, cP.shape[:-2])),
                "cov_P, cov_Q", "both singular (the residual covariance is not invertible); cov_P")
    return cP, cQ
