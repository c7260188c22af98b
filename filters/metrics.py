"""Error metrics of attitude/spin estimates: 003 eq (36)–(37), rotation angle, convergence, NEES, SPEED.

All functions are vectorised over leading axes (trials, time); angles are in radians inside and
the degree-valued thresholds of :class:`ConvergenceCriterion` say so in their names.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike
from scipy.stats import chi2

from attitude.euler import euler_from_matrix
from attitude.quaternion import matrix_from_quat, quat_angle_between

__all__ = [
    "attitude_error_angle",
    "euler_angle_error",
    "rate_error",
    "ConvergenceCriterion",
    "convergence_time",
    "nees",
    "nees_band",
    "speed_score",
    "SPEEDPLUS_ROTATION_THRESHOLD_DEG",
    "SPEEDPLUS_TRANSLATION_THRESHOLD",
]


def _nan_rows(q: np.ndarray) -> np.ndarray:
    return ~np.all(np.isfinite(q), axis=-1)


def attitude_error_angle(q_est: ArrayLike, q_true: ArrayLike) -> np.ndarray:
    """Rotation angle (rad, in [0, π]) of ``q_est⁻¹ ⊗ q_true``; sign-invariant; NaN rows stay NaN.

    ``2 arcsin‖δq_v‖``: unlike 003 eq (36) it has no gimbal lock (flag P003-14d,
    docs/papers.md#p003-14d).
    """
    qe = np.asarray(q_est, dtype=float)
    qt = np.asarray(q_true, dtype=float)
    qe, qt = np.broadcast_arrays(qe, qt)
    bad = _nan_rows(qe) | _nan_rows(qt)
    out = quat_angle_between(np.where(bad[..., None], 1.0, qe), np.where(bad[..., None], 1.0, qt))
    return np.where(bad, np.nan, out)


def euler_angle_error(q_est: ArrayLike, q_true: ArrayLike, *, seq: Literal["321", "312"] = "321"
                      ) -> np.ndarray:
    """003 eq (36): ``e_θ = ‖θ̂ − θ‖₂`` over the three Euler angles of ``R_NT`` (rad).

    The paper does not say which angles (flag P003-14d, docs/papers.md#p003-14d); these are the
    3-2-1 (yaw, pitch, roll) angles of ``D(q) = R_NT``.  Each difference is wrapped to ``(−π, π]``.
    Near gimbal lock the individual angles are ill-defined and this error can be large while the
    rotation-angle error is small; prefer :func:`attitude_error_angle` for judging convergence.
    """
    qe = np.asarray(q_est, dtype=float)
    qt = np.asarray(q_true, dtype=float)
    qe, qt = np.broadcast_arrays(qe, qt)
    bad = _nan_rows(qe) | _nan_rows(qt)
    ae, _ = euler_from_matrix(matrix_from_quat(np.where(bad[..., None], 1.0, qe)), seq)
    at, _ = euler_from_matrix(matrix_from_quat(np.where(bad[..., None], 1.0, qt)), seq)
    d = np.angle(np.exp(1j * (ae - at)))
    return np.where(bad, np.nan, np.linalg.norm(d, axis=-1))


def rate_error(omega_est: ArrayLike, omega_true: ArrayLike) -> np.ndarray:
    """003 eq (37): ``e_ω = ‖ω̂ − ω‖₂`` (same unit as the input)."""
    we = np.asarray(omega_est, dtype=float)
    wt = np.asarray(omega_true, dtype=float)
    return np.linalg.norm(we - wt, axis=-1)


@dataclass(frozen=True)
class ConvergenceCriterion:
    """When a run counts as converged (the paper gives no threshold: flag P003-15, docs/papers.md#p003-15).

    Converged if, for the last ``hold_s`` seconds of the run, the attitude error stays below
    ``attitude_deg`` **and** the rate error below ``rate_deg_s``.  The convergence time is the
    first epoch after which both errors stay below their thresholds to the end of the run.

    Attributes
    ----------
    attitude_deg : float
        Attitude-error threshold (deg).
    rate_deg_s : float
        Rate-error threshold (deg/s).
    hold_s : float
        Length of the final window that must be inside the band (s).
    attitude_metric : {"angle", "euler321"}
        Rotation-angle error (default) or 003 eq (36) on 3-2-1 Euler angles.
    """

    attitude_deg: float = 0.5
    rate_deg_s: float = 0.05
    hold_s: float = 10.0
    attitude_metric: Literal["angle", "euler321"] = "angle"

    def __post_init__(self) -> None:
        for name in ("attitude_deg", "rate_deg_s"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
        if not np.isfinite(self.hold_s) or self.hold_s < 0:
            raise ValueError(f"hold_s: must be finite and >= 0, got {self.hold_s!r}")
        if self.attitude_metric not in ("angle", "euler321"):
            raise ValueError(f"attitude_metric: expected 'angle' or 'euler321', got {self.attitude_metric!r}")


def convergence_time(t_s: ArrayLike, attitude_error_rad: ArrayLike, rate_error_rad_s: ArrayLike, *,
                     criterion: ConvergenceCriterion = ConvergenceCriterion()
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Convergence flag and time of each run.

    Parameters
    ----------
    t_s : (T,) array
        Epochs, increasing.
    attitude_error_rad, rate_error_rad_s : (..., T) arrays
        Error histories (NaN counts as outside the band).
    criterion : ConvergenceCriterion

    Returns
    -------
    converged : (...,) bool array
    time_s : (...,) array
        Convergence time in seconds from ``t_s[0]``; NaN where not converged.
    """
    t = np.asarray(t_s, dtype=float)
    ea = np.asarray(attitude_error_rad, dtype=float)
    er = np.asarray(rate_error_rad_s, dtype=float)
    if t.ndim != 1 or ea.shape[-1] != t.size or er.shape[-1] != t.size:
        raise ValueError(f"t_s/errors: time axes disagree: {t.shape}, {ea.shape}, {er.shape}")
    if t.size and (t[-1] - t[0]) < criterion.hold_s:
        raise ValueError(f"t_s: run of {t[-1] - t[0]:.3g} s is shorter than hold_s = {criterion.hold_s}")
    inside = (ea < np.deg2rad(criterion.attitude_deg)) & (er < np.deg2rad(criterion.rate_deg_s))
    # suffix-all: inside from index k to the end
    suffix = np.flip(np.logical_and.accumulate(np.flip(inside, -1), axis=-1), -1)
    any_in = suffix.any(-1)
    first = np.argmax(suffix, axis=-1)
    t_c = np.where(any_in, t[first] - t[0], np.nan)
    converged = any_in & (t[-1] - np.where(any_in, t[first], np.inf) >= criterion.hold_s)
    return converged, np.where(converged, t_c, np.nan)


def nees(error: ArrayLike, cov: ArrayLike) -> np.ndarray:
    """Normalised estimation error squared ``eᵀ P⁻¹ e`` over leading axes; NaN rows give NaN."""
    e = np.asarray(error, dtype=float)
    P = np.asarray(cov, dtype=float)
    if P.shape[-2:] != (e.shape[-1], e.shape[-1]):
        raise ValueError(f"cov: expected (..., {e.shape[-1]}, {e.shape[-1]}), got {P.shape}")
    bad = ~np.all(np.isfinite(e), -1) | ~np.all(np.isfinite(P), (-1, -2))
    eye = np.eye(e.shape[-1])
    Pg = np.where(bad[..., None, None], eye, P)
    eg = np.where(bad[..., None], 0.0, e)
    x = np.linalg.solve(Pg, eg[..., None])[..., 0]
    return np.where(bad, np.nan, np.sum(eg * x, -1))


def nees_band(dof: int, n_runs: int, *, probability: float = 0.95) -> tuple[float, float]:
    """Two-sided ``probability`` band of the average NEES over ``n_runs`` consistent runs.

    ``n_runs · mean NEES ~ χ²(n_runs · dof)`` (Bar-Shalom, Li, Kirubarajan 2001, §5.4.2).
    """
    if dof < 1 or n_runs < 1 or not (0 < probability < 1):
        raise ValueError(f"dof/n_runs/probability: got {dof}, {n_runs}, {probability}")
    a = (1 - probability) / 2
    k = dof * n_runs
    return float(chi2.ppf(a, k) / n_runs), float(chi2.ppf(1 - a, k) / n_runs)


#: SPEED+ (Kelvins SPEC2021) zeroing thresholds: errors below the testbed's calibration accuracy.
SPEEDPLUS_ROTATION_THRESHOLD_DEG = 0.169
SPEEDPLUS_TRANSLATION_THRESHOLD = 2.173e-3


def speed_score(q_est: ArrayLike, q_true: ArrayLike, *, r_est: ArrayLike | None = None,
                r_true: ArrayLike | None = None, thresholds: bool = False) -> np.ndarray:
    """Kelvins/SPEED pose score of each estimate (lower is better).

    ``s = e_q + e_t`` with ``e_q = 2 arccos|⟨q̂, q⟩|`` (rad) and ``e_t = ‖r̂ − r‖ / ‖r‖`` (the
    SPEED score of the ESA/Stanford Kelvins pose-estimation challenge, Kisantal et al. 2020).
    Without positions only ``e_q`` is returned.  With ``thresholds=True`` each term is zeroed
    below the SPEED+ calibration thresholds (0.169°, 2.173 mm/m; Park et al. 2023).
    """
    eq = attitude_error_angle(q_est, q_true)
    if thresholds:
        eq = np.where(eq < np.deg2rad(SPEEDPLUS_ROTATION_THRESHOLD_DEG), 0.0, eq)
    if (r_est is None) != (r_true is None):
        raise ValueError("r_est/r_true: give both positions or neither")
    if r_est is None:
        return eq
    re = np.asarray(r_est, dtype=float)
    rt = np.asarray(r_true, dtype=float)
    nt = np.linalg.norm(rt, axis=-1)
    if np.any(nt == 0):
        raise ValueError("r_true: zero-length position; the SPEED translation term is undefined")
    et = np.linalg.norm(re - rt, axis=-1) / nt
    if thresholds:
        et = np.where(et < SPEEDPLUS_TRANSLATION_THRESHOLD, 0.0, et)
    return eq + et
