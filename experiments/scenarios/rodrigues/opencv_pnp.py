"""OpenCV's PnP solvers as the 001 scenario's comparison: one ``cv2.solvePnP`` call with a failure reason."""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["solve_pnp"]


def solve_pnp(flag: int, P_T: np.ndarray, uv_px: np.ndarray, K: np.ndarray,
              guess: tuple[np.ndarray, np.ndarray] | None, *,
              failed_reason: str = "opencv_failed") -> tuple[np.ndarray | None, np.ndarray | None, str]:
    """One ``cv2.solvePnP`` call (SQPnP or the iterative LM) on the visible vertices.

    Parameters
    ----------
    flag : int
        ``cv2.SOLVEPNP_SQPNP`` (global, no guess) or ``cv2.SOLVEPNP_ITERATIVE`` (needs ≥ 4 points).
    P_T : (m, 3) array
        Target points in the target frame, m.
    uv_px : (m, 2) array
        Their images, px.
    K : (3, 3) array
        Camera intrinsics.
    guess : (rvec, tvec) or None
        Extrinsic guess (``useExtrinsicGuess``) for the iterative solver.
    failed_reason : str, keyword-only
        The reason given when OpenCV returns no (finite) solution.

    Returns
    -------
    rvec, tvec : (3, 1) arrays or None
        OpenCV's rotation vector of ``R_CT`` and ``r_TC_C`` (m); ``None`` on failure.
    reason : str
        ``""``, ``"too_few_points"``, ``"opencv_error"`` (OpenCV raised, e.g. SQPnP's assertion on
        targets under ≈ 0.5°) or ``failed_reason``.
    """
    if len(P_T) < (4 if flag == cv2.SOLVEPNP_ITERATIVE else 3):
        return None, None, "too_few_points"
    try:
        if guess is None:
            ok, rvec, tvec = cv2.solvePnP(P_T, uv_px, K, None, flags=flag)
        else:
            ok, rvec, tvec = cv2.solvePnP(P_T, uv_px, K, None, guess[0].copy(), guess[1].copy(), True, flags=flag)
    except cv2.error:
        return None, None, "opencv_error"
    if not ok or not (np.all(np.isfinite(rvec)) and np.all(np.isfinite(tvec))):
        return None, None, failed_reason
    return rvec, tvec, ""
