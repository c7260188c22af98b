"""The 003 closed loop built from parts: observers, frames, registrars, estimators, observer planning."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from closed_loop.estimators import ESTIMATORS, initial_estimate
    from closed_loop.frames import Frame, reconstruct, reconstruct_many
    from closed_loop.loop import ClosedLoop, ClosedLoopResult, Snapshot
    from closed_loop.observers import OBSERVERS, GeometricObserver, Observer, RenderedObserver
    from closed_loop.planning import ObserverPlan, Reconfiguration, plan_observers, select_active
    from closed_loop.registrars import (
        REGISTRARS,
        KabschRegistrar,
        MatchedClouds,
        MLRegistrar,
        Registrar,
        RegistrationIncrement,
        RobustKabschRegistrar,
        residual_rotation_covariance,
    )
    from closed_loop.registry import Registry, UnknownPartError
    from closed_loop.scenario import TumblingTarget, tumbling_target

# Public name -> submodule, imported on first use (the planner's reconfiguration loads CasADi, the
# registrars Numba; ``import closed_loop`` pays for neither).
_PUBLIC = {
    "ClosedLoop": "loop", "ClosedLoopResult": "loop", "Snapshot": "loop",
    "Observer": "observers", "RenderedObserver": "observers", "GeometricObserver": "observers",
    "OBSERVERS": "observers",
    "Frame": "frames", "reconstruct": "frames", "reconstruct_many": "frames",
    "Registrar": "registrars", "KabschRegistrar": "registrars", "RobustKabschRegistrar": "registrars",
    "MLRegistrar": "registrars", "MatchedClouds": "registrars", "RegistrationIncrement": "registrars",
    "REGISTRARS": "registrars", "residual_rotation_covariance": "registrars",
    "ESTIMATORS": "estimators", "initial_estimate": "estimators",
    "ObserverPlan": "planning", "Reconfiguration": "planning", "plan_observers": "planning",
    "select_active": "planning",
    "Registry": "registry", "UnknownPartError": "registry",
    "TumblingTarget": "scenario", "tumbling_target": "scenario",
}
_SUBMODULES = ("estimators", "frames", "loop", "observers", "planning", "registrars", "registry", "scenario")

__all__ = [
    "ClosedLoop",
    "ClosedLoopResult",
    "Snapshot",
    "Observer",
    "RenderedObserver",
    "GeometricObserver",
    "OBSERVERS",
    "Frame",
    "reconstruct",
    "reconstruct_many",
    "Registrar",
    "KabschRegistrar",
    "RobustKabschRegistrar",
    "MLRegistrar",
    "MatchedClouds",
    "RegistrationIncrement",
    "REGISTRARS",
    "residual_rotation_covariance",
    "ESTIMATORS",
    "initial_estimate",
    "ObserverPlan",
    "Reconfiguration",
    "plan_observers",
    "select_active",
    "Registry",
    "UnknownPartError",
    "TumblingTarget",
    "tumbling_target",
]


def __getattr__(name: str) -> Any:
    if name in _PUBLIC:
        value = getattr(importlib.import_module(f"closed_loop.{_PUBLIC[name]}"), name)
    elif name in _SUBMODULES:
        value = importlib.import_module(f"closed_loop.{name}")
    else:
        raise AttributeError(f"module 'closed_loop' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC) | set(_SUBMODULES))
