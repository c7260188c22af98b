"""Exclusion reasons of the selection timeline when no k-subset is feasible."""

import numpy as np

from formation.constraints import ObservationConstraints, evaluate
from formation.selection import select_observers


def test_short_epochs_name_the_pairwise_conflict_or_the_count_of_individually_feasible():
    # epoch 0: three cameras on one line of sight (axis angles 0 < γ_min = 5°), each fine on its own;
    # epoch 1: two of them leave the range window, so only one passes its own constraints.
    r0 = np.array([[0.0, -40.0, 0.0], [0.0, -60.0, 0.0], [0.0, -80.0, 0.0]])
    r1 = r0 * np.array([[1.0], [5.0], [5.0]])
    r = np.stack([r0, r1])
    tl = select_observers(evaluate(ObservationConstraints(), r), r, 2)
    assert tl.short.all()
    assert tl.excluded[0][0] == "no feasible set of the wanted size (pairwise axis_angle with [1, 2])"
    assert tl.excluded[1][0] == "no feasible set of the wanted size (only 1 candidates pass their own constraints)"
    assert tl.excluded[1][1].startswith("range")


def test_a_candidate_blocked_only_by_a_conflict_between_the_others_is_told_so():
    a = np.deg2rad(10.0)
    r = np.array([[[60 * np.sin(a), -60 * np.cos(a), 0.0], [0.0, -50.0, 0.0], [0.0, -70.0, 0.0]]])
    tl = select_observers(evaluate(ObservationConstraints(), r), r, 3)
    assert tl.short[0]
    assert tl.excluded[0][0] == "no feasible set of the wanted size (pairwise conflicts among the others)"
    assert tl.excluded[0][1] == "no feasible set of the wanted size (pairwise axis_angle with [2])"
