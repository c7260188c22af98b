"""The relative-rotation factor of one registration, with the frames' symmetric fit errors.

A registration of epoch ``k`` to epoch ``j`` measures ``ΔR_N ≈ R_NT(k) R_NT(j)ᵀ`` (003 eq 31–32
carried to N).  Its left N-frame error is a sum over the two frames' point noise.  The part of
frame ``k``'s noise that every registration of ``k`` sees the same way is the frame's share
(:meth:`closed_loop.frames.Frame.rotation_covariance_H`, the cloud orientation node ``B_k`` of
:class:`closed_loop.smoother.AttitudeSmoother`); it enters a registration with ``+`` on the newer
side and ``−`` on the older, so it cancels along a chain of increments.

What the share does not hold is the maximum-likelihood fit's own weighting: the fit of ``k`` to
``k − 1`` weights each point by ``(C_k + C_{k−1})⁻¹`` and the fit of ``k + 1`` to ``k`` by
``(C_{k+1} + C_k)⁻¹``, so frame ``k``'s noise enters the two increments with gains ``P_k + Δ`` and
``P_k − Δ`` about its own least-squares gain ``P_k``.  With the minus sign of the older side, the
``Δ`` part enters both increments with the *same* sign: it adds up along a chain instead of
cancelling.  Treated as independent per link it makes a chain of n increments too confident by up
to a factor 2 on that part (docs/closed_loop.md, "The fit's symmetric part").  This factor holds it
as a node per frame, ``h_k`` (a 3-vector, N frame at epoch ``k``, zero-mean prior):

    r = Log(ΔR_N · R_NT(j) R_NT(k)ᵀ) − h_k − ΔR_N h_j

``h_k`` enters the increment ending at ``k`` as it is and the next increment carried by that
increment's rotation, which is how frame ``k``'s error appears in both.
"""

from __future__ import annotations

import gtsam
import numpy as np

__all__ = ["relative_rotation_factor"]


def relative_rotation_factor(noise: gtsam.noiseModel.Base, key_j: int, key_k: int, dR_N: np.ndarray, *,
                             key_h_k: int | None = None, key_h_j: int | None = None) -> gtsam.NonlinearFactor:
    """Factor on the rotations ``X_j, X_k`` (in the form ``R_TN``) measured as ``X_jᵀ X_k = ΔR_Nᵀ``.

    Parameters
    ----------
    noise : gtsam noise model
        Of the registration's error not held by any node (left, N frame, rad²).
    key_j, key_k : int
        The older and the newer rotation (an attitude ``Y`` or a cloud orientation ``B``).
    dR_N : ndarray (3, 3)
        The measured ``R_NT(k) R_NT(j)ᵀ``.
    key_h_k, key_h_j : int, optional
        The frames' symmetric fit errors (``Vector3`` nodes, N frame at their own epochs), when held.

    Returns
    -------
    gtsam.NonlinearFactor
        A :class:`gtsam.BetweenFactorRot3` when neither node is given (the same residual), else a
        :class:`gtsam.CustomFactor` with analytic Jacobians.
    """
    dR = np.asarray(dR_N, dtype=float)
    if key_h_k is None and key_h_j is None:
        return gtsam.BetweenFactorRot3(key_j, key_k, gtsam.Rot3(dR.T), noise)
    keys = [key_j, key_k] + [key for key in (key_h_k, key_h_j) if key is not None]
    dRot = gtsam.Rot3(dR)
    eye = np.eye(3)

    def error(this: gtsam.CustomFactor, values: gtsam.Values, H: list[np.ndarray] | None) -> np.ndarray:
        Xj, Xk = values.atRot3(key_j), values.atRot3(key_k)
        phi = gtsam.Rot3.Logmap(dRot.compose(Xj.between(Xk)))
        r = phi.copy()
        if key_h_k is not None:
            r -= values.atVector(key_h_k)
        if key_h_j is not None:
            r -= dR @ values.atVector(key_h_j)
        if H is not None:
            Jr_inv = gtsam.Rot3.LogmapDerivative(phi)
            # right perturbations X ← X Exp(ξ): ∂/∂ξ_k = Jr⁻¹(φ); ∂/∂ξ_j = −Jr⁻¹(φ) · X_kᵀ X_j
            H[0] = -Jr_inv @ Xk.between(Xj).matrix()
            H[1] = Jr_inv
            i = 2
            if key_h_k is not None:
                H[i] = -eye
                i += 1
            if key_h_j is not None:
                H[i] = -dR
        return r

    return gtsam.CustomFactor(noise, keys, error)
