"""Typed measurements: validation at construction, and the filters' handling of missing epochs."""

import numpy as np
import pytest

from attitude.quaternion import quat_from_rotvec
from attitude.testing import assert_quat_equal
from filters import MEKF, AbsoluteAttitudeMeasurement, AttitudeEKF, IncrementMeasurement
from filters.noise_mapping import rotvec_covariance_from_angle_error

from .conftest import J_KG_M2

COV = rotvec_covariance_from_angle_error(np.deg2rad(0.2))
I3 = np.eye(3)


def _state(F, M=3):
    q0 = np.tile([1.0, 0, 0, 0], (M, 1))
    w0 = np.tile(np.deg2rad([5.0, 5.0, 5.0]), (M, 1))
    return F.initial_state(q0, w0, F.initial_covariance())


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"dq_H": np.ones(3)}, "dq_H"),
    ({"cov_rotvec_H": np.eye(4)}, "cov_rotvec_H"),
    ({"R_NH_prev": np.full((3, 3), np.nan)}, "R_NH_prev"),
    ({"R_NH_now": 2.0 * I3}, "R_NH_now"),
    ({"R_NH_now": np.diag([1.0, 1.0, -1.0])}, "R_NH_now"),
    ({"cov_side": "middle"}, "cov_side"),
    ({"dq_H": np.tile([1.0, 0, 0, 0], (2, 1)), "cov_rotvec_H": np.tile(COV, (3, 1, 1))}, "trial counts"),
])
def test_increment_measurement_rejects_bad_fields_naming_them(kwargs, field):
    good = {"dq_H": [1.0, 0, 0, 0], "cov_rotvec_H": COV, "R_NH_prev": I3, "R_NH_now": I3}
    with pytest.raises(ValueError, match=field):
        IncrementMeasurement(**{**good, **kwargs})


def test_absolute_measurement_rejects_bad_shapes_and_accepts_nan_rows():
    with pytest.raises(ValueError, match="q_NT"):
        AbsoluteAttitudeMeasurement(np.ones((2, 3)), COV)
    with pytest.raises(ValueError, match="cov_rotvec_T"):
        AbsoluteAttitudeMeasurement([1.0, 0, 0, 0], np.ones(3))
    z = AbsoluteAttitudeMeasurement([[1.0, 0, 0, 0], [np.nan] * 4], [[1.0, 0, 0], [0, 1, 0], [0, 0, 1]])
    assert z.q_NT.dtype == float and z.q_NT.shape == (2, 4) and z.cov_rotvec_T.shape == (3, 3)


@pytest.mark.parametrize("Filter", [AttitudeEKF, MEKF])
def test_no_increment_only_reclones_and_equals_an_all_missing_increment(Filter):
    F = Filter(J_kg_m2=J_KG_M2)
    st = F.predict(F.clone(_state(F)), 0.1)
    out = F.update_increment(st, None)
    missing = F.update_increment(st, IncrementMeasurement(np.full((3, 4), np.nan), COV, I3, I3))
    np.testing.assert_array_equal(out.q_NT, missing.q_NT)
    np.testing.assert_array_equal(out.P, missing.P)
    recloned = F.clone(st)
    assert_quat_equal(out.q_NT, st.q_NT, atol=1e-15)
    assert_quat_equal(out.q_NT_clone, out.q_NT, atol=0.0)
    np.testing.assert_allclose(out.P, recloned.P, rtol=0, atol=1e-18)
    assert out.t_clone_s == st.t_s
    np.testing.assert_array_equal(out.n_accepted, 0)
    assert np.isnan(out.last_nis).all() and out.ok.all()


@pytest.mark.parametrize("Filter", [AttitudeEKF, MEKF])
def test_one_shared_absolute_row_equals_the_same_row_per_trial(Filter):
    F = Filter(J_kg_m2=J_KG_M2)
    st = F.predict(_state(F), 0.1)
    z = quat_from_rotvec(np.deg2rad([0.3, -0.2, 0.1]) + np.deg2rad(0.5))
    shared = F.update_absolute(st, AbsoluteAttitudeMeasurement(z, COV))
    rows = F.update_absolute(st, AbsoluteAttitudeMeasurement(np.tile(z, (3, 1)), np.tile(COV, (3, 1, 1))))
    np.testing.assert_array_equal(shared.q_NT, rows.q_NT)
    np.testing.assert_array_equal(shared.P, rows.P)
    np.testing.assert_array_equal(shared.n_accepted, 1)


