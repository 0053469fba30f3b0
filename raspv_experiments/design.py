"""The order of a session's trials from a protocol's design and the subject (no rclpy).

Everything is reproducible from the protocol file and the subject id: the subject number (the
digits of the id, ``S07`` → 7) picks the row of a balanced Latin square (Williams design:
every condition comes once at every position and follows every other condition equally often,
so order and first-order carry-over effects are counterbalanced over a complete set of
subjects), and seeds the random orders with the design's ``seed``.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from raspv_experiments.protocol import Protocol


@dataclass(frozen=True)
class PlannedTrial:
    index: int              # 1-based position in the session
    block: int              # 1-based
    condition: str
    task: str
    repetition: int         # 1-based per condition × task; 0 for practice trials
    practice: bool
    break_before: bool      # a break (the subject rests) comes before this trial

    @property
    def label(self) -> str:
        rep = "practice" if self.practice else f"rep {self.repetition}"
        return f"{self.condition} / {self.task} / {rep}"

    @property
    def slug(self) -> str:
        """File-name friendly id, e.g. ``007-depth-corridor-r2``."""
        rep = "p" if self.practice else f"r{self.repetition}"
        return f"{self.index:03d}-{self.condition}-{self.task}-{rep}"


def trial_seed(subject: int, index: int) -> int:
    """The seed of virtual subject ``subject``'s trial at 1-based session position ``index``
    (practice trials count): its policy's noise and what it is told of the goal. The subject node,
    the session runner and the quick sweep all seed trials with this."""
    return subject * 100_003 + index


def scripted_subject_id(policy: str, number: int) -> str:
    """The subject id of virtual subject ``number`` walking with ``policy`` (its session folder's
    name; its number picks the session's counterbalanced order)."""
    return f"scripted-{policy}-{number}"


def subject_number(subject: str) -> int:
    """The number in a subject id (its last group of digits): ``S07`` → 7, ``scripted-follow_path-3`` → 3."""
    found = re.findall(r"\d+", subject)
    if not found:
        raise ValueError(f"subject id {subject!r} has no number; use ids like S07 (the number picks the "
                         "counterbalanced order and seeds random orders)")
    return int(found[-1])


def balanced_latin_square(n: int) -> list[list[int]]:
    """Williams design for ``n`` conditions: n rows when n is even, 2n (each row and its
    reverse) when n is odd. Row r, position j: condition index."""
    if n < 1:
        raise ValueError("a Latin square needs at least one condition")
    first = [0]
    lo, hi = 1, n - 1
    for j in range(1, n):
        if j % 2:
            first.append(lo)
            lo += 1
        else:
            first.append(hi)
            hi -= 1
    rows = [[(c + r) % n for c in first] for r in range(n)]
    if n % 2:
        rows += [row[::-1] for row in rows]
    return rows


def condition_order(protocol: Protocol, subject: int) -> list[str]:
    names = [c.name for c in protocol.conditions]
    d = protocol.design
    if d.order == "fixed":
        return names
    if d.order == "random":
        rng = np.random.default_rng([d.seed, subject, 0])
        return [names[i] for i in rng.permutation(len(names))]
    rows = balanced_latin_square(len(names))
    return [names[i] for i in rows[(subject - 1) % len(rows)]]


def plan_session(protocol: Protocol, subject: str) -> list[PlannedTrial]:
    """The trials of ``subject``'s session in order."""
    d = protocol.design
    number = subject_number(subject)
    conditions = condition_order(protocol, number)
    tasks = [t.name for t in protocol.tasks]
    if d.blocks == "condition":
        blocks = [[(c, t, r) for r in range(1, d.repetitions + 1) for t in tasks] for c in conditions]
    else:
        blocks = [[(c, t, r) for r in range(1, d.repetitions + 1) for c in conditions for t in tasks]]
    trials: list[PlannedTrial] = []
    for b, cells in enumerate(blocks, start=1):
        if d.within_block == "random":
            rng = np.random.default_rng([d.seed, number, b])
            cells = [cells[i] for i in rng.permutation(len(cells))]
        practice = [(cells[k % len(cells)][0], cells[k % len(cells)][1]) for k in range(d.practice)]
        first = True
        for c, t in practice:
            trials.append(PlannedTrial(len(trials) + 1, b, c, t, 0, True, first and b > 1 and d.break_between_blocks))
            first = False
        for c, t, r in cells:
            trials.append(PlannedTrial(len(trials) + 1, b, c, t, r, False, first and b > 1 and d.break_between_blocks))
            first = False
    return trials
