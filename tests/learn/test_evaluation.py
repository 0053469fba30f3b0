"""The pre-registered evaluation: the file and its hash, the configuration it trains and scores,
the ledger's refusal, per-frame confusions and the bootstrap over seeds and frames (synthetic
counts and tiny tensors; no training)."""
from __future__ import annotations

import hashlib
import types
from pathlib import Path

import numpy as np
import pytest
import torch

from raspv_learn.bootstrap import class_counts, iou_of, summarise
from raspv_learn.config import ConfigError, load_config
from raspv_learn.evaluation import EVALUATIONS_DIR, EvaluationError, configuration_for, load_evaluation
from raspv_learn.ledger import earlier_scorings, read_ledger
from raspv_learn.metrics import Confusion
from raspv_learn.prepare import Split
from raspv_learn.scoring import ScoringRefused, check_ledger, compare_evaluation, model_identity, render_table
from raspv_learn.train import confusions_per_frame


def test_the_grocery_evaluation_and_the_configuration_it_trains():
    ev = load_evaluation("grocery")
    path = EVALUATIONS_DIR / "grocery.yaml"
    assert ev.sha256 == hashlib.sha256(path.read_bytes()).hexdigest()
    assert ev.test_worlds == ("grocery",) and ev.training_seeds == (0, 1, 2) and ev.primary_depth == "realistic"
    base = load_config("argus_iii")
    c = configuration_for(base, ev, 2)
    assert c.data.test_worlds == ("grocery",) and c.data.test_frames_per_world == 500 and c.data.seed == 0
    assert c.train.seed == 2 and c.data.depth_sensor["dark_dropout"] == 0.6
    assert c.data.train_worlds == base.data.train_worlds and c.train.epochs == base.train.epochs
    perfect = configuration_for(base, ev, 2, "perfect")
    assert perfect.data.depth_sensor is None and perfect.data.key() != c.data.key()
    # the shipped models' keys do not change with the new (None) depth_sensor field
    assert base.key() == "a8048971791877a1" and base.data.key() == "5618db895157707c"
    with pytest.raises(ConfigError, match="not a training seed"):
        configuration_for(base, ev, 7)
    with pytest.raises(EvaluationError, match="no depth condition"):
        configuration_for(base, ev, 0, "foggy")


def test_a_bad_evaluation_file_is_one_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\ntest_worlds: [grocery]\n")
    with pytest.raises(EvaluationError, match="needs exactly the keys") as info:
        load_evaluation(bad)
    assert "\n" not in str(info.value)
    with pytest.raises(EvaluationError, match="No such file"):
        load_evaluation("no_such_evaluation")


def _entry(world="grocery", config="argus_iii", model="a" * 64, scored_at="2026-12-06T20:00:00+00:00"):
    return {"world": world, "configuration": config, "model": model, "scored_at": scored_at}


def test_the_ledger_refuses_a_model_trained_after_its_world_was_scored(tmp_path):
    ev = load_evaluation("grocery")
    entries = [_entry()]
    later = {"model": "b" * 64, "trained_at": "2026-12-06T21:00:00+00:00"}
    earlier = {"model": "b" * 64, "trained_at": "2026-12-06T19:00:00+00:00"}
    with pytest.raises(ScoringRefused, match="pass --rescore"):
        check_ledger(entries, ev, "argus_iii", later, rescore=False)
    assert check_ledger(entries, ev, "argus_iii", later, rescore=True) == entries
    assert check_ledger(entries, ev, "argus_iii", earlier, rescore=False) == []        # trained before the scoring
    assert check_ledger(entries, ev, "optimist", later, rescore=False) == []           # another configuration
    assert check_ledger(entries, ev, "argus_iii", {**later, "model": "a" * 64}, rescore=False) == []   # same model
    assert earlier_scorings(entries, "office", "argus_iii", "b" * 64, later["trained_at"]) == []
    # a model trained within the same second as the scoring: times are kept to the microsecond
    from raspv_learn.ledger import append
    ledger = tmp_path / "ledger.jsonl"
    scored = append({**_entry(), "scored_at": None}, ledger)
    from datetime import datetime, timedelta
    assert "." in scored["scored_at"]
    same_second = (datetime.fromisoformat(scored["scored_at"]) + timedelta(microseconds=1)).isoformat()
    assert earlier_scorings(read_ledger(ledger), "grocery", "argus_iii", "b" * 64, same_second) != []
    ledger.write_text('{"world": "grocery"}\n')
    with pytest.raises(ValueError, match="needs world, configuration, model and scored_at"):
        read_ledger(ledger)


