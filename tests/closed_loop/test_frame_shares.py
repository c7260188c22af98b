"""The frame's share of its registrations' error: subset orientation covariances against Monte Carlo."""

from __future__ import annotations

import numpy as np
import pytest

from closed_loop.frames import Frame
from reconstruction.triangulation import Triangulation


def _cloud(rng: np.random.Generator, n: int = 60) -> tuple[np.ndarray, np.ndarray]:
    """Points on a 3 m × 2 m face 0.5 m deep, with depth-elongated covariances (σ 5 mm across, 40 mm along z)."""
    X = np.column_stack([rng.uniform(-1.5, 1.5, n), rng.uniform(-1.0, 1.0, n), rng.uniform(-0.25, 0.25, n)])
    cov = np.broadcast_to(np.diag([0.005 ** 2, 0.005 ** 2, 0.04 ** 2]), (n, 3, 3)).copy()
    return X, cov


def _frame(X: np.ndarray, cov: np.ndarray) -> Frame:
    n = len(X)
    tri = Triangulation(X_W=X, cov_W=cov, valid=np.ones(n, bool), failure_code=np.zeros(n, np.int8),
                        views_used=np.ones((n, 2), bool), n_views=np.full(n, 2), rms_reprojection_px=np.zeros(n),
                        chi2=np.zeros(n), n_valid=np.asarray(n), ok=True, failure_reason="")
    return Frame(obs=None, tri=tri)


def _gls_rotation(X: np.ndarray, cov: np.ndarray, noise: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """GLS rotation of the rigid motion that best explains ``noise`` on the points ``idx`` (translation free)."""
    S = np.zeros((len(idx), 3, 3))
    x = X[idx]
    S[:, 0, 1], S[:, 0, 2], S[:, 1, 2] = -x[:, 2], x[:, 1], -x[:, 0]
    S = S - S.transpose(0, 2, 1)
    J = np.concatenate([-S, np.broadcast_to(np.eye(3), S.shape)], axis=2)
    W = np.linalg.inv(cov[idx])
    info = np.einsum("nki,nkl,nlj->ij", J, W, J)
    g = np.einsum("nki,nkl,tnl->ti", J, W, noise[:, idx])
    return np.linalg.solve(info, g.T).T[:, :3]


@pytest.mark.parametrize("case", ["nested", "overlapping"])
def test_subset_excess_covariance_matches_monte_carlo_of_the_two_subsets_gls_rotations(case):
    """Cov(e(used) − e(share)) from the information of the subsets equals its Monte Carlo estimate (4000 draws)."""
    rng = np.random.default_rng(7)
    X, cov = _cloud(rng)
    frame = _frame(X, cov)
    share = np.arange(0, 45)
    used = np.arange(5, 30) if case == "nested" else np.arange(25, 60)
    V = frame.subset_excess_covariance_H(used, share)
    L = np.linalg.cholesky(cov)
    noise = np.einsum("nij,tnj->tni", L, rng.standard_normal((4000, len(X), 3)))
    d = _gls_rotation(X, cov, noise, used) - _gls_rotation(X, cov, noise, share)
    emp = np.cov(d.T)
    # 4000 draws: relative standard error of a variance ≈ sqrt(2/4000) = 2.2 %
    np.testing.assert_allclose(np.diag(emp), np.diag(V), rtol=0.08)
    if case == "nested":
        C_u, C_s = frame.rotation_covariance_H(used), frame.rotation_covariance_H(share)
        np.testing.assert_allclose(V, C_u - C_s, rtol=1e-9, atol=1e-14)


def test_subset_excess_is_zero_for_the_share_itself_and_rotation_covariance_ignores_other_points():
    """``used == share`` leaves nothing; a far-off point outside ``points`` does not change the subset's covariance."""
    rng = np.random.default_rng(3)
    X, cov = _cloud(rng, 40)
    frame = _frame(X, cov)
    idx = np.arange(40)
    np.testing.assert_allclose(frame.subset_excess_covariance_H(idx, idx), 0.0, atol=1e-14)
    X_far = np.vstack([X, [[0.0, 0.0, 8.0]]])
    cov_far = np.concatenate([cov, cov[:1]])
    far = _frame(X_far, cov_far)
    np.testing.assert_allclose(far.rotation_covariance_H(idx), frame.rotation_covariance_H(), rtol=1e-9)
    # the off-surface point's lever arm shrinks the whole cloud's covariance: the reason for ``points``
    assert np.trace(far.rotation_covariance_H()) < 0.8 * np.trace(frame.rotation_covariance_H())
