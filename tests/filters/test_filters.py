"""AttitudeEKF (003's additive EKF) and MEKF: API, equivalence with filterpy, robustness, failures."""

import numpy as np
import pytest

from attitude.quaternion import quat_from_rotvec, quat_multiply
from experiments.bench.bench_filters import problem, run_batched, run_filterpy
from filters import (
    MEKF,
    AbsoluteAttitudeMeasurement,
    AttitudeEKF,
    IncrementMeasurement,
    MeasurementModel,
    ProcessNoise,
    draw_initial_estimates,
    simulate_measurements,
)
from filters.noise_mapping import rotvec_covariance_from_angle_error
from filters.state import FAILURE_NOT_PD

from .conftest import J_KG_M2

FILTERS = [AttitudeEKF, MEKF]
COV_02 = rotvec_covariance_from_angle_error(np.deg2rad(0.2))


def _state(F, M=3):
    q0 = np.tile([1.0, 0, 0, 0], (M, 1))
    w0 = np.tile(np.deg2rad([5.0, 5.0, 5.0]), (M, 1))
    return F.initial_state(q0, w0, F.initial_covariance())


def test_batched_ekf_equals_a_loop_of_filterpy_extended_kalman_filters():
    """Same problem, independent implementation (filterpy EKF, RK4 predict_x, filterpy UT)."""
    _, _, _, q0, w0, meas = problem(3, 150, angle_error_deg=0.6, seed=3)
    pn = ProcessNoise()
    st = run_batched(AttitudeEKF(J_kg_m2=J_KG_M2, process_noise=pn, gate_probability=None),
                     q0, w0, meas, 150)
    x_peer = run_filterpy(q0, w0, meas, 150, pn)
    np.testing.assert_allclose(np.c_[st.q_NT, st.omega_TN_T], x_peer, atol=1e-12)


@pytest.mark.parametrize("Filter", FILTERS)
def test_missing_measurement_only_propagates(Filter):
    F = Filter(J_kg_m2=J_KG_M2)
    st = F.predict(_state(F), 0.1)
    z = np.full((3, 4), np.nan)
    z[1] = st.q_NT[1]
    out = F.update_absolute(st, AbsoluteAttitudeMeasurement(z, COV_02))
    for i in (0, 2):  # untouched, apart from the symmetrisation every update applies
        np.testing.assert_array_equal(out.q_NT[i], st.q_NT[i])
        np.testing.assert_array_equal(out.P[i], 0.5 * (st.P[i] + st.P[i].T))
    assert not np.array_equal(out.P[1], st.P[1])
    np.testing.assert_array_equal(out.n_accepted, [0, 1, 0])
    assert np.isnan(out.last_nis[[0, 2]]).all()
    same = F.update_absolute(st, None)
    np.testing.assert_array_equal(same.P, 0.5 * (st.P + np.swapaxes(st.P, 1, 2)))


@pytest.mark.parametrize("Filter", FILTERS)
def test_chi_square_gate_rejects_and_counts_a_gross_outlier(Filter):
    F = Filter(J_kg_m2=J_KG_M2, gate_probability=0.9999)
    st = _state(F)
    for _ in range(30):  # converge on perfect measurements
        st = F.update_absolute(F.predict(st, 0.1), AbsoluteAttitudeMeasurement(st.q_NT, COV_02))
    z = st.q_NT.copy()
    z[0] = quat_multiply(z[0], quat_from_rotvec([0.0, np.deg2rad(15.0), 0.0]))
    out = F.update_absolute(st, AbsoluteAttitudeMeasurement(z, COV_02))
    np.testing.assert_array_equal(out.n_rejected - st.n_rejected, [1, 0, 0])
    np.testing.assert_array_equal(out.q_NT[0], st.q_NT[0])
    assert out.last_nis[0] > F.gate_threshold
    ungated = Filter(J_kg_m2=J_KG_M2, gate_probability=None)
    assert ungated.update_absolute(st, AbsoluteAttitudeMeasurement(z, COV_02)).n_rejected.sum() == st.n_rejected.sum()


