"""Formation planning: observation constraints, view geometry, observer selection and reconfiguration."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from formation.constraints import ConstraintEvaluation, ObservationConstraints, evaluate
    from formation.execution import states_along_plan
    from formation.geometry import ViewGeometry, symmetric_views
    from formation.quality import crlb_score
    from formation.reconfiguration import ReconfigurationPlan, assign_slots, plan
    from formation.scenarios import SixSpacecraftScenario, six_spacecraft_scenario
    from formation.selection import SelectionTimeline, select_observers

# Public name -> submodule, imported on first use: the reconfiguration planner loads CasADi, which
# ``import formation`` should not pay for.
_PUBLIC = {
    "ObservationConstraints": "constraints",
    "ConstraintEvaluation": "constraints",
    "evaluate": "constraints",
    "states_along_plan": "execution",
    "ViewGeometry": "geometry",
    "symmetric_views": "geometry",
    "crlb_score": "quality",
    "ReconfigurationPlan": "reconfiguration",
    "assign_slots": "reconfiguration",
    "plan": "reconfiguration",
    "SixSpacecraftScenario": "scenarios",
    "six_spacecraft_scenario": "scenarios",
    "SelectionTimeline": "selection",
    "select_observers": "selection",
}
_SUBMODULES = ("constraints", "execution", "geometry", "quality", "reconfiguration", "scenarios",
               "selection")

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


def __getattr__(name: str) -> Any:
    if name in _PUBLIC:
        value = getattr(importlib.import_module(f"formation.{_PUBLIC[name]}"), name)
    elif name in _SUBMODULES:
        value = importlib.import_module(f"formation.{name}")
    else:
        raise AttributeError(f"module 'formation' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC) | set(_SUBMODULES))
