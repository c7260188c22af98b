"""Formation planning: observation constraints, view geometry, observer selection and reconfiguration."""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader as lazy

if TYPE_CHECKING:
    from formation.constraints import ConstraintEvaluation, ObservationConstraints, evaluate
    from formation.execution import states_along_plan
    from formation.geometry import ViewGeometry, symmetric_views
    from formation.quality import crlb_score
    from formation.reconfiguration import ReconfigurationPlan, assign_slots, plan
    from formation.scenarios import SixSpacecraftScenario, six_spacecraft_scenario
    from formation.selection import SelectionTimeline, select_observers

__all__ = [
    "ObservationConstraints",
    "ConstraintEvaluation",
    "evaluate",
    "states_along_plan",
    "ViewGeometry",
    "symmetric_views",
    "crlb_score",
    "ReconfigurationPlan",
    "assign_slots",
    "plan",
    "SixSpacecraftScenario",
    "six_spacecraft_scenario",
    "SelectionTimeline",
    "select_observers",
]

# Submodules and public names are imported on first use: the reconfiguration planner loads CasADi,
# which ``import formation`` should not pay for.
_SUBMODULES = ("constraints", "execution", "geometry", "quality", "reconfiguration", "scenarios",
               "selection")
__getattr__, __dir__, _ = lazy.attach(__name__, submodules=_SUBMODULES, submod_attrs={
    "constraints": ["ObservationConstraints", "ConstraintEvaluation", "evaluate"],
    "execution": ["states_along_plan"],
    "geometry": ["ViewGeometry", "symmetric_views"],
    "quality": ["crlb_score"],
    "reconfiguration": ["ReconfigurationPlan", "assign_slots", "plan"],
    "scenarios": ["SixSpacecraftScenario", "six_spacecraft_scenario"],
    "selection": ["SelectionTimeline", "select_observers"],
})