def test_compare_refuses_before_scoring_anything(tmp_path, monkeypatch, capsys):
    """A model trained after grocery was scored with another argus_iii model: refused (no data
    read, no observer trained); a model trained for another evaluation file: refused."""
    ev = load_evaluation("grocery")
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "runs" / "learn" / "grocery" / "argus_iii-seed0"
    folder.mkdir(parents=True)
    torch.save({"encoder": {}, "trained_at": "2026-12-06T21:00:00+00:00",
                "evaluation": {"name": "grocery", "sha256": ev.sha256}}, folder / "weights.pt")
    ledger = tmp_path / "ledger.jsonl"
    ledger.write_text('{"world": "grocery", "configuration": "argus_iii", "model": "other", '
                      '"scored_at": "2026-12-06T20:00:00+00:00"}\n')
    args = types.SimpleNamespace(config="argus_iii", depth=None, rescore=False, quiet=True)
    assert compare_evaluation(args, ev, ledger=ledger) == 2
    err = capsys.readouterr().err.strip()
    assert "was scored on 2026-12-06T20:00:00+00:00 with another argus_iii model" in err and "\n" not in err
    torch.save({"encoder": {}, "trained_at": "2026-12-06T19:00:00+00:00",
                "evaluation": {"name": "grocery", "sha256": "0" * 64}}, folder / "weights.pt")
    with pytest.raises(ScoringRefused, match="trained for evaluation sha256 000000000000"):
        model_identity(folder / "weights.pt", ev)
    assert compare_evaluation(args, ev, ledger=ledger) == 2


def test_per_frame_confusions_sum_to_the_pooled_one():
    rng = np.random.default_rng(0)
    targets = rng.integers(0, 4, size=(7, 5, 6)).astype(np.uint8)
    logits = torch.from_numpy(rng.normal(size=(7, 3, 5, 6)).astype(np.float32))
    split = Split(np.zeros((7, 1, 2, 2), np.float16), targets, np.zeros((7, 1), np.float16))
    per_frame = confusions_per_frame(lambda i: logits[i], split, batch=3)
    pooled = Confusion()
    pooled.add(logits, torch.from_numpy(targets))
    np.testing.assert_array_equal(per_frame.sum(0), pooled.matrix)
    assert per_frame[4].sum() == (targets[4] > 0).sum()


