"""The 003 closed loop built from parts: observers, frames, registrars, estimators, observer planning."""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader as lazy

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

# Submodules and public names are imported on first use (the planner's reconfiguration loads CasADi,
# the registrars Numba; ``import closed_loop`` pays for neither).
_SUBMODULES = ("estimators", "frames", "loop", "observers", "planning", "registrars", "registry", "scenario")
__getattr__, __dir__, _ = lazy.attach(__name__, submodules=_SUBMODULES, submod_attrs={
    "loop": ["ClosedLoop", "ClosedLoopResult", "Snapshot"],
    "observers": ["Observer", "RenderedObserver", "GeometricObserver", "OBSERVERS"],
    "frames": ["Frame", "reconstruct", "reconstruct_many"],
    "registrars": ["Registrar", "KabschRegistrar", "RobustKabschRegistrar", "MLRegistrar", "MatchedClouds",
                   "RegistrationIncrement", "REGISTRARS", "residual_rotation_covariance"],
    "estimators": ["ESTIMATORS", "initial_estimate"],
    "planning": ["ObserverPlan", "Reconfiguration", "plan_observers", "select_active"],
    "registry": ["Registry", "UnknownPartError"],
    "scenario": ["TumblingTarget", "tumbling_target"],
})