@pytest.mark.parametrize("Filter", [AttitudeEKF, MEKF])
def test_updates_refuse_raw_arrays_naming_the_measurement(Filter):
    F = Filter(J_kg_m2=J_KG_M2)
    st = _state(F)
    with pytest.raises(ValueError, match="z: expected an AbsoluteAttitudeMeasurement"):
        F.update_absolute(st, st.q_NT)
    with pytest.raises(ValueError, match="z: expected an IncrementMeasurement"):
        F.update_increment(F.clone(st), AbsoluteAttitudeMeasurement(st.q_NT, COV))


# ---------------------------------------------------------------- bad rows (issue 17)
NAN4 = [np.nan] * 4
BAD_ROWS = {  # (quaternion row, covariance row) of trial 1; trials 0 and 2 are good
    "inf quaternion": ([np.inf, 0, 0, 0], COV),
    "partly NaN quaternion": ([1.0, np.nan, 0, 0], COV),
    "zero quaternion": ([0.0, 0, 0, 0], COV),
    "NaN covariance": ([1.0, 0, 0, 0], np.full((3, 3), np.nan)),
    "inf covariance": ([1.0, 0, 0, 0], np.diag([np.inf, 1e-6, 1e-6])),
    "negative-definite covariance": ([1.0, 0, 0, 0], -COV),
    "indefinite covariance": ([1.0, 0, 0, 0], np.diag([1e-6, -1e-6, 1e-6])),
}


def _rows(bad_q, bad_cov):
    q = np.array([[1.0, 0, 0, 0], bad_q, [1.0, 0, 0, 0]], dtype=float)
    cov = np.stack([COV, np.asarray(bad_cov, float), COV])
    return q, cov


@pytest.mark.parametrize("case", BAD_ROWS)
def test_both_filters_reject_and_count_the_same_bad_absolute_row_and_stay_finite(case):
    counts = []
    for Filter in (AttitudeEKF, MEKF):
        F = Filter(J_kg_m2=J_KG_M2)
        st = F.predict(_state(F), 0.1)
        out = F.update_absolute(st, AbsoluteAttitudeMeasurement(*_rows(*BAD_ROWS[case])))
        assert out.ok.all() and np.isfinite(out.q_NT).all() and np.isfinite(out.P).all()
        np.testing.assert_array_equal(out.q_NT[1], st.q_NT[1])  # the bad row changed nothing
        assert np.isnan(out.last_nis[1]) and out.n_consecutive_rejected[1] == 0
        counts.append((out.n_accepted.tolist(), out.n_rejected.tolist()))
    assert counts[0] == counts[1] == ([1, 0, 1], [0, 1, 0])


@pytest.mark.parametrize("case", BAD_ROWS)
def test_both_filters_reject_and_count_the_same_bad_increment_row_and_stay_finite(case):
    counts = []
    for Filter in (AttitudeEKF, MEKF):
        F = Filter(J_kg_m2=J_KG_M2)
        st = F.predict(F.clone(_state(F)), 0.1)
        dq = quat_from_rotvec(st.omega_TN_T[0] * 0.1)
        q, cov = _rows(*BAD_ROWS[case])
        q[[0, 2]] = dq
        out = F.update_increment(st, IncrementMeasurement(q, cov, I3, I3))
        assert out.ok.all() and np.isfinite(out.q_NT).all() and np.isfinite(out.P).all()
        counts.append((out.n_accepted.tolist(), out.n_rejected.tolist()))
    assert counts[0] == counts[1] == ([1, 0, 1], [0, 1, 0])


@pytest.mark.parametrize("Filter", [AttitudeEKF, MEKF])
def test_an_all_nan_row_stays_missing_whatever_its_covariance(Filter):
    F = Filter(J_kg_m2=J_KG_M2)
    st = F.predict(_state(F), 0.1)
    q, cov = _rows(NAN4, np.full((3, 3), np.nan))
    out = F.update_absolute(st, AbsoluteAttitudeMeasurement(q, cov))
    assert out.n_accepted.tolist() == [1, 0, 1] and out.n_rejected.tolist() == [0, 0, 0]


@pytest.mark.parametrize("Filter", [AttitudeEKF, MEKF])
def test_bad_rows_do_not_reset_the_covariance_however_many(Filter):
    F = Filter(J_kg_m2=J_KG_M2, reset_after_rejections=2)
    st = F.predict(_state(F), 0.1)
    for _ in range(3):
        st = F.update_absolute(st, AbsoluteAttitudeMeasurement(*_rows([np.inf, 0, 0, 0], COV)))
    assert st.n_rejected[1] == 3 and st.n_resets[1] == 0
