"""Benchmarks printed by ``coobs bench``: our figure beside the peer library's, as a ratio."""

from __future__ import annotations

import importlib
import pkgutil
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass

__all__ = ["BenchRow", "throughput_row", "duration_row", "best_time", "topics", "run_topic"]


@dataclass(frozen=True)
class BenchRow:
    """One benchmark result.

    Attributes
    ----------
    benchmark : str
        What was measured, e.g. ``"quaternion product, 1e6 batch"``.
    figure : float
        Our measured figure, in ``unit``.
    unit : str
        Unit of ``figure`` and ``peer_figure`` (e.g. ``"products/s"``, ``"s"``).
    peer : str
        The peer implementation measured on the same input ("" when there is none).
    peer_figure : float
        The peer's figure in ``unit`` (NaN when there is no peer).
    ratio : float
        Ours relative to the peer, oriented so that > 1 means ours is better.
    note : str
        Target, accuracy check or caveat.
    """

    benchmark: str
    figure: float
    unit: str
    peer: str = ""
    peer_figure: float = float("nan")
    ratio: float = float("nan")
    note: str = ""

    def as_dict(self) -> dict:
        return asdict(self)


def throughput_row(benchmark: str, ours_s: float, peer_s: float, count: float, unit: str,
                   peer: str, note: str = "") -> BenchRow:
    """Row for a throughput benchmark: ``count`` items done in ``ours_s`` and ``peer_s`` seconds."""
    ours = count / ours_s
    theirs = count / peer_s if peer_s > 0 else float("nan")
    return BenchRow(benchmark, ours, unit, peer, theirs, ours / theirs, note)


def duration_row(benchmark: str, ours_s: float, peer_s: float, peer: str, note: str = "") -> BenchRow:
    """Row for a duration benchmark (lower is better); ``ratio = peer_s / ours_s``."""
    return BenchRow(benchmark, ours_s, "s", peer, peer_s, peer_s / ours_s, note)


def best_time(fn: Callable[[], object], *, repeat: int = 3, number: int = 1) -> float:
    """Best wall time in seconds of ``number`` calls of ``fn`` over ``repeat`` repetitions."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        best = min(best, (time.perf_counter() - t0) / number)
    return best


def topics() -> list[str]:
    """Names of the benchmark modules found (``bench_<topic>.py`` → ``topic``)."""
    import experiments.bench as pkg

    return sorted(m.name.removeprefix("bench_") for m in pkgutil.iter_modules(pkg.__path__)
                  if m.name.startswith("bench_"))


def run_topic(topic: str, *, quick: bool = False) -> list[BenchRow]:
    """Run one benchmark module and return its rows.

    Each module ``experiments/bench/bench_<topic>.py`` defines ``run(*, quick: bool) -> list[BenchRow]``
    and is discovered by :func:`topics`, so a new benchmark is a new module.  ``ratio`` is always
    "how many times better ours is" (higher is better), whatever the unit: for throughputs it is
    ours / peer, for durations peer / ours.
    """
    if topic not in topics():
        raise ValueError(f"topic: unknown benchmark topic {topic!r}; known: {', '.join(topics())}")
    module = importlib.import_module(f"experiments.bench.bench_{topic}")
    return list(module.run(quick=quick))
