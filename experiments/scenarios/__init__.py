"""The scenario kinds: one sub-package per ``kind`` of config, each running and drawing its scenario."""

from __future__ import annotations

from experiments.config import KINDS, kind_module

__all__ = ["KINDS", "kind_module"]
