"""Evidence before use: weak registrations are refused with the reason, good ones pass."""

from __future__ import annotations

import numpy as np

from closed_loop.evidence import Evidence, check_evidence


def _pairs(n: int, rng: np.random.Generator, *, sigma_m: float = 0.01, line: bool = False):
    P = rng.uniform(-2.0, 2.0, (n, 3))
    if line:
        P = np.outer(np.linspace(-2, 2, n), [1.0, 0.5, 0.2]) + 1e-4 * rng.normal(size=(n, 3))
    Q = P + rng.normal(size=(n, 3)) * sigma_m
    C = np.broadcast_to(np.eye(3) * sigma_m ** 2 / 2, (n, 3, 3)).copy()
    return P, Q, C


def test_good_registration_passes():
    rng = np.random.default_rng(0)
    P, Q, C = _pairs(40, rng)
    assert check_evidence(P, Q, C, C, np.eye(3), np.zeros(3), np.ones(40, bool), Evidence()) == ""


def test_too_few_inliers_are_refused():
    """The quickstart's 8-match registration (16° wrong, claimed σ 2.9°) could not pass: 8 < 10."""
    rng = np.random.default_rng(1)
    P, Q, C = _pairs(8, rng)
    why = check_evidence(P, Q, C, C, np.eye(3), np.zeros(3), np.ones(8, bool), Evidence())
    assert why.startswith("evidence: 8 inlier pairs")


def test_points_on_a_line_are_refused():
    rng = np.random.default_rng(2)
    P, Q, C = _pairs(30, rng, line=True)
    why = check_evidence(P, Q, C, C, np.eye(3), np.zeros(3), np.ones(30, bool), Evidence())
    assert "condition number" in why


def test_residuals_inconsistent_with_their_covariance_are_refused():
    """A 1° wrong rotation on a 2 m cloud leaves residuals of ~3 cm against σ = 1 cm: refused."""
    rng = np.random.default_rng(3)
    P, Q, C = _pairs(40, rng)
    from scipy.spatial.transform import Rotation

    R = Rotation.from_rotvec(np.deg2rad([1.0, 0.0, 0.0])).as_matrix()
    why = check_evidence(P, Q, C, C, R, np.zeros(3), np.ones(40, bool), Evidence())
    assert "residual chi2" in why
