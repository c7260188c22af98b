"""Relative pose of a target from the chaser's close-approach sensors (papers 000, 001, 004)."""

from __future__ import annotations

import importlib
from types import ModuleType

#: Sub-packages, imported on first use (``chaser.tof`` needs OpenCV, ``chaser.cylindrical`` filterpy).
__all__ = ["cylindrical", "rodrigues_pose", "tof"]


def __getattr__(name: str) -> ModuleType:
    """Import the sub-package ``name`` on first access."""
    if name in __all__:
        return importlib.import_module(f"chaser.{name}")
    raise AttributeError(f"module 'chaser' has no attribute {name!r}")