@pytest.mark.parametrize("Filter", FILTERS)
def test_lost_positive_definiteness_is_flagged_for_that_trial_only(Filter):
    F = Filter(J_kg_m2=J_KG_M2)
    st = _state(F)
    P = st.P.copy()
    k = P.shape[-1] - 1  # last rate component of either filter
    P[1, k, k] = -1.0  # corrupt one trial
    st = st.replace(P=P)
    out = F.update_absolute(F.predict(st, 0.1), AbsoluteAttitudeMeasurement(st.q_NT, COV_02))
    np.testing.assert_array_equal(out.failed, [False, True, False])
    assert out.failure_reason[1] == FAILURE_NOT_PD
    assert np.isnan(out.q_NT[1]).all() and np.isfinite(out.q_NT[[0, 2]]).all()
    later = F.update_absolute(F.predict(out, 0.1), AbsoluteAttitudeMeasurement(out.q_NT, COV_02))  # no exception afterwards
    np.testing.assert_array_equal(later.failed, [False, True, False])
    assert np.isfinite(later.P[[0, 2]]).all()


@pytest.mark.parametrize("Filter", FILTERS)
def test_increment_in_the_rotating_hill_frame_must_be_converted_to_N(Filter):
    """docs/conventions.md: with R_NH(t) the rate converges; treating H as N is wrong by several n.

    Read as N-frame increments, the H increments carry an extra −n about the orbit normal; the
    attitude then drifts by n t (3.8° in 60 s) and the body-frame rate error grows with it.
    """
    n = 0.0011  # rad/s, LEO
    from .conftest import truth

    t, q, w = truth(600)
    M = 10
    F = Filter(J_kg_m2=J_KG_M2, process_noise=ProcessNoise(1e-14, 1e-14))
    rngs = np.random.default_rng(4).spawn(M)
    q0, w0 = draw_initial_estimates(q[0], w[0], sigma_q=1e-4, sigma_omega_rad_s=np.deg2rad(0.1), rngs=rngs)
    model = MeasurementModel(kind="increment", angle_error_deg=0.02, orbit_rate_rad_s=n)
    meas = simulate_measurements(t, q, model, rngs=rngs)
    err = {}
    for mode in ("converted", "ignored"):
        st = F.clone(F.initial_state(q0, w0, F.initial_covariance(sigma_q=1e-4)))
        for k in range(1, t.size):
            st = F.predict(st, 0.1)
            Rp, Rn = (meas.R_NH[k - 1], meas.R_NH[k]) if mode == "converted" else (np.eye(3), np.eye(3))
            st = F.update_increment(st, IncrementMeasurement(meas.values[:, k], meas.cov_rotvec, Rp, Rn))
        err[mode] = np.linalg.norm(st.omega_TN_T - w[-1], axis=1)
    assert np.median(err["converted"]) < 0.2 * n
    assert np.median(err["ignored"]) > 3 * n


@pytest.mark.parametrize("Filter", FILTERS)
def test_bad_input_raises_value_error_naming_the_parameter(Filter):
    F = Filter(J_kg_m2=J_KG_M2)
    st = _state(F)
    with pytest.raises(ValueError, match="q_NT"):
        F.initial_state(np.ones(3), np.zeros(3), F.initial_covariance())
    with pytest.raises(ValueError, match="P0"):
        F.initial_state([1.0, 0, 0, 0], np.zeros(3), -F.initial_covariance())
    with pytest.raises(ValueError, match="dt_s"):
        F.predict(st, -0.1)
    with pytest.raises(ValueError, match="cov_rotvec_T"):
        F.update_absolute(st, AbsoluteAttitudeMeasurement(st.q_NT, np.eye(4)))
    with pytest.raises(ValueError, match="q_NT"):
        F.update_absolute(st, AbsoluteAttitudeMeasurement(st.q_NT[:2], COV_02))
    with pytest.raises(ValueError, match="clone"):
        F.update_increment(st, IncrementMeasurement(st.q_NT, COV_02, np.eye(3), np.eye(3)))
    with pytest.raises(ValueError, match="R_NH_now"):
        F.update_increment(F.clone(st), IncrementMeasurement(st.q_NT, COV_02, np.eye(3), 2 * np.eye(3)))
    with pytest.raises(ValueError, match="J_kg_m2"):
        Filter(J_kg_m2=np.diag([1.0, 1.0, 3.0]))  # violates the triangle inequality
    with pytest.raises(ValueError, match="gate_probability"):
        Filter(J_kg_m2=J_KG_M2, gate_probability=1.5)
    other = (MEKF if Filter is AttitudeEKF else AttitudeEKF)(J_kg_m2=J_KG_M2)
    with pytest.raises(ValueError, match="state"):
        F.predict(_state(other), 0.1)
