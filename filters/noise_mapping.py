"""Map a rotation-vector covariance to the covariance of a noisy unit quaternion (unscented transform).

003 §2.3 takes the measurement covariance of its quaternion measurement ``z = q + v`` "from the
attitude-angle error by the unscented transform" (Julier–Uhlmann, the paper's ref [22]).  Here the
attitude error is a rotation vector ``e`` (rad) with covariance ``Σ`` (3×3), applied on the right
(body frame: ``z = q ⊗ exp(e/2)``) or on the left (reference frame: ``z = exp(e/2) ⊗ q``), and the
4×4 covariance of ``z`` is obtained with the scaled unscented transform.

The sigma-point weights are filterpy's (:class:`filterpy.kalman.MerweScaledSigmaPoints`) and the
sigma points are its default ones (rows of the Cholesky factor of ``(n + λ) Σ``); the
transform itself is vectorised over a batch of quaternions and covariances so that a Monte Carlo
of M filters does not call filterpy M times per step (a test checks it against
:func:`filterpy.kalman.unscented_transform` sample by sample).

For an isotropic ``Σ = σ² I`` the first-order result is ``σ²/4 Ξ(q) Ξ(q)ᵀ = σ²/4 (I − q qᵀ)``
(the linearisation of ``q ⊗ exp(e/2)`` about ``e = 0``), which the unscented transform
reproduces up to O(σ⁴).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Literal

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints
from numpy.typing import ArrayLike

from attitude.batch import (
    quaternion_left_matrices,
    quaternion_right_matrices,
    quaternions_from_rotvecs,
    xi_matrices,
)

__all__ = ["UT_ALPHA", "UT_BETA", "UT_KAPPA", "sigma_point_weights", "quat_noise_covariance",
           "rotation_noise_moments",
           "quat_noise_covariance_linear", "rotvec_covariance_from_angle_error"]

#: Unscented-transform parameters: α = 1, β = 2, κ = 0 (Julier's symmetric set with the Gaussian
#: kurtosis correction); sigma points at ±√3 σ along each principal axis.
UT_ALPHA = 1.0
UT_BETA = 2.0
UT_KAPPA = 0.0


@lru_cache(maxsize=8)
def _weights(n: int, alpha: float, beta: float, kappa: float) -> tuple[np.ndarray, np.ndarray, float]:
    pts = MerweScaledSigmaPoints(n, alpha=alpha, beta=beta, kappa=kappa)
    lam = alpha**2 * (n + kappa) - n
    return pts.Wm.copy(), pts.Wc.copy(), n + lam


def sigma_point_weights(n: int = 3, *, alpha: float = UT_ALPHA, beta: float = UT_BETA,
                        kappa: float = UT_KAPPA) -> tuple[np.ndarray, np.ndarray, float]:
    """filterpy's scaled sigma-point weights ``(Wm, Wc)`` and the spread ``n + λ``."""
    Wm, Wc, c = _weights(int(n), float(alpha), float(beta), float(kappa))
    return Wm.copy(), Wc.copy(), c


def rotvec_covariance_from_angle_error(angle_error_rad: ArrayLike) -> np.ndarray:
    """Isotropic rotation-vector covariance of an attitude-angle error ``e`` (2-norm of 3 axes).

    The paper quotes ``e`` as one number; it is read as the 2-norm of an isotropic three-axis
    error, so σ_axis = e/√3 and ``Σ = e²/3 I``.  ``(...,) → (..., 3, 3)``.
    """
    e = np.asarray(angle_error_rad, dtype=float)
    if np.any(~np.isfinite(e)) or np.any(e < 0):
        raise ValueError(f"angle_error_rad: must be finite and >= 0, got {e!r}")
    return (e**2 / 3.0)[..., None, None] * np.eye(3)


def _check(q: ArrayLike, cov: ArrayLike, side: str) -> tuple[np.ndarray, np.ndarray]:
    q = np.asarray(q, dtype=float)
    cov = np.asarray(cov, dtype=float)
    if q.ndim == 0 or q.shape[-1] != 4:
        raise ValueError(f"q: expected shape (..., 4), got {q.shape}")
    if cov.ndim < 2 or cov.shape[-2:] != (3, 3):
        raise ValueError(f"cov_rotvec: expected shape (..., 3, 3), got {cov.shape}")
    if side not in ("right", "left"):
        raise ValueError(f"side: expected 'right' or 'left', got {side!r}")
    return q, cov


