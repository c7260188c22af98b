"""Relative pose of a target from the chaser's close-approach sensors (papers 000, 001, 004)."""

from __future__ import annotations

import lazy_loader as lazy

#: Sub-packages, imported on first use (``chaser.tof`` needs OpenCV, ``chaser.cylindrical`` filterpy).
__all__ = ["cylindrical", "rodrigues_pose", "tof"]

__getattr__, __dir__, _ = lazy.attach(__name__, submodules=__all__)
