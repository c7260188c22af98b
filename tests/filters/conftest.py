"""Shared truth for the filter tests: 003 Experiment B/C (q0 = [1,0,0,0], ω0 = 5°/s per axis)."""

import numpy as np
import pytest

from attitude.rigid_body import propagate_torque_free

J_KG_M2 = np.diag([1000.0, 800.0, 600.0])
RATIOS_TRUE = np.array([0.8, 0.6])
OMEGA0_RAD_S = np.deg2rad([5.0, 5.0, 5.0])
DT_S = 0.1


def truth(n_steps: int):
    t = np.arange(n_steps + 1) * DT_S
    q, w = propagate_torque_free([1.0, 0.0, 0.0, 0.0], OMEGA0_RAD_S, J_KG_M2, t)
    return t, q, w


@pytest.fixture(scope="session")
def truth_40s():
    return truth(400)


@pytest.fixture(scope="session")
def truth_120s():
    return truth(1200)
