"""The estimate of a batch of attitude filters at one epoch (an immutable value)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

__all__ = ["FilterState", "ProcessNoise", "FAILURE_NOT_PD", "FAILURE_NON_FINITE"]

FAILURE_NOT_PD = "covariance lost positive definiteness"
FAILURE_NON_FINITE = "non-finite state or covariance"


@dataclass(frozen=True)
class ProcessNoise:
    """Continuous white-noise spectral densities of the filter's process model.

    The truth is torque-free, so these are small tuning terms: the defaults give a per-step
    ``Q_proc = 1e-10 I`` in rad units at Δt = 0.1 s (the paper gives no value).

    Attributes
    ----------
    attitude_psd_rad2_s : float
        Attitude random walk on each body axis, rad²/s.
    rate_psd_rad2_s3 : float
        Rate random walk on each body axis, rad²/s³ (unmodelled torque / J).
    inertia_ratio_psd_1_s : float
        Random walk of each inertia ratio, 1/s (inertia-ratio filter only).
    """

    attitude_psd_rad2_s: float = 1e-9
    rate_psd_rad2_s3: float = 1e-9
    inertia_ratio_psd_1_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("attitude_psd_rad2_s", "rate_psd_rad2_s3", "inertia_ratio_psd_1_s"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"{name}: must be finite and >= 0, got {v!r}")


@dataclass(frozen=True)
class FilterState:
    """Estimates, covariance and bookkeeping of ``M`` filters run side by side.

    A single filter is a batch of one.  Filters return new states; they never modify one.

    Attributes
    ----------
    t_s : float
        Epoch of the estimate, seconds from the scenario epoch.
    q_NT : (M, 4) array
        Attitude estimate (T to N), Hamilton, scalar first.  NaN rows for failed trials.
    omega_TN_T : (M, 3) array
        Body-rate estimate, rad/s, T components.  NaN rows for failed trials.
    P : (M, n, n) array
        Covariance in the filter's own coordinates (see the filter's ``state_layout``).
    inertia_ratios : (M, 2) array or None
        Estimated (J_yy/J_xx, J_zz/J_xx) for the inertia-ratio MEKF.
    q_NT_clone : (M, 4) array or None
        Attitude at the last cloned epoch (stochastic cloning for increment measurements).
    t_clone_s : float or None
        Epoch of the clone.
    n_accepted, n_rejected : (M,) int arrays
        Measurements used, and rejected: by the chi-square gate, or as bad rows (non-finite or
        partly NaN, a zero quaternion, a covariance not finite or not positive definite; see
        :mod:`filters.measurements`).  Missing (all-NaN) rows count in neither.
    n_consecutive_rejected : (M,) int array
        Gate rejections since the last accepted measurement (bad rows do not count).
    n_resets : (M,) int array
        Times the covariance was reset to ``P_reset`` after too many consecutive rejections (a
        filter whose estimate has drifted outside its own gate would otherwise reject every
        later measurement).
    P_reset : (M, n_core, n_core) array
        Covariance used for such a reset (the initial covariance by default).
    failed : (M,) bool array
        Trial whose covariance stopped being positive definite (or turned non-finite); its
        estimates are NaN from then on and it is not updated any more.  :attr:`ok` is its
        negation.
    failure_reason : (M,) str array
        Empty for healthy trials.
    last_nis : (M,) array
        Normalised innovation squared of the last update (NaN where no measurement was processed).
    """

    t_s: float
    q_NT: np.ndarray
    omega_TN_T: np.ndarray
    P: np.ndarray
    inertia_ratios: np.ndarray | None
    q_NT_clone: np.ndarray | None
    t_clone_s: float | None
    n_accepted: np.ndarray
    n_rejected: np.ndarray
    n_consecutive_rejected: np.ndarray
    n_resets: np.ndarray
    P_reset: np.ndarray
    failed: np.ndarray
    failure_reason: np.ndarray
    last_nis: np.ndarray

    @property
    def n_trials(self) -> int:
        """Number ``M`` of filters in the batch."""
        return self.q_NT.shape[0]

    @property
    def ok(self) -> np.ndarray:
        """``(M,)`` bool: trials that have not failed (``failure_reason`` is empty for them)."""
        return ~self.failed

    @property
    def has_clone(self) -> bool:
        return self.q_NT_clone is not None

    def replace(self, **changes: object) -> FilterState:
        """A copy with the given fields changed (``dataclasses.replace``)."""
        return replace(self, **changes)