def _counts(iou_per_frame: np.ndarray, cells: int = 100) -> np.ndarray:
    """[tp, fp, fn] per frame with the given IoU (tp = iou·cells, the rest fp/fn)."""
    tp = np.rint(iou_per_frame * cells)
    return np.stack([tp, (cells - tp) // 2, cells - tp - (cells - tp) // 2], -1)


def test_bootstrap_over_seeds_and_frames():
    rng = np.random.default_rng(1)
    F = 200
    base = rng.uniform(0.3, 0.7, F)                                     # frame difficulty, shared by rows
    hand_a = np.stack([_counts(np.clip(base + rng.normal(0, 0.02, F), 0, 1)) for _ in range(3)])
    hand_b = np.stack([_counts(np.clip(base - 0.1 + rng.normal(0, 0.02, F), 0, 1)) for _ in range(3)])
    learned = np.stack([_counts(np.clip(base + 0.15 + rng.normal(0, 0.02, F), 0, 1)) for _ in range(3)])
    counts = np.stack([hand_a, hand_b, learned])                       # (R=3, S=3, F, 3)
    s = summarise(counts, ["a", "b", "learned"], "learned", resamples=2000, confidence=0.95, seed=0)
    assert s.best == "a"
    np.testing.assert_allclose(s.per_seed, iou_of(counts.sum(2)))
    g = s.gain.points()
    assert 12 < g.low < g.mean < g.high < 18                           # +15 points built in, paired: narrow
    for r, ci in s.rows_ci.items():
        assert ci.low <= ci.mean <= ci.high
    again = summarise(counts, ["a", "b", "learned"], "learned", resamples=2000, confidence=0.95, seed=0)
    assert again.gain == s.gain                                        # seeded
    # a learned row identical to the best one: zero gain in every paired resample
    same = np.stack([hand_a, hand_b, hand_a])
    z = summarise(same, ["a", "b", "learned"], "learned", resamples=500, confidence=0.95, seed=3).gain
    assert z.mean == z.low == z.high == 0.0
    # seeds that disagree widen the interval: one seed much worse
    spread = counts.copy()
    spread[2, 0] = _counts(np.clip(base - 0.05, 0, 1))
    wide = summarise(spread, ["a", "b", "learned"], "learned", resamples=2000, confidence=0.95, seed=0).gain
    assert (wide.high - wide.low) > 3 * (s.gain.high - s.gain.low)


def test_class_counts_of_a_confusion():
    m = np.array([[5, 1, 2], [0, 7, 3], [4, 1, 9]])                    # true × predicted
    np.testing.assert_array_equal(class_counts(m[None], "iou_obstacle")[0], [9, 5, 5])
    np.testing.assert_array_equal(class_counts(m[None], "iou_floor")[0], [5, 4, 3])


def test_the_table_says_when_a_world_was_rescored():
    table = {"configuration": "argus_iii", "depth": "realistic", "primary": True, "seeds": [0], "frames": 10,
             "rows": [{"row": "depth", "per_seed": [0.5], "mean": 0.5, "low": 0.4, "high": 0.6},
                      {"row": "learned", "per_seed": [0.7], "mean": 0.7, "low": 0.6, "high": 0.8}],
             "best_hand_designed": "depth", "gain_points": {"mean": 20.0, "low": 9.0, "high": 30.0},
             "target_met": False, "rescored": True, "confidence": 0.95, "resamples": 100}
    text = render_table(table)
    assert "RESCORED" in text and "| learned | 70.0 | 70.0 [60.0, 80.0] |" in text and "NOT met" in text
    assert "RESCORED" not in render_table({**table, "rescored": False})


def test_the_shipped_ledger_knows_the_office_is_spent():
    """The office history, recorded from git: a new Argus III or Optimist model is refused on the
    office; the 20-epoch Argus III entry is marked as the rescore it was."""
    entries = read_ledger()
    office = [e for e in entries if e["world"] == "office"]
    assert {e["configuration"] for e in office} == {"argus_iii", "optimist"}
    assert [e["rescore"] for e in office if e["configuration"] == "argus_iii"] == [False, True]
    now = "2026-12-06T22:00:00+00:00"
    for config in ("argus_iii", "optimist"):
        assert earlier_scorings(entries, "office", config, "f" * 64, now)
    shipped = hashlib.sha256((Path(__file__).parents[2] / "raspv_learn/models/argus_iii.pt").read_bytes()).hexdigest()
    assert shipped in {e["model"] for e in office}


@pytest.mark.parametrize("argv, says", [
    (["learn", "train", "argus_iii", "--evaluation", "grocery"], "needs --seed (one of [0, 1, 2])"),
    (["learn", "train", "argus_iii", "--evaluation", "grocery", "--seed", "5"], "seed 5: not a training seed"),
    (["learn", "train", "argus_iii", "--seed", "1"], "--seed, --depth and --rescore go with --evaluation"),
    (["learn", "compare", "--evaluation", "grocery", "--data", "x"], "no --data or --out"),
    (["learn", "dataset", "argus_iii", "--evaluation", "nope"], "evaluation nope: No such file"),
])
def test_cli_misuse_is_one_line(argv, says, capsys):
    from raspv_bringup.cli import main as raspv

    assert raspv(argv) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and "\n" not in err
