"""The sweep cells of ``cylindrical_004`` (``sweep.cell``): only ``envelope`` for now."""

from __future__ import annotations

from collections.abc import Callable

from experiments.scenarios.cylindrical.config import Config
from experiments.sweep import SweepCell

__all__ = ["SWEEP_CELLS", "sweep_cell"]


def _envelope(cfg: Config) -> SweepCell:
    from experiments.scenarios.cylindrical.envelope import envelope_sweep_cell

    return envelope_sweep_cell(cfg)


#: sweep cell name (``sweep.cell``) → factory ``(base config) -> SweepCell``
SWEEP_CELLS: dict[str, Callable[[Config], SweepCell]] = {"envelope": _envelope}


def sweep_cell(cfg: Config) -> SweepCell:
    """The sweep cell named by ``cfg.sweep.cell``; ``ValueError`` naming the known ones otherwise."""
    name = cfg.sweep.cell if cfg.sweep is not None else ""
    if name not in SWEEP_CELLS:
        raise ValueError(f"unknown cell {name!r}; known: {', '.join(SWEEP_CELLS)}")
    return SWEEP_CELLS[name](cfg)
