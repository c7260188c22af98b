"""Unscented mapping of a rotation-vector covariance to a quaternion covariance (003 §3.3.8)."""

import numpy as np
import pytest
from filterpy.kalman import MerweScaledSigmaPoints, unscented_transform
from hypothesis import given, settings
from hypothesis import strategies as st

from attitude.quaternion import quat_from_rotvec, quat_multiply
from filters.noise_mapping import (
    quat_noise_covariance,
    quat_noise_covariance_linear,
    rotvec_covariance_from_angle_error,
)
from tests.attitude.strategies import unit_quats


def _random_cov(seed, scale):
    A = np.random.default_rng(seed).normal(size=(3, 3)) * scale
    return A @ A.T + 1e-3 * scale**2 * np.eye(3)


@settings(max_examples=40, deadline=None)
@given(unit_quats(), st.integers(0, 2**32 - 1), st.sampled_from(["right", "left"]))
def test_batched_ut_equals_filterpy_unscented_transform(q, seed, side):
    cov = _random_cov(seed, 0.05)
    pts = MerweScaledSigmaPoints(3, alpha=1.0, beta=2.0, kappa=0.0)
    dq = quat_from_rotvec(pts.sigma_points(np.zeros(3), cov))
    z = quat_multiply(q, dq) if side == "right" else quat_multiply(dq, q)
    m_ref, P_ref = unscented_transform(z, pts.Wm, pts.Wc)
    m, P = quat_noise_covariance(q, cov, side=side)
    np.testing.assert_allclose(m, m_ref, atol=1e-15)
    np.testing.assert_allclose(P, P_ref, atol=1e-17)


@given(unit_quats())
def test_isotropic_ut_is_sigma2_over_4_times_projector_to_first_order(q):
    e = np.deg2rad(0.6)  # 003's 2-view attitude error
    cov = rotvec_covariance_from_angle_error(e)
    s2 = e**2 / 3
    _, P = quat_noise_covariance(q, cov)
    np.testing.assert_allclose(P, s2 / 4 * (np.eye(4) - np.outer(q, q)), atol=s2**2)
    np.testing.assert_allclose(P, quat_noise_covariance_linear(q, cov), atol=s2**2)


def test_ut_matches_sampled_covariance_of_noisy_quaternions():
    q = np.array([0.6, 0.0, 0.8, 0.0])
    cov = _random_cov(11, 0.2)  # large errors (~10°) so that the nonlinearity shows
    e = np.random.default_rng(5).multivariate_normal(np.zeros(3), cov, size=400_000)
    z = quat_multiply(q, quat_from_rotvec(e))
    m, P = quat_noise_covariance(q, cov)
    np.testing.assert_allclose(m, z.mean(0), atol=2e-3)
    np.testing.assert_allclose(P, np.cov(z.T), atol=0.03 * np.abs(P).max())


def test_bad_covariance_raises_naming_the_parameter():
    with pytest.raises(ValueError, match="cov_rotvec"):
        quat_noise_covariance([1.0, 0, 0, 0], np.eye(2))
    with pytest.raises(ValueError, match="cov_rotvec"):
        quat_noise_covariance([1.0, 0, 0, 0], -np.eye(3))
    with pytest.raises(ValueError, match="side"):
        quat_noise_covariance([1.0, 0, 0, 0], np.eye(3), side="up")
    with pytest.raises(ValueError, match="angle_error_rad"):
        rotvec_covariance_from_angle_error(-1.0)
