"""The random streams of a sweep: one per trial of a cell, whatever the worker count or order.

The stream of trial ``t`` of a cell is ``SeedSequence(entropy=[seed, *sha256(cell parameters)],
spawn_key=(t,))``: it depends on the sweep seed, the cell's parameter values and the trial number
only, so adding a value to the grid or trials to the sweep leaves the existing cells' numbers
unchanged.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from typing import Any

import numpy as np

from experiments.sweep.spec import params_key

__all__ = ["cell_entropy", "cell_seed_sequences", "child_seeds"]


def cell_entropy(seed: int, params: Mapping[str, Any]) -> list[int]:
    """The entropy words of a cell's streams: ``[seed, *first 16 bytes of sha256(params_key(params))]``."""
    digest = hashlib.sha256(params_key(params).encode()).digest()
    return [int(seed), *np.frombuffer(digest[:16], dtype="<u4").tolist()]


def cell_seed_sequences(seed: int, params: Mapping[str, Any], trials: int) -> list[np.random.SeedSequence]:
    """The per-trial seed sequences of one cell .

    Parameters
    ----------
    seed : int
        The sweep's seed.
    params : mapping
        The cell's swept values, dotted key → Python scalar.
    trials : int
        Number of trials.

    Returns
    -------
    list of numpy.random.SeedSequence
        ``SeedSequence(entropy=[seed, *sha256(params)], spawn_key=(t,))`` for ``t < trials``;
        spawn children from each for spacecraft and sensors.
    """
    entropy = cell_entropy(seed, params)
    return [np.random.SeedSequence(entropy, spawn_key=(t,)) for t in range(trials)]


def child_seeds(ss: np.random.SeedSequence, n: int) -> list[np.random.SeedSequence]:
    """The ``n`` children of ``ss`` that ``ss.spawn(n)`` gives on a fresh object, without mutating ``ss``.

    ``SeedSequence.spawn`` is stateful (a second call gives other children); cell functions derive
    their per-role streams with this pure form so that calling them twice with the same seeds gives
    the same numbers.
    """
    return [np.random.SeedSequence(ss.entropy, spawn_key=(*ss.spawn_key, i), pool_size=ss.pool_size)
            for i in range(int(n))]

