"""A factor-graph smoother of the target's attitude, rate and inertia shape (gtsam, iSAM2).

States: the attitude at every epoch (``Y_k = R_TN(k)``), the body rate ``ω_k`` and the inertia
shape as the tensor's five entries at trace 3 (:func:`closed_loop.torque_free_factor.tensor_from_entries`;
reported as principal axes and ratios, :class:`closed_loop.torque_free_factor.InertiaShape`).  Factors:

* a prior on the first epoch (the first frame defines the body frame, flag P003-14a,
  docs/papers.md#p003-14a) and on the inertia shape;
* torque-free dynamics between consecutive epochs (003 eq 25–27,
  :func:`closed_loop.torque_free_factor.torque_free_factor`) with a small process noise;
* per observed frame, the orientation of its cloud ``B_k`` (in the form of ``Y``) tied to the
  epoch's attitude by the frame's own cloud-orientation covariance
  (:meth:`closed_loop.frames.Frame.rotation_covariance_H`): the error that the frame's point noise
  puts into *every* registration it takes part in;
* one relative rotation per accepted registration, to the previous epoch, to a keyframe or a
  loop closure: ``R_NT(k) R_NT(j)ᵀ = R_NH(k) ΔR_H R_NH(j)ᵀ`` (003 eq 31–32 carried to N), a
  :class:`gtsam.BetweenFactorRot3` between ``B_j`` and ``B_k`` with a Huber-robust noise of the
  registration's covariance less the two frames' shares, after a χ² gate on its innovation
  against the current estimate.

The frames' shares make the graph count each frame's noise once: consecutive increments share a
frame and their errors cancel along a chain (lag-1 correlation −0.14), and a keyframe's noise
enters every closure to it.  Treating the registrations as independent instead makes the chained
estimate too pessimistic and the keyframe closures too confident.

What a share does not hold is the maximum-likelihood fit's own weighting.  The fit of ``k`` to
``k − 1`` weights each point by ``(C_k + C_{k−1})⁻¹`` and the fit of ``k + 1`` to ``k`` by
``(C_{k+1} + C_k)⁻¹``, so frame ``k``'s noise enters the two increments with gains ``P_k + Δ``
and ``P_k − Δ`` about its own least-squares gain ``P_k`` (the share's); with the older side's
minus sign the ``Δ`` part enters both increments with the *same* sign, and adds up along a chain
instead of cancelling.  Taken as independent per link (it is the fit's covariance beyond its two
subsets', ``F``) it left a run of 40 increments too confident (NEES 4.5 against the truth).  Each
frame that an increment reaches gets a second node ``U_k``, its *curr view*
(:meth:`AttitudeSmoother._hold_symmetric`): the increment into ``k`` ends at ``U_k``, the next
one starts at ``B_k``, and ``B_k → U_k`` carries ``4 H`` with ``H = F / 2`` taken from the share
(``S_k − H``), which gives the links' joint second moments with plain between factors.

:meth:`AttitudeSmoother.update` runs one iSAM2 step (online); :meth:`AttitudeSmoother.batch`
re-solves the whole graph with Levenberg–Marquardt (analysis).  Covariances are iSAM2's marginals.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np
from gtsam.symbol_shorthand import B, J, U, W, Y
from scipy.stats import chi2

from closed_loop.torque_free_factor import InertiaShape, propagate_batch, torque_free_factor

__all__ = ["AttitudeSmoother", "SmootherSettings", "GateResult"]


@dataclass(frozen=True)
class SmootherSettings:
    """Noise and solver settings of :class:`AttitudeSmoother`.

    Attributes
    ----------
    estimate_inertia : bool
        Estimate the inertia shape (5 parameters: the tensor's entries at trace 3,
        :func:`closed_loop.torque_free_factor.tensor_from_entries`) from a broad prior; else hold
        it at the given tensor.
    inertia_prior_sigma_entries : float
        σ of the prior on each of those entries when estimated (the trace is 3: the moments are
        about 1).
    process_sigma_attitude_rad : float
        Per-second σ of the attitude process noise (un-modelled torque), rad/√s.
    process_sigma_rate_rad_s : float
        Per-second σ of the rate process noise, rad/s/√s.
    warmup_process_sigma_rate_rad_s : float
        While the inertia shape is learnt (the dogleg epochs below) the rate process noise is at
        least this: one iSAM2 step per epoch lags the optimum of a young shape, and stiffer
        dynamics factors make it lag further.
    gate_probability : float
        χ²₃ quantile of the innovation gate on every relative rotation.
    huber_k : float
        Huber threshold (whitened units) of the relative-rotation factors.
    relinearize_threshold : float
        iSAM2 relinearisation threshold of the attitudes (rad) and the rates (rad/s).
    relinearize_threshold_inertia : float
        The same for the inertia entries: every dynamics factor depends on it, so
        a finer threshold relinearises the whole graph at each update.
    relinearize_skip : int
        iSAM2 checks for relinearisation every this many updates.
    dogleg_epochs : int
        With the inertia estimated, the first this many epochs are solved with Powell's dogleg,
        then Gauss–Newton takes over.
    warmup_batch_every : int
        During those epochs, every this many epochs the whole graph is re-solved by
        Levenberg–Marquardt and iSAM2 restarted there (0: never).
    batch_iterations : int
        Iteration cap of those Levenberg–Marquardt solves (and of :meth:`AttitudeSmoother.batch`).
    """

    estimate_inertia: bool = True
    inertia_prior_sigma_entries: float = 0.5
    process_sigma_attitude_rad: float = 1e-6
    process_sigma_rate_rad_s: float = 1e-8
    warmup_process_sigma_rate_rad_s: float = 1e-7
    gate_probability: float = 0.999
    huber_k: float = 3.0
    relinearize_threshold: float = 1e-5
    relinearize_threshold_inertia: float = 1e-3
    relinearize_skip: int = 10
    dogleg_epochs: int = 120
    warmup_batch_every: int = 20
    batch_iterations: int = 50


@dataclass(frozen=True)
class GateResult:
    """The verdict on one relative rotation.

    Attributes
    ----------
    accepted : bool
    chi2 : float
        Squared Mahalanobis norm of the innovation.
    threshold : float
    """

    accepted: bool
    chi2: float
    threshold: float


def _rot(R: np.ndarray) -> gtsam.Rot3:
    return gtsam.Rot3(np.asarray(R, dtype=float))


@dataclass
class AttitudeSmoother:
    """iSAM2 over the states of a tumbling target (module docstring).

    Build it with the inertia tensor used as the prior's mean (or the known tensor) and
    :meth:`start` it at the first epoch; then for each new epoch :meth:`add_epoch`, gate and add
    the registrations (:meth:`add_relative`) and :meth:`update` (one update per epoch: the gate
    uses the predicted covariance of the new epoch).
    """

    J_prior_kg_m2: np.ndarray
    settings: SmootherSettings = field(default_factory=SmootherSettings)

    def __post_init__(self) -> None:
        self._isam = gtsam.ISAM2(self._params(dogleg=self.settings.estimate_inertia))
        self._dogleg = bool(self.settings.estimate_inertia)
        self._graph = gtsam.NonlinearFactorGraph()
        self._values = gtsam.Values()
        self._all = gtsam.NonlinearFactorGraph()
        self._t: list[float] = []
        self._pending_cov: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._marginal_cache: dict[int, np.ndarray] = {}
        self._rate_cache: dict[int, np.ndarray] = {}
        self._frame_cov: dict[int, np.ndarray] = {}
        self._share_pending: dict[int, np.ndarray] = {}
        self._curr_view: dict[int, np.ndarray] = {}

    def _params(self, *, dogleg: bool) -> gtsam.ISAM2Params:
        """iSAM2 settings: per-variable relinearisation thresholds, QR, and Gauss–Newton or Powell's dogleg.

        Every change of the solution is propagated (the default wildfire threshold 1e-3 would leave
        rates 0.06 °/s stale).  The dogleg (a trust region, at the price of the graph's nonlinear
        error at every step) serves the first ``dogleg_epochs`` when the inertia shape is estimated:
        its first steps from a broad prior are far outside the linear range, where Gauss–Newton can
        diverge.
        """
        p = gtsam.ISAM2Params()
        thr = gtsam.ISAM2ThresholdMap()
        fine, coarse = self.settings.relinearize_threshold, self.settings.relinearize_threshold_inertia
        for ch, dim, th in (("y", 3, fine), ("b", 3, fine), ("u", 3, fine), ("w", 3, fine), ("j", 5, coarse)):
            thr.insert((ch, np.full(dim, th)))
        p.setRelinearizeThreshold(thr)
        p.relinearizeSkip = int(self.settings.relinearize_skip)
        p.setFactorization("QR")
        opt = gtsam.ISAM2DoglegParams() if dogleg else gtsam.ISAM2GaussNewtonParams()
        opt.setWildfireThreshold(0.0)
        p.setOptimizationParams(opt)
        return p

    # ---------------------------------------------------------------- building
    def start(self, t_s: float, R_NT0: np.ndarray, cov_attitude_T: np.ndarray, omega_TN_T0_rad_s: np.ndarray,
              cov_omega_T: np.ndarray) -> None:
        """Priors on the first epoch and the inertia shape.

        Parameters
        ----------
        t_s : float
        R_NT0 : ndarray (3, 3)
            Prior mean of the first attitude.
        cov_attitude_T : ndarray (3, 3)
            Its covariance as a body-frame rotation-vector error, rad².
        omega_TN_T0_rad_s : ndarray (3,)
        cov_omega_T : ndarray (3, 3)
            Rate covariance, (rad/s)².
        """
        s = self.settings
        R0 = np.asarray(R_NT0, dtype=float)
        # body-frame error a (R = R̂ Exp(a)) is the tangent −R̂ ε of Y = R_TN: cov_ε = R̂ cov_a R̂ᵀ
        cov_eps = R0 @ np.asarray(cov_attitude_T) @ R0.T
        shape = InertiaShape.from_tensor(self.J_prior_kg_m2)
        g, v = self._graph, self._values
        g.add(gtsam.PriorFactorRot3(Y(0), _rot(R0.T), gtsam.noiseModel.Gaussian.Covariance(cov_eps)))
        g.add(gtsam.PriorFactorVector(W(0), np.asarray(omega_TN_T0_rad_s, float),
                                      gtsam.noiseModel.Gaussian.Covariance(np.asarray(cov_omega_T, float))))
        if s.estimate_inertia:
            g.add(gtsam.PriorFactorVector(J(0), shape.entries,
                                          gtsam.noiseModel.Isotropic.Sigma(5, s.inertia_prior_sigma_entries)))
            v.insert(J(0), shape.entries)
        v.insert(Y(0), _rot(R0.T))
        v.insert(W(0), np.asarray(omega_TN_T0_rad_s, float))
        self._t = [float(t_s)]
        self.update()

    @property
    def times(self) -> list[float]:
        """Times of the epochs in the graph, s."""
        return self._t

    @property
    def n_epochs(self) -> int:
        """Epochs in the graph."""
        return len(self._t)

    def inertia(self) -> InertiaShape:
        """The current estimate of the inertia shape (the prior's tensor when it is not estimated)."""
        if not self.settings.estimate_inertia:
            return InertiaShape.from_tensor(self.J_prior_kg_m2)
        return InertiaShape.from_entries(self._isam.calculateEstimateVector(J(0)))

    def add_epoch(self, t_s: float) -> int:
        """A new epoch joined to the last by the dynamics factor, initialised by propagation; its index."""
        k = len(self._t)
        dt = float(t_s) - self._t[-1]
        if not dt > 0:
            raise ValueError(f"t_s: epochs must increase, got {t_s} after {self._t[-1]}")
        s = self.settings
        rate = max(s.process_sigma_rate_rad_s, s.warmup_process_sigma_rate_rad_s) if self._dogleg else s.process_sigma_rate_rad_s
        sig = np.concatenate([np.full(3, s.process_sigma_attitude_rad), np.full(3, rate)])
        noise = gtsam.noiseModel.Diagonal.Sigmas(sig * np.sqrt(dt))
        n_sub = max(1, int(np.ceil(dt / 0.5)))
        if s.estimate_inertia:
            f = torque_free_factor(noise, (Y(k - 1), W(k - 1), Y(k), W(k), J(0)), dt, n_substeps=n_sub)
        else:
            f = torque_free_factor(noise, (Y(k - 1), W(k - 1), Y(k), W(k)), dt, n_substeps=n_sub,
                                   J_T=np.asarray(self.J_prior_kg_m2, float))
        self._graph.add(f)
        R, w = self.estimate(k - 1)
        Rp, wp = propagate_batch(R[None], w[None], self.inertia().J_T[None], dt, n_sub)
        self._values.insert(Y(k), _rot(Rp[0].T))
        self._values.insert(W(k), wp[0])
        # predicted covariance of the new attitude for the gate before the next update: the last
        # epoch's plus its rate uncertainty carried over dt (cross terms dropped)
        cY = self._pending_cov.get(k - 1)
        if cY is None:
            cY = self._marginal_Y(k - 1)
            cW = self._rate_cache.pop(k - 1, None)
            if cW is None:
                cW = self._isam.marginalCovariance(W(k - 1))
        else:
            cY, cW = cY
        self._pending_cov = {k: (cY + dt * dt * (R @ cW @ R.T), cW)}
        self._t.append(float(t_s))
        return k

    def gate(self, j: int, k: int, dR_N: np.ndarray, cov_N: np.ndarray) -> GateResult:
        """χ² test of a relative rotation ``R_NT(k) R_NT(j)ᵀ ≈ dR_N`` against the current estimate.

        The innovation ``Log(dR_N R̂ᵀ)`` is compared with ``cov_N`` plus the estimate's
        ``Σ_k + ΔR Σ_j ΔRᵀ`` (marginals, correlation ignored: conservative for nearby epochs).
        """
        Rk, _ = self.estimate(k)
        Rj, _ = self.estimate(j)
        dR_est = Rk @ Rj.T
        nu = gtsam.Rot3.Logmap(_rot(np.asarray(dR_N) @ dR_est.T))
        S = np.asarray(cov_N) + self._marginal_Y(k) + dR_est @ self._marginal_Y(j) @ dR_est.T
        try:
            c2 = float(nu @ np.linalg.solve(S, nu))
        except np.linalg.LinAlgError:
            c2 = float("inf")
        thr = float(chi2.ppf(self.settings.gate_probability, 3))
        return GateResult(accepted=bool(np.isfinite(c2) and c2 <= thr), chi2=c2, threshold=thr)

    def _marginal_Y(self, k: int) -> np.ndarray:
        """Covariance of ``Y_k`` for the gate: predicted while the epoch awaits its first update, else the
        marginal last computed for it (at that epoch, by :meth:`covariance_T`: the filtered one, which
        only shrinks later; an old variable's marginal costs a pass over the Bayes tree)."""
        if k in self._pending_cov:
            return self._pending_cov[k][0]
        c = self._marginal_cache.get(k)
        if c is None:
            c = self._marginal_cache[k] = self._isam.marginalCovariance(Y(k))
        return c

    def add_frame(self, k: int, cov_frame_N: np.ndarray) -> None:
        """The cloud orientation ``B_k`` of epoch ``k``'s frame, with its covariance (left, N, rad²); once per epoch."""
        if k in self._frame_cov:
            return
        cov = 0.5 * (np.asarray(cov_frame_N, float) + np.asarray(cov_frame_N, float).T)
        self._frame_cov[k] = cov
        self._share_pending[k] = cov  # its factor joins at the update: the increment into k may lower it
        R, _ = self.estimate(k)
        self._values.insert(B(k), _rot(R.T))

    def add_relative(self, j: int, k: int, dR_N: np.ndarray, cov_N: np.ndarray, *, remainder_N: np.ndarray | None = None,
                     symmetric_N: np.ndarray | None = None, inflation: float = 1.0) -> None:
        """A relative-rotation factor ``R_NT(k) R_NT(j)ᵀ = dR_N`` with left N-frame covariance ``cov_N`` (rad²).

        Where the frames were added (:meth:`add_frame`) the factor joins their cloud orientations
        with ``cov_N`` less the frames' shares ``Σ_k + ΔR Σ_j ΔRᵀ`` (kept positive definite: at
        least 10 % of ``cov_N`` in every direction); otherwise it joins the attitudes with
        ``cov_N``.  ``remainder_N``, when given, is that remainder computed by the caller from the
        point subsets the registration used (:mod:`closed_loop.smoothing_loop` does; with the
        exact maximum-likelihood fit its residual against the truth has NEES 2.5–3.4,
        docs/closed_loop.md), kept at least 1 % of ``cov_N`` in every direction.  ``inflation``
        multiplies the remainder (a closure shares its keyframe's points with the keyframe's other
        closures, a correlation the graph does not hold).  ``symmetric_N``, given for a registration
        to the previous epoch, is the fit's part that enters this increment and the next with the
        same sign (module docstring; the caller leaves it out of ``remainder_N``): where both frames
        have shares it goes to frame ``k``'s curr view (:meth:`_hold_symmetric`), else into the
        remainder.  Other registrations get back the part of their frames' shares that a curr view
        took.  Call :meth:`gate` first; this adds unconditionally (Huber-robust).
        """
        dR = np.asarray(dR_N, float)
        cov = 0.5 * (np.asarray(cov_N, float) + np.asarray(cov_N, float).T)
        if remainder_N is None:
            zero = np.zeros((3, 3))
            remainder, floor = cov - self._frame_cov.get(k, zero) - dR @ self._frame_cov.get(j, zero) @ dR.T, 0.1
        else:
            remainder, floor = np.asarray(remainder_N, float), 0.01
        kj = B(j) if j in self._frame_cov else Y(j)
        kk = B(k) if k in self._frame_cov else Y(k)
        if (symmetric_N is not None and j in self._frame_cov and k in self._share_pending
                and k not in self._curr_view):
            kk, remainder = U(k), remainder + self._hold_symmetric(j, k, dR, np.asarray(symmetric_N, float))
        else:  # the nodes' shares were lowered by their curr-view parts: give them back to this link
            zero = np.zeros((3, 3))
            remainder = remainder + self._curr_view.get(k, zero) + dR @ self._curr_view.get(j, zero) @ dR.T
            if symmetric_N is not None:
                remainder = remainder + np.asarray(symmetric_N, float)
        m, V = np.linalg.eigh(cov)
        iso = np.diag(1.0 / np.sqrt(m)) @ V.T  # whitening of cov
        rm, rV = np.linalg.eigh(iso @ (0.5 * (remainder + remainder.T)) @ iso.T)
        resid = np.linalg.inv(iso) @ (rV * np.maximum(rm, floor)) @ rV.T @ np.linalg.inv(iso).T
        base = gtsam.noiseModel.Gaussian.Covariance(0.5 * float(inflation) * (resid + resid.T))
        noise = gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(self.settings.huber_k), base)
        # B_jᵀ B_k = R_NT(j) R_NT(k)ᵀ = dR_Nᵀ; its right error is the (negated) left error of dR_N
        self._graph.add(gtsam.BetweenFactorRot3(kj, kk, _rot(dR.T), noise))

    def _hold_symmetric(self, j: int, k: int, dR: np.ndarray, symmetric_N: np.ndarray) -> np.ndarray:
        """Put the symmetric part of the increment ``j = k − 1 → k`` into frame ``k``'s nodes; the change to its remainder.

        The fit's excess ``F`` over its two subsets enters this increment and the next with the same
        sign (half from each frame, ``H = F / 2``; module docstring).  Frame ``k`` gets a second
        node ``U_k`` (its *curr view*): ``Y_k → B_k`` with the share lowered to ``S_k − H`` and
        ``B_k → U_k`` with ``4 H``; this increment joins ``B_j`` to ``U_k`` and the next joins
        ``B_k`` to ``U_{k+1}``.  With ``H`` the same for neighbouring frames this gives each
        increment its variance ``S_j + S_k + F``, two consecutive increments their covariance
        ``−S_k + H`` and a run of increments ``4 H`` per inner frame: the joint second moments of
        links whose frames' errors enter them with gains ``P ± Δ``.  ``H`` is capped at half the
        share (whitened by it); the cut and, where frame ``j`` has no curr view, the ``H`` its
        lowered share does not give are settled in the remainder.
        """
        m, V = np.linalg.eigh(0.25 * (symmetric_N + symmetric_N.T))
        Hk = (V * np.maximum(m, 0.0)) @ V.T
        S = self._share_pending[k]
        sm, sV = np.linalg.eigh(S)
        root = (sV * np.sqrt(np.maximum(sm, 1e-300))) @ sV.T
        iroot = (sV / np.sqrt(np.maximum(sm, 1e-300))) @ sV.T
        hm, hV = np.linalg.eigh(iroot @ Hk @ iroot)
        held = root @ ((hV * np.clip(hm, 1e-6, 0.5)) @ hV.T) @ root
        self._share_pending[k] = S - held
        self._curr_view[k] = held
        R, _ = self.estimate(k)
        self._values.insert(U(k), _rot(R.T))
        self._graph.add(gtsam.BetweenFactorRot3(B(k), U(k), gtsam.Rot3(), gtsam.noiseModel.Gaussian.Covariance(4 * held)))
        change = 2 * (Hk - held)
        if j not in self._curr_view:
            change = change - dR @ held @ dR.T
        return change

    def update(self) -> None:
        """One iSAM2 step with the factors and variables added since the last."""
        for k, cov in self._share_pending.items():
            # B_k = Y_k Exp(ε): ε is minus the left N-frame error of the cloud's orientation
            self._graph.add(gtsam.BetweenFactorRot3(Y(k), B(k), gtsam.Rot3(), gtsam.noiseModel.Gaussian.Covariance(cov)))
        self._share_pending = {}
        self._isam.update(self._graph, self._values)
        self._all.push_back(self._graph)
        self._graph = gtsam.NonlinearFactorGraph()
        self._values = gtsam.Values()
        self._pending_cov = {}
        every = self.settings.warmup_batch_every
        if self._dogleg and every and self.n_epochs % every == 0 and self.n_epochs < self.settings.dogleg_epochs:
            # while the inertia shape is young, re-solve the whole graph to convergence and restart
            # iSAM2 there (one step per update can lag far behind the optimum in this phase)
            self._restart(self._solve_batch(), dogleg=True)
        if self._dogleg and self.n_epochs >= self.settings.dogleg_epochs:
            # hand over to Gauss-Newton: a new iSAM2 on the whole graph from the converged solution
            self._restart(self._solve_batch() if every else self._isam.calculateEstimate(), dogleg=False)
            self._dogleg = False

    def _solve_batch(self) -> gtsam.Values:
        """Levenberg–Marquardt on the whole graph from the current estimate.

        The damping is scaled by the diagonal of the information (Marquardt's form): the dynamics
        factors' whitening (σ ≈ 1e-6) puts that diagonal near 1e12, where gtsam's default
        λ·I, capped at 1e5, leaves every step a plain Gauss–Newton step; when those fail (far from
        the optimum, while the inertia is young) the default optimizer stops where it started.
        """
        params = gtsam.LevenbergMarquardtParams()
        params.setMaxIterations(self.settings.batch_iterations)
        params.setDiagonalDamping(True)
        params.setlambdaUpperBound(1e30)
        return gtsam.LevenbergMarquardtOptimizer(self._all, self._isam.calculateEstimate(), params).optimize()

    def _restart(self, values: gtsam.Values, *, dogleg: bool) -> None:
        """A new iSAM2 on the whole graph, linearised at ``values`` (the marginals cache is dropped)."""
        self._isam = gtsam.ISAM2(self._params(dogleg=dogleg))
        self._isam.update(self._all, values)
        self._marginal_cache.clear()
        self._rate_cache.clear()

    # ---------------------------------------------------------------- reading
    def estimate(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """``(R_NT (3, 3), ω_T (3,))`` at epoch ``k`` (the last update's estimate)."""
        if self._values.exists(Y(k)):
            return self._values.atRot3(Y(k)).matrix().T, self._values.atVector(W(k))
        return self._isam.calculateEstimateRot3(Y(k)).matrix().T, self._isam.calculateEstimateVector(W(k))

    def covariance_T(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Marginal covariances at epoch ``k``: body-frame attitude error (rad²) and rate (rad²/s²)."""
        R, _ = self.estimate(k)
        c_eps = self._marginal_cache[k] = self._isam.marginalCovariance(Y(k))
        c_w = self._rate_cache[k] = self._isam.marginalCovariance(W(k))
        return R.T @ c_eps @ R, c_w

    def graph_error(self, R_NT: np.ndarray, omega_T: np.ndarray, inertia: InertiaShape | None = None) -> float:
        """The graph's nonlinear cost ``½ Σ ‖r‖²`` (whitened, robust) at the given states of every epoch.

        ``R_NT`` ``(T, 3, 3)`` and ``omega_T`` ``(T, 3)`` (rad/s); ``inertia`` when it is estimated.
        The frames' cloud orientations (:meth:`add_frame`) are set to their epochs' attitudes.  With
        the truth it tells whether a solution is a minimum: no minimiser costs more than the truth.
        """
        v = gtsam.Values()
        for k in range(self.n_epochs):
            v.insert(Y(k), _rot(np.asarray(R_NT[k]).T))
            v.insert(W(k), np.asarray(omega_T[k], float))
            if k in self._frame_cov:
                v.insert(B(k), _rot(np.asarray(R_NT[k]).T))
            if k in self._curr_view:
                v.insert(U(k), _rot(np.asarray(R_NT[k]).T))
        if self.settings.estimate_inertia:
            if inertia is None:
                raise ValueError("inertia: required when the inertia shape is estimated")
            v.insert(J(0), inertia.entries)
        return float(self._all.error(v))

    def batch(self) -> tuple[np.ndarray, np.ndarray, InertiaShape]:
        """Levenberg–Marquardt on the whole graph from the iSAM2 estimate (the smoothed solution).

        Returns
        -------
        R_NT : ndarray (T, 3, 3)
        omega_T : ndarray (T, 3)
        inertia : InertiaShape
        """
        res = self._solve_batch()
        T = self.n_epochs
        R = np.stack([res.atRot3(Y(k)).matrix().T for k in range(T)])
        w = np.stack([res.atVector(W(k)) for k in range(T)])
        if not self.settings.estimate_inertia:
            return R, w, self.inertia()
        return R, w, InertiaShape.from_entries(res.atVector(J(0)))
