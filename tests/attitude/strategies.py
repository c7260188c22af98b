"""Hypothesis strategies for rotations, including rotations within 1e-6 rad of 180°."""

import numpy as np
from hypothesis import strategies as st

finite = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)


@st.composite
def unit_quats(draw):
    """Uniform-ish unit quaternions plus near-180° and near-identity ones."""
    kind = draw(st.sampled_from(["random", "near_pi", "exact_pi", "near_identity"]))
    v = np.array([draw(finite) for _ in range(3)])
    if np.linalg.norm(v) < 1e-3:
        v = np.array([0.3, -0.5, 0.8])
    axis = v / np.linalg.norm(v)
    if kind == "random":
        q = np.array([draw(finite), *v])
        if np.linalg.norm(q) < 1e-3:
            q = np.array([1.0, 0.0, 0.0, 0.0])
        q = q / np.linalg.norm(q)
    else:
        if kind == "near_pi":
            angle = np.pi - draw(st.floats(0.0, 1e-6))
        elif kind == "exact_pi":
            angle = np.pi
        else:
            angle = draw(st.floats(0.0, 1e-6))
        q = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])
    if draw(st.booleans()):
        q = -q
    return q


vectors = st.lists(st.floats(-3.0, 3.0, allow_nan=False), min_size=3, max_size=3).map(np.array)
