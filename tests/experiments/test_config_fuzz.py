"""The standing fuzz corpus: malformed variants of every shipped config are refused in one line or valid and finite."""

from __future__ import annotations

from collections import Counter

import pytest

from experiments.config import load_config
from tests.experiments.config_fuzz import MUTATIONS, SHIPPED, generate, nonfinite_paths, outcome

N_CASES = 700  # 50 of each of the 14 mutation kinds
SEED = 17


def test_every_shipped_config_validates_with_no_nonfinite_float():
    assert len(SHIPPED) >= 9
    for path in SHIPPED:
        _, cfg = load_config(path)
        assert nonfinite_paths(cfg.model_dump()) == [], path.name


def test_generator_is_reproducible_and_covers_every_mutation_kind():
    first = [(c.mutation, c.origin, c.data, c.table, c.overrides) for c in generate(2 * len(MUTATIONS), SEED)]
    again = [(c.mutation, c.origin, c.data, c.table, c.overrides) for c in generate(2 * len(MUTATIONS), SEED)]
    assert first == again
    assert Counter(m for m, *_ in first) == Counter({m: 2 for m in MUTATIONS})


def test_malformed_configs_are_refused_in_one_named_line_or_valid_and_finite(tmp_path):
    """700 seeded cases: 0 tracebacks, 0 accepted non-finite values, 0 messages over 300 characters or without a key."""
    counts: Counter = Counter()
    bad = []
    for case in generate(N_CASES, SEED):
        what, detail = outcome(case, tmp_path)
        counts[what] += 1
        if what not in ("refused", "accepted"):
            bad.append(f"{what}: {case.mutation} of {case.origin}: {detail}")
    assert bad == []
    assert counts["refused"] + counts["accepted"] == N_CASES
    assert counts["refused"] >= N_CASES // 2  # the corpus mostly holds nonsense


@pytest.mark.parametrize("mutation", ["nonfinite", "binary", "deep_nesting", "huge_string", "kind", "wrong_container"])
def test_mutations_that_never_make_sense_are_always_refused(tmp_path, mutation):
    cases = [c for c in generate(4 * len(MUTATIONS), SEED + 1) if c.mutation == mutation]
    assert len(cases) == 4
    assert [outcome(c, tmp_path)[0] for c in cases] == ["refused"] * 4
