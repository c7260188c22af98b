"""Residual statistics of a rigid fit ``r = Q − R P − t``: RMS, information, Mahalanobis gate.

With per-point covariances ``C_P``, ``C_Q`` of both clouds the residual has covariance
``C_Q + R C_P Rᵀ`` (first order), the weight of the chi-square gate of RANSAC and of the
maximum-likelihood cost.
"""

from __future__ import annotations

import numpy as np

from reconstruction._geometry import check_covariances, sym3_inv

__all__ = ["check_covariance_pair", "mahalanobis2", "residual_information", "residual_rms"]


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


def check_covariance_pair(cov_P: np.ndarray | None, cov_Q: np.ndarray | None,
                          shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray] | None:
    """Checked per-point covariances of both clouds (both or neither; ``None`` for neither).

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
    return cP, cQ
