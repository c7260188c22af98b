"""The closed loop built from parts in plain Python: geometric observer, ML registrar, EKF."""

from __future__ import annotations

import numpy as np
import pytest

from attitude.quaternion import quat_angle_between
from closed_loop import (
    ClosedLoop,
    GeometricObserver,
    MLRegistrar,
    RegistrationIncrement,
    initial_estimate,
    reconstruct,
    tumbling_target,
)
from filters import AttitudeEKF, IncrementMeasurement
from formation.geometry import symmetric_views
from vision.camera import PinholeCamera
from vision.target import fy1_target

J = np.diag([1000.0, 800.0, 600.0])


@pytest.fixture(scope="module")
def parts():
    """The construction of docs/architecture.md: truth, three station-kept cameras, the loop."""
    truth = tumbling_target(np.arange(20) * 0.5, [1.0, 0.0, 0.0, 0.0], np.deg2rad([5.0, 5.0, 5.0]), J,
                            orbit_radius_m=7.24e6, sun_N=[1.0, -0.5, 0.6])
    cameras_r_H = symmetric_views(3, 40.0, 10.0).r_CT_H
    camera = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)
    loop = ClosedLoop(observer=GeometricObserver(camera, fy1_target()), registrar=MLRegistrar(),
                      estimator=AttitudeEKF(J_kg_m2=J))
    return truth, cameras_r_H, loop


def _run(parts, seed: int, **options):
    truth, cameras_r_H, loop = parts
    s_init, s_obs, s_reg = np.random.SeedSequence(seed).spawn(3)
    state0 = initial_estimate(loop.estimator, truth.q_NT[0], truth.omega_TN_T_rad_s[0], sigma_q=1e-4,
                              sigma_omega_rad_s=np.deg2rad(0.1), rng=np.random.default_rng(s_init))
    return loop.run(truth.t_s, truth.q_HT, truth.R_NH, truth.sun_H, truth.illumination, cameras_r_H, state0,
                    rng_observe=np.random.default_rng(s_obs), rng_register=np.random.default_rng(s_reg), **options)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_loop_from_parts_tracks_the_tumbling_target(parts, seed):
    """20 epochs at 0.5 s (2.5° steps per axis): every increment updates the filter; measured over
    seeds 0–5: median increment error ≤ 0.20°, largest 0.53°, attitude error ≤ 0.72°, final rate
    error ≤ 0.066 °/s; the bounds below leave about a factor 2."""
    truth = parts[0]
    res = _run(parts, seed)
    assert res.ok.sum() == 19 and not res.ok[0]
    assert res.failure_reason[0] == "initial epoch" and set(res.failure_reason[1:]) == {""}
    assert np.nanmedian(res.increment_error_deg) < 0.4
    assert np.nanmax(res.increment_error_deg) < 1.0
    att = np.degrees(quat_angle_between(res.q_NT_est, truth.q_NT))
    rate = np.degrees(np.linalg.norm(res.omega_TN_T_est_rad_s - truth.omega_TN_T_rad_s, axis=-1))
    assert att.max() < 1.5
    assert rate[-5:].max() < 0.15
    assert np.all(res.n_tracks > 30) and np.all(res.n_matches[1:] > 20)


def test_epochs_without_a_usable_increment_record_why(parts):
    """One observer dropped at epochs 8–10 (the set changes at 8 and 11); at epoch 14 only one is
    left (in shadow, say): not observed, and the next epoch has nothing to register against."""
    truth = parts[0]
    T = truth.t_s.size
    active = np.ones((T, 3), bool)
    active[8:11, 2] = False
    active[14, 1:] = False
    why = np.array([""] * T, dtype=object)
    why[14] = "target in Earth shadow"
    res = _run(parts, 0, active=active, inactive_reason=why)
    assert res.failure_reason[8] == "observer set changed" and res.failure_reason[11] == "observer set changed"
    assert res.ok[9] and res.ok[10]
    assert res.failure_reason[14] == "target in Earth shadow" and res.n_tracks[14] == 0
    assert not res.ok[15] and res.failure_reason[15] == "previous epoch not observed"
    assert np.all(res.failure_reason[~res.ok] != "")
    np.testing.assert_array_equal(res.active, active)
    np.testing.assert_array_equal(np.isfinite(res.increment_error_deg), res.ok)


def test_snapshot_keeps_the_first_observed_epoch_from_the_requested_one(parts):
    res = _run(parts, 0, snapshot_from=10)
    assert res.snapshot is not None and res.snapshot.epoch == 10
    assert res.snapshot.T_CW.shape == (3, 4, 4) and res.snapshot.frame.ok
    np.testing.assert_array_equal(res.snapshot.observers, [0, 1, 2])


def test_geometric_observer_single_epoch_is_the_batched_call_of_one(parts):
    truth, cameras_r_H, loop = parts
    from formation.quality import camera_poses_at_target

    T_CW = camera_poses_at_target(cameras_r_H)
    one = loop.observer.observe(T_CW, truth.q_HT[3], 2.0 * truth.sun_H[3], rng=np.random.default_rng(5))
    batch = loop.observer.observe_epochs(T_CW[None], truth.q_HT[3][None], truth.sun_H[3][None],
                                         rng=np.random.default_rng(5))[0]
    np.testing.assert_allclose(one.uv_px, batch.uv_px, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(one.feature_id, batch.feature_id)


def test_registration_of_a_failed_frame_is_a_failed_increment_without_measurement(parts):
    truth, cameras_r_H, loop = parts
    from formation.quality import camera_poses_at_target

    T_CW = camera_poses_at_target(cameras_r_H)
    good = reconstruct(loop.observer.observe(T_CW, truth.q_HT[0], truth.sun_H[0], rng=np.random.default_rng(1)))
    dark = reconstruct(loop.observer.observe(T_CW, truth.q_HT[1], truth.sun_H[1], rng=np.random.default_rng(2),
                                             sun_visible_fraction=0.0))
    assert good.ok and not dark.ok and dark.failure_reason
    inc = loop.registrar.register(good, dark, rng=np.random.default_rng(3))
    assert not inc.ok and inc.failure_reason == f"this epoch: {dark.failure_reason}"
    assert inc.measurement(truth.R_NH[0], truth.R_NH[1]) is None


def test_usable_increment_becomes_the_filter_measurement():
    inc = RegistrationIncrement(R_H=np.eye(3), cov_rotvec_H=1e-6 * np.eye(3), n_matches=50, n_inliers=48, ok=True,
                                failure_reason="")
    z = inc.measurement(np.eye(3), np.eye(3))
    assert isinstance(z, IncrementMeasurement) and z.cov_side == "left"
    np.testing.assert_allclose(np.asarray(z.dq_H).reshape(4), [1.0, 0.0, 0.0, 0.0], atol=1e-15)
    no_cov = RegistrationIncrement(np.eye(3), np.full((3, 3), np.nan), 50, 48, True, "")
    assert no_cov.measurement(np.eye(3), np.eye(3)) is None