def quat_noise_covariance(
    q: ArrayLike,
    cov_rotvec: ArrayLike,
    *,
    side: Literal["right", "left"] = "right",
    alpha: float = UT_ALPHA,
    beta: float = UT_BETA,
    kappa: float = UT_KAPPA,
) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of ``z = q ⊗ exp(e/2)`` (or ``exp(e/2) ⊗ q``), ``e ~ N(0, Σ)``, by the UT.

    Parameters
    ----------
    q : (..., 4) array
        Noise-free unit quaternion.
    cov_rotvec : (..., 3, 3) array
        Covariance Σ of the rotation-vector error (rad²), broadcasting against ``q``.
    side : {"right", "left"}
        Error applied in the body frame (right) or in the reference frame (left).

    Returns
    -------
    mean : (..., 4) array
        UT mean of ``z`` (not renormalised: its norm is slightly below 1).
    cov : (..., 4, 4) array
        UT covariance of ``z`` about that mean, rank 3 (null along ``q`` to first order).
    """
    q, cov = _check(q, cov_rotvec, side)
    m, C = rotation_noise_moments(cov, alpha=alpha, beta=beta, kappa=kappa)
    Lq = quaternion_left_matrices(q) if side == "right" else quaternion_right_matrices(q)
    return (Lq @ m[..., None])[..., 0], Lq @ C @ np.swapaxes(Lq, -1, -2)


def rotation_noise_moments(cov_rotvec: ArrayLike, *, alpha: float = UT_ALPHA, beta: float = UT_BETA,
                           kappa: float = UT_KAPPA) -> tuple[np.ndarray, np.ndarray]:
    """UT mean ``m`` (..., 4) and covariance ``C`` (..., 4, 4) of the noise quaternion ``exp(e/2)``.

    Since ``q ⊗ δq = L(q) δq`` is linear in ``δq`` for a fixed ``q``, the unscented transform of
    ``q ⊗ exp(e/2)`` is exactly ``(L(q) m, L(q) C L(q)ᵀ)`` (``Rm(q)`` for the left side): the
    sigma points depend on Σ only, so a filter whose Σ does not change computes them once.
    """
    cov = np.asarray(cov_rotvec, dtype=float)
    if cov.ndim < 2 or cov.shape[-2:] != (3, 3):
        raise ValueError(f"cov_rotvec: expected shape (..., 3, 3), got {cov.shape}")
    Wm, Wc, c = _weights(3, float(alpha), float(beta), float(kappa))
    L = _sqrt_psd(cov * c)
    cols = np.swapaxes(L, -1, -2)  # rows: columns of L, as filterpy's rows of the upper factor
    e = np.concatenate([np.zeros(cols.shape[:-2] + (1, 3)), cols, -cols], -2)  # (..., 7, 3)
    dq = quaternions_from_rotvecs(e)
    mean = Wm @ dq
    d = dq - mean[..., None, :]
    return mean, np.swapaxes(d, -1, -2) @ (Wc[:, None] * d)


def _sqrt_psd(A: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor (filterpy's default square root); symmetric square root if singular."""
    A = 0.5 * (A + np.swapaxes(A, -1, -2))
    try:
        return np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        lam, V = np.linalg.eigh(A)
        if np.any(lam < -1e-12 * np.maximum(1.0, np.abs(lam).max())):
            raise ValueError("cov_rotvec: not positive semi-definite") from None
        return (V * np.sqrt(np.clip(lam, 0.0, None))[..., None, :]) @ np.swapaxes(V, -1, -2)


def quat_noise_covariance_linear(q: ArrayLike, cov_rotvec: ArrayLike, *,
                                 side: Literal["right", "left"] = "right") -> np.ndarray:
    """First-order covariance ``¼ Ψ Σ Ψᵀ`` with ``Ψ = Ξ(q)`` (right) or ``Rm(q)[:, 1:]`` (left)."""
    q, cov = _check(q, cov_rotvec, side)
    Psi = xi_matrices(q) if side == "right" else quaternion_right_matrices(q)[..., :, 1:]
    return 0.25 * Psi @ cov @ np.swapaxes(Psi, -1, -2)
