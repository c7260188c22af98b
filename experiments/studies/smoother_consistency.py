"""The smoother's consistency on synthetic relative rotations of an exactly known torque-free truth.

No images, no registration: the truth is diag(1000, 800, 600) kg m² turned 25° about (1, 2, 3)
(the body frame is not the principal frame), 5 °/s about each axis, sampled every 0.5 s; every epoch
gets a relative rotation to the previous one and every fourth a closure 40 s back (both settable), each with
isotropic Gaussian noise of ``sigma_deg`` drawn exactly as the smoother's noise model says.  With
such measurements the only way to leave the NEES band is the estimator itself (its linearisation,
its solver), which is what this study isolates (docs/closed_loop.md, "Consistency, measured").

    python -m experiments.studies.smoother_consistency --trials 10 --duration 90 --sigma-deg 0.05
    python -m experiments.studies.smoother_consistency --trials 10 --duration 90 --known-inertia
    python -m experiments.studies.smoother_consistency --trials 10 --closure-lag 4 --closure-every 2   # early closures
    python -m experiments.studies.smoother_consistency --trials 20 --duration 60 --sigma-deg 0.03 --share-deg 0.04 --closure-lag 4 --closure-every 2
    python -m experiments.studies.smoother_consistency --trials 10 --duration 30 --sigma-deg 0.01 --share-deg 0.04 --symmetric-deg 0.03
    python -m experiments.studies.smoother_consistency --drift --seed 1      # iSAM2's cost against the truth's

prints the share of epochs whose ``trials``-run average NEES (attitude, 3 dof) is inside its 95 %
band, and the NEES mean and median per 10 s; ``--drift`` prints, for one run, the graph's cost at
iSAM2's online estimate beside its cost at the truth, epoch by epoch.  ``--set name=value`` overrides
a :class:`closed_loop.smoother.SmootherSettings` field (e.g. ``--set warmup_batch_every=5``).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from contextlib import nullcontext
from dataclasses import fields, replace
from functools import partial

import numpy as np
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from attitude.quaternion import matrix_from_quat
from attitude.rigid_body import propagate_torque_free
from closed_loop.smoother import AttitudeSmoother, SmootherSettings
from closed_loop.torque_free_factor import InertiaShape, rotation_error_T

__all__ = ["J_T", "truth", "synthetic_run", "monte_carlo"]

# diag(1000, 800, 600) turned 25° about (1, 2, 3): the body frame is not the principal frame
J_T = np.array([[954.613, 67.899, -85.132], [67.899, 823.754, -0.428], [-85.132, -0.428, 621.633]])
PRIOR_J = np.diag([1.0, 0.9, 0.8])  # the configs' default inertia prior (estimator.inertia_prior_kg_m2)


def truth(duration_s: float, dt_s: float = 0.5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (s), attitudes ``R_NT`` ``(T, 3, 3)`` and body rates (rad/s) of the torque-free truth."""
    t = np.arange(0.0, duration_s + 0.5 * dt_s, dt_s)
    q, w = propagate_torque_free(np.array([1.0, 0.0, 0.0, 0.0]), np.deg2rad([5.0, 5.0, 5.0]), J_T, t)
    return t, matrix_from_quat(q), w


