"""Trial order: balanced Latin squares, seeded random orders, blocks, practice and breaks, reproducible
from the protocol file and the subject id."""
from __future__ import annotations

import copy
import itertools
from collections import Counter

import pytest

from raspv_experiments.design import balanced_latin_square, plan_session, subject_number
from raspv_experiments.protocol import EXPERIMENTS_DIR, load_protocol

EXAMPLE = EXPERIMENTS_DIR / "example.yaml"



@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 6])
def test_balanced_latin_square_counterbalances_position_and_carry_over(n):
    rows = balanced_latin_square(n)
    assert len(rows) == (n if n % 2 == 0 else 2 * n)
    for row in rows:
        assert sorted(row) == list(range(n))                       # every condition once per subject
    for j in range(n):                                             # every condition equally often at every position
        assert len(set(Counter(row[j] for row in rows).values())) == 1
    if n > 1:                                                      # every ordered pair follows equally often
        pairs = Counter((a, b) for row in rows for a, b in zip(row, row[1:]))
        assert set(pairs) == {(a, b) for a, b in itertools.permutations(range(n), 2)}
        assert len(set(pairs.values())) == 1


def test_subject_numbers():
    assert subject_number("S07") == 7
    assert subject_number("scripted-follow_path-3") == 3
    with pytest.raises(ValueError, match="has no number"):
        subject_number("alice")


def _protocol(write_protocol, example_doc, conditions=("a", "b", "c", "d"), **design):
    doc = copy.deepcopy(example_doc)
    doc["conditions"] = {c: {"spv": {"mode": "depth"}} for c in conditions}
    doc["design"].update(design)
    return load_protocol(write_protocol(doc))


def test_latin_square_order_by_subject_number(write_protocol, example_doc):
    p = _protocol(write_protocol, example_doc, repetitions=2)
    orders = {s: [t.condition for t in plan_session(p, s)][::2] for s in ("S01", "S02", "S03", "S04", "S05")}
    assert orders["S01"] == ["a", "b", "d", "c"]
    assert orders["S05"] == orders["S01"]                          # the square repeats every 4 subjects
    for j in range(4):
        assert {orders[s][j] for s in ("S01", "S02", "S03", "S04")} == {"a", "b", "c", "d"}


def test_blocks_practice_breaks_and_repetitions(write_protocol, example_doc):
    p = _protocol(write_protocol, example_doc, conditions=("a", "b"), order="fixed", repetitions=3, practice=1)
    plan = plan_session(p, "S01")
    assert [t.index for t in plan] == list(range(1, 9))
    assert [(t.condition, t.repetition, t.practice, t.break_before) for t in plan] == [
        ("a", 0, True, False), ("a", 1, False, False), ("a", 2, False, False), ("a", 3, False, False),
        ("b", 0, True, True), ("b", 1, False, False), ("b", 2, False, False), ("b", 3, False, False)]
    assert [t.block for t in plan] == [1] * 4 + [2] * 4
    assert plan[5].slug == "006-b-hallway-r1"


def test_random_orders_are_seeded_by_the_file_and_the_subject(write_protocol, example_doc):
    p = _protocol(write_protocol, example_doc, conditions=tuple("abcdef"), order="random", blocks="none",
                  within_block="random", repetitions=2, seed=11)
    first = [(t.condition, t.repetition) for t in plan_session(p, "S03")]
    assert first == [(t.condition, t.repetition) for t in plan_session(p, "S03")]      # reproducible
    assert first != [(t.condition, t.repetition) for t in plan_session(p, "S04")]      # per subject
    assert sorted(first) == sorted((c, r) for c in "abcdef" for r in (1, 2))           # complete
    q = _protocol(write_protocol, example_doc, conditions=tuple("abcdef"), order="random", blocks="none",
                  within_block="random", repetitions=2, seed=12)
    assert first != [(t.condition, t.repetition) for t in plan_session(q, "S03")]      # per seed


def test_the_example_plan():
    plan = plan_session(load_protocol(EXAMPLE), "S01")
    assert [t.condition for t in plan] == ["depth"] * 3 + ["downsampling"] * 3
    assert [t.condition for t in plan_session(load_protocol(EXAMPLE), "S02")] == ["downsampling"] * 3 + ["depth"] * 3
