"""The grocery table in docs/learn.md against a fresh recomputation from the per-frame scores
(raspv_learn/evaluations/grocery.per_frame.npz: obstacle [tp, fp, fn] of every row, seed and test
frame, written by the scoring): per-seed IoU, mean, bootstrap CI and gain, to the printed digit."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from raspv_learn.bootstrap import summarise
from raspv_learn.evaluation import EVALUATIONS_DIR, load_evaluation

DOCS = Path(__file__).resolve().parents[2] / "docs" / "learn.md"


def _docs_table(text: str, config: str, depth: str) -> tuple[dict, tuple[float, float, float]]:
    start = text.index(f"{config}, {depth} depth")
    block = text[start:text.index("target +10 on the lower bound", start)]
    rows = {}
    for m in re.finditer(r"^\| (\w+)(?: \(best hand-designed\))? \| (.+) \| ([\d.]+) \[([\d.]+), ([\d.]+)\] \|$", block,
                         re.M):
        rows[m.group(1)] = ([float(x) for x in m.group(2).split(" | ")], float(m.group(3)), float(m.group(4)),
                            float(m.group(5)))
    g = re.search(r"gain learned − \w+: ([+-][\d.]+) points \[([+-][\d.]+), ([+-][\d.]+)\]", block)
    return rows, tuple(float(x) for x in g.groups())


@pytest.mark.parametrize("config", ["argus_iii", "optimist"])
def test_the_documented_grocery_table_is_the_per_frame_scores(config):
    ev = load_evaluation("grocery")
    with np.load(EVALUATIONS_DIR / "grocery.per_frame.npz") as f:
        counts, rows, seeds = f[f"{config}-realistic-counts"], list(f[f"{config}-realistic-rows"]), \
            list(f[f"{config}-realistic-seeds"])
    assert seeds == list(ev.training_seeds) and counts.shape[2] == ev.test_frames_per_world
    s = summarise(counts, rows, "learned", ev.resamples, ev.confidence, ev.bootstrap_seed)
    documented, gain = _docs_table(DOCS.read_text(), config, "realistic")
    assert set(documented) == set(rows)
    for i, r in enumerate(rows):
        per_seed, mean, low, high = documented[r]
        np.testing.assert_allclose(per_seed, np.round(100 * s.per_seed[i], 1), atol=0.051)
        ci = s.rows_ci[r].points()
        np.testing.assert_allclose([mean, low, high], np.round([ci.mean, ci.low, ci.high], 1), atol=0.051)
    g = s.gain.points()
    np.testing.assert_allclose(gain, np.round([g.mean, g.low, g.high], 1), atol=0.051)