def synthetic_run(duration_s: float, *, estimate_inertia: bool, seed: int = 0, sigma_deg: float = 0.3,
                  closure_lag_s: float = 40.0, closure_every: int = 4, share_deg: float = 0.0,
                  symmetric_deg: float = 0.0, hold_symmetric: bool = True, wrong_at: int | None = None, settings: SmootherSettings | None = None,
                  after_update: Callable[[AttitudeSmoother, int], None] | None = None):
    """One smoother run on synthetic relative rotations (module docstring).

    Every ``closure_every``-th epoch also gets a closure ``closure_lag_s`` back.  ``share_deg > 0``
    gives every epoch a frame error ``ε_k`` (isotropic, that σ per axis) common to all its links, as
    a triangulated cloud's orientation error is: a link ``j → k`` is then
    ``Exp(r) Exp(−ε_k) R_k R_jᵀ Exp(ε_j)`` with its own ``r`` of ``sigma_deg``, and the smoother gets
    the frames' shares (:meth:`AttitudeSmoother.add_frame`) and ``r``'s covariance as the remainder.
    ``symmetric_deg > 0`` (with ``share_deg > 0``) also gives every frame an error ``h_k`` that enters
    the increment ending at ``k`` and the next one with the same sign, as a fit's weighting puts a
    frame's noise into its two increments (:mod:`closed_loop.smoother`): the increment ``k − 1 → k``
    is multiplied on the left by ``Exp(h_k + A h_{k−1})``; with ``hold_symmetric`` the smoother is
    given it as ``symmetric_N``, else as part of the independent remainder.  ``wrong_at``: at that epoch two wrong closures to epoch 0 (a 180° symmetric face and a 10°
    corruption, each claiming ``sigma_deg``) are put to the gate, and whether each was refused is
    returned.  ``after_update(smoother, k)`` is called after each epoch's update.  Returns
    ``(smoother, (t, R_NT, ω), nees (T−1, 2): attitude and rate, refused)``.
    """
    rng = np.random.default_rng(seed)
    t, R, w = truth(duration_s)
    s = replace(settings or SmootherSettings(), estimate_inertia=estimate_inertia)
    sm = AttitudeSmoother(J_prior_kg_m2=PRIOR_J if estimate_inertia else J_T, settings=s)
    sm.start(0.0, R[0], np.eye(3) * 1e-8, w[0] + rng.normal(size=3) * np.deg2rad(0.1),
             np.eye(3) * np.deg2rad(0.1) ** 2)
    sigma = np.deg2rad(sigma_deg)
    C = np.eye(3) * sigma ** 2
    S = np.eye(3) * np.deg2rad(share_deg) ** 2
    eps = rng.normal(size=(len(t), 3)) * np.deg2rad(share_deg) if share_deg > 0 else np.zeros((len(t), 3))
    Sh = np.eye(3) * np.deg2rad(symmetric_deg) ** 2
    h = rng.normal(size=(len(t), 3)) * np.deg2rad(symmetric_deg) if symmetric_deg > 0 else np.zeros((len(t), 3))
    lag = int(round(closure_lag_s / (t[1] - t[0])))
    nees, refused = [], []
    for k in range(1, len(t)):
        sm.add_epoch(t[k])
        if share_deg > 0:
            sm.add_frame(k - 1, S)  # once per epoch (later calls are ignored)
            sm.add_frame(k, S)
        for j in [k - 1] + ([k - lag] if k >= lag and k % closure_every == 0 else []):
            A = R[k] @ R[j].T
            sym = h[k] + A @ h[j] if j == k - 1 else np.zeros(3)
            meas = Rotation.from_rotvec(rng.normal(size=3) * sigma + sym).as_matrix() \
                @ Rotation.from_rotvec(-eps[k]).as_matrix() @ A @ Rotation.from_rotvec(eps[j]).as_matrix()
            V = 2 * Sh if j == k - 1 else np.zeros((3, 3))
            cov = C + V + S + A @ S @ A.T
            if sm.gate(j, k, meas, cov).accepted:
                if share_deg > 0 and hold_symmetric and j == k - 1:
                    sm.add_relative(j, k, meas, cov, remainder_N=C, symmetric_N=V)
                else:
                    sm.add_relative(j, k, meas, cov, remainder_N=C + V if share_deg > 0 else None)
        if wrong_at is not None and k == wrong_at:
            for wrong in (Rotation.from_rotvec([0.0, 0.0, np.pi]).as_matrix(),   # a symmetric face
                          Rotation.from_rotvec(np.deg2rad([10.0, 0.0, 0.0])).as_matrix()):  # bad matches
                refused.append(not sm.gate(0, k, wrong @ R[k] @ R[0].T, C).accepted)
        sm.update()
        if after_update is not None:
            after_update(sm, k)
        Re, we = sm.estimate(k)
        Ca, Cw = sm.covariance_T(k)
        e = rotation_error_T(Re[None], R[k][None])[0]
        nees.append((e @ np.linalg.solve(Ca, e), (we - w[k]) @ np.linalg.solve(Cw, we - w[k])))
    return sm, (t, R, w), np.array(nees), refused


def _nees_of_run(seed: int, *, duration_s: float, **run) -> np.ndarray:
    return synthetic_run(duration_s, seed=seed, **run)[2]


