"""Tests of orbits.hill: the Hill frame and relative states in it."""

from __future__ import annotations

import numpy as np
import pytest

from orbits.hill import hill_angular_velocity, hill_frame, hill_from_inertial, inertial_from_hill
from orbits.two_body import MU_EARTH_M3_S2, state_from_elements

A_M = 6721.2e3


def _random_chief(rng, size):
    a = rng.uniform(6.7e6, 4.2e7, size)
    e = rng.uniform(0.0, 0.7, size)
    i = rng.uniform(0.0, np.pi, size)
    return state_from_elements(a, e, i, rng.uniform(0, 2 * np.pi, size),
                               rng.uniform(0, 2 * np.pi, size), rng.uniform(0, 2 * np.pi, size))


def test_hill_frame_is_right_handed_and_radial_alongtrack_normal():
    rng = np.random.default_rng(1)
    r, v = _random_chief(rng, 50)
    R = hill_frame(r, v)
    np.testing.assert_allclose(R.swapaxes(-1, -2) @ R, np.broadcast_to(np.eye(3), R.shape), atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-14)
    np.testing.assert_allclose(R[..., 0], r / np.linalg.norm(r, axis=-1, keepdims=True), atol=1e-15)
    h = np.cross(r, v)
    np.testing.assert_allclose(R[..., 2], h / np.linalg.norm(h, axis=-1, keepdims=True), atol=1e-15)
    # Along-track axis has a positive component along the velocity.
    assert np.all(np.einsum("ni,ni->n", R[..., 1], v) > 0)


def test_hill_round_trip_is_identity():
    rng = np.random.default_rng(2)
    r_C, v_C = _random_chief(rng, 40)
    r_D = r_C + rng.normal(0, 1e3, (40, 3))
    v_D = v_C + rng.normal(0, 1.0, (40, 3))
    rho, rho_dot = hill_from_inertial(r_C, v_C, r_D, v_D)
    r2, v2 = inertial_from_hill(r_C, v_C, rho, rho_dot)
    np.testing.assert_allclose(r2, r_D, rtol=0, atol=1e-7)
    np.testing.assert_allclose(v2, v_D, rtol=0, atol=1e-10)


def test_deputy_on_same_circular_orbit_is_fixed_in_hill_frame():
    """Analytic truth: a deputy leading by angle Δθ on the chief's circular orbit sits at
    r(cos Δθ − 1, sin Δθ, 0) in H with zero velocity as seen in the rotating frame."""
    dtheta = 100.0 / A_M
    nu = np.array([0.3, 0.3 + dtheta])
    r, v = state_from_elements(A_M, 0.0, 0.7, 1.1, 0.0, nu)
    rho, rho_dot = hill_from_inertial(r[0], v[0], r[1], v[1])
    expected = A_M * np.array([np.cos(dtheta) - 1.0, np.sin(dtheta), 0.0])
    np.testing.assert_allclose(rho, expected, atol=1e-8)
    np.testing.assert_allclose(rho_dot, 0.0, atol=1e-11)


def test_hill_rate_is_mean_motion_for_circular_orbit():
    r, v = state_from_elements(A_M, 0.0, 0.5, 0.2, 0.0, 1.0)
    w = hill_angular_velocity(r, v)
    n = np.sqrt(MU_EARTH_M3_S2 / A_M**3)
    np.testing.assert_allclose(np.linalg.norm(w), n, rtol=1e-14)


def test_hill_broadcasts_deputies_over_chief_epochs():
    rng = np.random.default_rng(3)
    r_C, v_C = _random_chief(rng, 7)  # (T=7, 3)
    r_D = r_C[None] + rng.normal(0, 50, (4, 7, 3))
    v_D = v_C[None] + rng.normal(0, 0.05, (4, 7, 3))
    rho, rho_dot = hill_from_inertial(r_C, v_C, r_D, v_D)
    assert rho.shape == (4, 7, 3) and rho_dot.shape == (4, 7, 3)
    for k in range(4):
        rk, vk = hill_from_inertial(r_C, v_C, r_D[k], v_D[k])
        np.testing.assert_allclose(rho[k], rk, atol=0)
        np.testing.assert_allclose(rho_dot[k], vk, atol=0)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"r_C_N": np.ones(4)}, "r_C_N"),
        ({"v_D_N": np.ones((2, 2))}, "v_D_N"),
        ({"r_C_N": np.zeros(3)}, "r_C_N"),
        ({"v_C_N": np.array([A_M, 0.0, 0.0])}, "v_C_N"),
    ],
)
def test_hill_bad_input_names_argument(kwargs, name):
    args = {"r_C_N": np.array([A_M, 0, 0]), "v_C_N": np.array([0, 7700.0, 0]),
            "r_D_N": np.array([A_M, 100, 0]), "v_D_N": np.array([0, 7700.0, 0])}
    args.update(kwargs)
    with pytest.raises(ValueError, match=name):
        hill_from_inertial(**args)
