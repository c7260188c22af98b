"""A standing corpus of malformed configs, generated from every shipped config by a seeded rng.

Each case is one mutation of one file of ``experiments/configs/``: a deleted, unknown or mistyped
key, a NaN/inf/huge/negative number, a wrong container, deep nesting, a huge string, a binary file,
a bad ``kind``, a bad sweep grid, a bad mesh path or a dotted override (``--set``) into nowhere.
Validation (:func:`experiments.config.load_config`) must either refuse the case with a
:class:`~experiments.config.ConfigError` whose message is one line of at most 300 characters
naming a key, or accept a config holding no non-finite float.

Run as a script for the counts per mutation kind::

    python -m tests.experiments.config_fuzz --n 1000 --seed 0

It also times the refusal of a 10 000-value (and a 100 000-value) sweep grid.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
import tempfile
import time
import tomllib
import traceback
from collections import Counter, defaultdict
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from experiments.config import MAX_MESSAGE_CHARS, ConfigError, load_config

__all__ = ["Case", "MUTATIONS", "OUTCOMES", "SHIPPED", "generate", "outcome", "to_toml", "nonfinite_paths", "grid_refusal_s",
           "main"]

#: the shipped configs every case starts from
SHIPPED = sorted((Path(__file__).resolve().parents[2] / "experiments" / "configs").glob("*.toml"))
#: what validation may do with a case; only the first two are allowed
OUTCOMES = ("refused", "accepted", "traceback", "nonfinite", "bad_message")
#: a good message: "key: what is wrong", one line
_GOOD_MESSAGE = re.compile(r'(?:[^\s:"]|"[^"\n]*")+: \S')


@dataclass
class Case:
    """One malformed config: a parsed table, or the bytes of a file, plus dotted overrides."""

    mutation: str
    origin: str
    table: dict[str, Any] | None = None
    data: bytes | None = None
    overrides: dict[str, Any] = field(default_factory=dict)


# --- TOML text -------------------------------------------------------------------------------------

def _toml_str(s: str) -> str:
    out = []
    for ch in s:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, str):
        return _toml_str(v)
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_toml_str(k)} = {_toml_value(x)}" for k, x in v.items() if x is not None) + "}"
    raise TypeError(f"no TOML for {type(v).__name__}")


def to_toml(table: dict[str, Any]) -> str:
    """A TOML text of ``table``: one ``key = value`` line per top-level key, inline tables below."""
    return "".join(f"{_toml_str(k)} = {_toml_value(v)}\n" for k, v in table.items() if v is not None)


# --- walking a table --------------------------------------------------------------------------------

def _paths(node: Any, prefix: tuple = ()) -> Iterator[tuple[tuple, Any]]:
    """Every (path, value) below ``node``; a path is a tuple of keys and list indices."""
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for k, v in items:
        yield prefix + (k,), v
        yield from _paths(v, prefix + (k,))


def _get(table: Any, path: tuple) -> Any:
    for p in path:
        table = table[p]
    return table


def _set(table: Any, path: tuple, value: Any) -> None:
    _get(table, path[:-1])[path[-1]] = value


def _pick(rng: np.random.Generator, seq: list) -> Any:
    return seq[int(rng.integers(len(seq)))]


def _leaves(table: dict, numeric: bool = False) -> list[tuple]:
    out = []
    for path, v in _paths(table):
        if numeric and not (isinstance(v, int | float) and not isinstance(v, bool)):
            continue
        if not numeric and isinstance(v, dict):
            continue
        out.append(path)
    return out


def _tables(table: dict) -> list[tuple]:
    return [()] + [p for p, v in _paths(table) if isinstance(v, dict)]


def _deep(depth: int, inner: Any, rng: np.random.Generator) -> Any:
    for _ in range(depth):
        inner = {"a": inner} if rng.random() < 0.5 else [inner]
    return inner


# --- mutations: each changes ``table`` in place (or returns bytes / overrides) ---------------------

def _delete_key(rng, t, case):
    path = _pick(rng, [p for p, _ in _paths(t) if not isinstance(p[-1], int)])
    del _get(t, path[:-1])[path[-1]]


def _unknown_key(rng, t, case):
    where = _get(t, _pick(rng, _tables(t)))
    where[_pick(rng, ["nope", "distance", "Seed", "x1", "kind_", "trials_"])] = _pick(rng, [1, 2.5, "x", True, [1]])


def _mistype(rng, t, case):
    path = _pick(rng, _leaves(t))
    _set(t, path, _pick(rng, ["text", "", True, False, 7, 2.5, -3, [1, 2], [], {"a": 1}, {}, [[1.0]]]))


def _nonfinite(rng, t, case):
    path = _pick(rng, _leaves(t, numeric=True))
    _set(t, path, _pick(rng, [math.nan, math.inf, -math.inf]))


def _huge(rng, t, case):
    path = _pick(rng, _leaves(t, numeric=True))
    _set(t, path, _pick(rng, [1e308, -1.7e308, 1.7e308, 9.2e18, 1e30, 10**30, 2**63, -(2**63) - 1, 10**400,
                              5e-324]))


def _negative(rng, t, case):
    path = _pick(rng, _leaves(t, numeric=True))
    v = _get(t, path)
    _set(t, path, -abs(v) if v else -1)


def _wrong_container(rng, t, case):
    path = _pick(rng, [p for p, _ in _paths(t)])
    v = _get(t, path)
    if isinstance(v, dict):
        new = list(v.values())
    elif isinstance(v, list):
        new = {str(i): x for i, x in enumerate(v)}
    else:
        new = _pick(rng, [[v], {"value": v}, [[v]]])
    _set(t, path, new)


def _deep_nesting(rng, t, case):
    depth = int(_pick(rng, [17, 40, 400, 2000]))
    path = _pick(rng, _leaves(t))
    _set(t, path, _deep(depth, _get(t, path), rng))


def _huge_string(rng, t, case):
    n = int(_pick(rng, [4097, 5000, 100_000, 10_000_000 if rng.random() < 0.1 else 200_000]))
    text = "x" * n
    if rng.random() < 0.3:
        _get(t, _pick(rng, _tables(t)))[text[:int(_pick(rng, [300, 5000]))]] = 1
    else:
        _set(t, _pick(rng, _leaves(t)), text)


def _binary(rng, t, case):
    text = to_toml(t)
    choice = int(rng.integers(6))
    if choice == 0:
        case.data = rng.integers(0, 256, int(rng.integers(1, 4096)), dtype=np.uint8).tobytes()
    elif choice == 1:
        case.data = text.encode("utf-16")
    elif choice == 2:
        case.data = text.encode()[: int(rng.integers(1, max(2, len(text))))]
    elif choice == 3:
        case.data = text.encode() + b"\x00\xff\xfe"
    elif choice == 4:
        case.data = ("# \u00e9t\u00e9\n" + text).encode("latin-1", "replace")
    else:
        case.data = b"kind = " + b"{a = " * 1200 + b"1" + b"}" * 1200 + b"\n"


def _kind(rng, t, case):
    t["kind"] = _pick(rng, [["formation"], 5, "unknown", {"a": 1}, "", "x" * 5000, True, [t.get("kind")]])


def _grid(rng, t, case):
    sweep = t.setdefault("sweep", {"cell": "error_map", "trials": 1})
    if not isinstance(sweep, dict):
        sweep = t["sweep"] = {"cell": "error_map", "trials": 1}
    grid = sweep.setdefault("grid", {})
    key = _pick(rng, ["formation.distance_m", "formation.n_views", "time.dt_s", "nope.x", "kind", "sweep.trials",
                      "formation..x", "1bad", "seed"])
    grid[key] = _pick(rng, [
        {"start": 30, "stop": math.inf, "step": 10}, {"start": -math.inf, "stop": 1, "step": 1},
        {"start": 30, "stop": 100, "step": 1e-12}, {"start": 30, "stop": 100, "num": 10**9},
        {"start": 30, "stop": 100, "step": math.nan}, {"start": 0, "stop": 1}, {"start": 1, "stop": 0, "step": 1},
        {"start": -1e308, "stop": 1e308, "step": 1.0}, [float(v) for v in np.linspace(1, 999, 20_000)],
        [], [[1, 2]], [math.nan], [1, 1], "30", [{"a": 1}], list(range(1, 100)),
    ])


def _mesh(rng, t, case):
    target = t.setdefault("target", {})
    if not isinstance(target, dict):
        target = t["target"] = {}
    target["model"] = _pick(rng, ["/etc/passwd", "x" * 5000 + ".obj", "nonexistent.obj", "/dev/null",
                                  "vision/target/meshes/README.md", "experiments/configs/quickstart.toml",
                                  "a/" * 600 + "m.obj", "/" + "b" * 300 + ".stl", "topex", "hubble", "fy1", "",
                                  "/tmp", "\x00.obj"])


def _override(rng, t, case):
    key = _pick(rng, ["seed.x", "formation.nope", "kind.x", "title.a.b", "sweep.grid.x", "target.model.x",
                      "nope", "formation.distance_m", "time", "camera"])
    case.overrides[key] = _pick(rng, [1, "x", math.nan, {"a": 1}, [1, 2], True])


#: mutation kind → function(rng, table, case) changing the table in place (or setting case fields)
MUTATIONS: dict[str, Callable[[np.random.Generator, dict, Case], None]] = {
    "delete_key": _delete_key,
    "unknown_key": _unknown_key,
    "mistype": _mistype,
    "nonfinite": _nonfinite,
    "huge": _huge,
    "negative": _negative,
    "wrong_container": _wrong_container,
    "deep_nesting": _deep_nesting,
    "huge_string": _huge_string,
    "binary": _binary,
    "kind": _kind,
    "grid": _grid,
    "mesh": _mesh,
    "override": _override,
}


def generate(n: int, seed: int) -> Iterator[Case]:
    """``n`` cases, each mutation kind in turn, from shipped configs drawn by ``np.random.default_rng(seed)``.

    About a third of the table cases are written as TOML files (so the parser is exercised too).
    """
    rng = np.random.default_rng(seed)
    tables = {p.name: tomllib.loads(p.read_text()) for p in SHIPPED}
    kinds = list(MUTATIONS)
    for i in range(n):
        origin = _pick(rng, sorted(tables))
        table = json.loads(json.dumps(tables[origin]))
        case = Case(mutation=kinds[i % len(kinds)], origin=origin)
        MUTATIONS[case.mutation](rng, table, case)
        if case.data is None:
            if rng.random() < 1 / 3:
                try:
                    case.data = to_toml(table).encode()
                except (RecursionError, ValueError):
                    case.table = table
            else:
                case.table = table
        yield case


def nonfinite_paths(node: Any, prefix: str = "") -> list[str]:
    """Dotted paths of every non-finite float in a dumped config."""
    out = []
    stack = [(node, prefix)]
    while stack:
        v, at = stack.pop()
        if isinstance(v, float) and not math.isfinite(v):
            out.append(at)
        elif isinstance(v, dict):
            stack.extend((x, f"{at}.{k}" if at else str(k)) for k, x in v.items())
        elif isinstance(v, list | tuple):
            stack.extend((x, f"{at}[{j}]") for j, x in enumerate(v))
    return out


def outcome(case: Case, workdir: Path) -> tuple[str, str]:
    """Validate one case: ``(outcome, detail)``, the outcome one of :data:`OUTCOMES`."""
    source: Any = case.table
    if case.data is not None:
        source = workdir / "case.toml"
        source.write_bytes(case.data)
    try:
        _, cfg = load_config(source, case.overrides)
    except ConfigError as exc:
        msg = str(exc)
        good = "\n" not in msg and len(msg) <= MAX_MESSAGE_CHARS and _GOOD_MESSAGE.match(msg) is not None
        return ("refused" if good else "bad_message"), msg
    except Exception as exc:  # noqa: BLE001 - the corpus exists to find these
        return "traceback", "".join(traceback.format_exception_only(exc)).strip()[:300]
    bad = nonfinite_paths(cfg.model_dump())
    return ("nonfinite", ", ".join(bad)[:300]) if bad else ("accepted", "")


def grid_refusal_s(n_values: int = 10_000, origin: str = "003_fig5_fig6.toml") -> tuple[float, str]:
    """Seconds :func:`load_config` takes to refuse ``origin`` with ``n_values`` distances swept, and its message."""
    table = tomllib.loads((SHIPPED[0].parent / origin).read_text())
    table["sweep"]["grid"]["formation.distance_m"] = [0.1 * i for i in range(1, n_values + 1)]
    t0 = time.perf_counter()
    try:
        load_config(table)
    except ConfigError as exc:
        return time.perf_counter() - t0, str(exc)
    return time.perf_counter() - t0, "accepted"


def main(argv: list[str] | None = None) -> int:
    """Print the outcome counts per mutation kind; exit 1 on any traceback, non-finite or bad message."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000, help="number of cases")
    ap.add_argument("--seed", type=int, default=0, help="seed of the generator")
    ap.add_argument("--show", type=int, default=3, help="examples shown per failing outcome")
    args = ap.parse_args(argv)
    counts: dict[str, Counter] = defaultdict(Counter)
    failures: dict[str, list[str]] = defaultdict(list)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for case in generate(args.n, args.seed):
            what, detail = outcome(case, Path(tmp))
            counts[case.mutation][what] += 1
            if what not in ("refused", "accepted"):
                failures[what].append(f"{case.mutation} of {case.origin}: {detail}")
    wall_s = time.perf_counter() - t0
    print(f"{'mutation':16s} " + " ".join(f"{o:>11s}" for o in OUTCOMES))
    total: Counter = Counter()
    for kind in MUTATIONS:
        total.update(counts[kind])
        print(f"{kind:16s} " + " ".join(f"{counts[kind][o]:11d}" for o in OUTCOMES))
    print(f"{'total':16s} " + " ".join(f"{total[o]:11d}" for o in OUTCOMES))
    print(f"{args.n} cases, seed {args.seed}, {wall_s:.1f} s")
    load_config(SHIPPED[0])  # the kinds imported before timing
    for n_values in (10_000, 100_000):
        grid_s, msg = grid_refusal_s(n_values)
        print(f"a {n_values}-value grid refused in {grid_s:.3f} s: {msg}")
    for what, lines in failures.items():
        for line in lines[:args.show]:
            print(f"{what}: {line}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