def monte_carlo(trials: int, duration_s: float, *, estimate_inertia: bool = True, sigma_deg: float = 0.3,
                settings: SmootherSettings | None = None, workers: int = 2, closure_lag_s: float = 40.0,
                closure_every: int = 4, share_deg: float = 0.0, symmetric_deg: float = 0.0,
                hold_symmetric: bool = True, progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """NEES ``(trials, T−1, 2)`` of :func:`synthetic_run` with seeds ``0 … trials−1``; ``progress(done, trials)`` after each run."""
    run = partial(_nees_of_run, duration_s=duration_s, estimate_inertia=estimate_inertia, sigma_deg=sigma_deg,
                  settings=settings or SmootherSettings(), closure_lag_s=closure_lag_s, closure_every=closure_every,
                  share_deg=share_deg, symmetric_deg=symmetric_deg, hold_symmetric=hold_symmetric)
    out = []
    with ProcessPoolExecutor(workers) if workers > 1 else nullcontext() as pool:
        for nees in (pool.map(run, range(trials)) if pool is not None else map(run, range(trials))):
            out.append(nees)
            if progress is not None:
                progress(len(out), trials)
    return np.stack(out)


def _drift(duration_s: float, seed: int, sigma_deg: float, settings: SmootherSettings, closure_lag_s: float,
           closure_every: int) -> list[str]:
    """Per epoch (every 2nd), ``k: cost at iSAM2's estimate / cost at the truth`` for one run."""
    rows: list[str] = []
    t, R, w = truth(duration_s)
    J_true = InertiaShape.from_tensor(J_T)

    def trace(sm: AttitudeSmoother, k: int) -> None:
        if k % 2 == 0:
            est = [sm.estimate(i) for i in range(k + 1)]
            at_est = sm.graph_error(np.stack([e[0] for e in est]), np.stack([e[1] for e in est]), sm.inertia())
            rows.append(f"{k}: {at_est:.3g} / {sm.graph_error(R[:k + 1], w[:k + 1], J_true):.3g}")

    synthetic_run(duration_s, estimate_inertia=True, seed=seed, sigma_deg=sigma_deg, settings=settings,
                  closure_lag_s=closure_lag_s, closure_every=closure_every, after_update=trace)
    return rows


def main(argv: Sequence[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--trials", type=int, default=10)
    p.add_argument("--duration", type=float, default=90.0, help="seconds")
    p.add_argument("--sigma-deg", type=float, default=0.3, help="σ of each relative rotation, deg")
    p.add_argument("--known-inertia", action="store_true")
    p.add_argument("--closure-lag", type=float, default=40.0, help="how far back the closures reach, s")
    p.add_argument("--closure-every", type=int, default=4, help="a closure every this many epochs")
    p.add_argument("--share-deg", type=float, default=0.0,
                   help="σ of each epoch's frame error common to its links (the smoother gets the frames' shares), deg")
    p.add_argument("--symmetric-deg", type=float, default=0.0,
                   help="with --share-deg: σ of each frame's error entering its two increments alike (the fit's), deg")
    p.add_argument("--symmetric-as-remainder", action="store_true",
                   help="give the smoother that part as each link's own, not through the frames' curr views")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--drift", action="store_true", help="one run: the graph's cost at iSAM2's estimate and at the truth")
    p.add_argument("--seed", type=int, default=1, help="the run of --drift")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="a SmootherSettings field")
    a = p.parse_args(argv)
    for name, value, ok in (("--trials", a.trials, a.trials >= 1), ("--duration", a.duration, a.duration > 0),
                            ("--sigma-deg", a.sigma_deg, a.sigma_deg > 0), ("--closure-lag", a.closure_lag, a.closure_lag > 0),
                            ("--closure-every", a.closure_every, a.closure_every >= 1), ("--workers", a.workers, a.workers >= 1)):
        if not ok:
            p.error(f"{name}: must be positive, got {value!r}")
    for name, value in (("--share-deg", a.share_deg), ("--symmetric-deg", a.symmetric_deg)):
        if not value >= 0:
            p.error(f"{name}: must be zero or positive, got {value!r}")
    if a.symmetric_deg > 0 and not a.share_deg > 0:
        p.error(f"--symmetric-deg: needs --share-deg above zero (the frames' nodes), got --share-deg {a.share_deg!r}")
    known = {f.name: f.type for f in fields(SmootherSettings)}
    over = {}
    for item in a.set:
        name, _, value = item.partition("=")
        if name not in known:
            p.error(f"--set: {name!r} is not a SmootherSettings field ({', '.join(known)})")
        try:
            over[name] = (value.lower() == "true") if known[name] in (bool, "bool") else float(value)
            if known[name] in (int, "int"):
                over[name] = int(over[name])
        except ValueError:
            p.error(f"--set: {name} needs a number, got {value!r}")
    settings = SmootherSettings(**over)
    if a.drift:
        print("epoch: cost at iSAM2's estimate / cost at the truth")
        print("  ".join(_drift(a.duration, a.seed, a.sigma_deg, settings, a.closure_lag, a.closure_every)))
        return
    nees = monte_carlo(a.trials, a.duration, estimate_inertia=not a.known_inertia, sigma_deg=a.sigma_deg,
                       settings=settings, workers=a.workers, closure_lag_s=a.closure_lag,
                       closure_every=a.closure_every, share_deg=a.share_deg, symmetric_deg=a.symmetric_deg,
                       hold_symmetric=not a.symmetric_as_remainder, progress=lambda done, total: print(f"run {done}/{total}", file=sys.stderr, flush=True))
    lo, hi = chi2.ppf([0.025, 0.975], 3 * a.trials) / a.trials
    avg = nees[:, :, 0].mean(0)
    share = f", frame shares {a.share_deg:g}°" if a.share_deg > 0 else ""
    if a.symmetric_deg > 0:
        share += (f", symmetric parts {a.symmetric_deg:g}° "
                  f"({'as remainders' if a.symmetric_as_remainder else 'in curr views'})")
    print(f"{a.trials} runs of {a.duration:g} s, σ = {a.sigma_deg:g}°{share}, inertia {'given' if a.known_inertia else 'estimated'}: "
          f"average NEES in its 95 % band [{lo:.2f}, {hi:.2f}] at {100 * np.mean((avg >= lo) & (avg <= hi)):.0f} % of epochs")
    print("from (s)  NEES attitude mean / median   rate mean")
    for i in range(0, nees.shape[1], 20):
        blk = nees[:, i:i + 20]
        print(f"{i / 2:7.0f}   {blk[..., 0].mean():6.2f} / {np.median(blk[..., 0]):5.2f}   {blk[..., 1].mean():9.2f}")


if __name__ == "__main__":
    main()
