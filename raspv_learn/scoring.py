"""``raspv learn compare --evaluation NAME``: the pre-registered scoring (docs/learn.md).

For every configuration, depth condition (primary first) and training seed whose model exists
(``runs/learn/NAME/<config>-seed<S>/weights.pt``, trained for this very file: its sha256), the
computational observer is trained with that seed on every hand-designed mode's images and on the
learned encoder's, and scored on every test frame (a confusion matrix per frame, kept in
``runs/learn/NAME/scores/`` so a killed comparison resumes). The ledger
(:mod:`raspv_learn.ledger`) is consulted before, and written after, each learned row; then the
table: per row the IoU of each seed, the mean over seeds and its bootstrap CI
(:mod:`raspv_learn.bootstrap`), the gain over the best hand-designed row with its CI, and the
target on the lower bound. The summary goes to ``runs/learn/NAME/results.json``.
"""
from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np

from raspv_learn.bootstrap import class_counts, summarise
from raspv_learn.evaluation import Evaluation, configuration_for, run_folder
from raspv_learn import ledger as ledger_module
from raspv_learn.ledger import LedgerError, append, earlier_scorings, read_ledger

LEARNED = "learned"


class ScoringRefused(ValueError):
    """A scoring the ledger forbids (one line)."""


def model_identity(weights: Path, evaluation: Evaluation) -> dict:
    """sha256 and training time of a model trained for ``evaluation``; raises ScoringRefused when
    it was trained for another evaluation file (or none)."""
    import torch

    state = torch.load(weights, weights_only=False, map_location="cpu")
    recorded = (state.get("evaluation") or {}).get("sha256")
    if recorded != evaluation.sha256:
        raise ScoringRefused(f"{weights}: trained for evaluation sha256 {str(recorded)[:12]}, not {evaluation.name}'s "
                             f"{evaluation.sha256[:12]} (the file changed, or the model was not trained for it)")
    return {"model": hashlib.sha256(weights.read_bytes()).hexdigest(), "trained_at": state["trained_at"],
            "state": state}


def check_ledger(entries: list[dict], evaluation: Evaluation, config_name: str, identity: dict,
                 rescore: bool) -> list[dict]:
    """The earlier scorings that make this one a rescore; raises ScoringRefused without ``rescore``."""
    earlier = [e for w in evaluation.test_worlds
               for e in earlier_scorings(entries, w, config_name, identity["model"], identity["trained_at"])]
    if earlier and not rescore:
        e = earlier[0]
        raise ScoringRefused(f"{config_name}: {e['world']} was scored on {e['scored_at']} with another {config_name} "
                             f"model ({e['model'][:12]}), before this one was trained ({identity['trained_at']}); "
                             "pass --rescore to score it anyway (the table will say so)")
    return earlier


def compare_evaluation(args, evaluation: Evaluation, runs_root: str | Path = "runs/learn",
                       ledger: Path | None = None) -> int:
    from raspv_learn.config import load_config

    ledger = Path(ledger or ledger_module.LEDGER)
    names = evaluation.configurations if args.config in (None, "all") else (args.config,)
    conditions = [args.depth] if getattr(args, "depth", None) else \
        [evaluation.primary_depth, *[c for c in evaluation.depth if c != evaluation.primary_depth]]
    root = Path(runs_root) / evaluation.name
    results = {"evaluation": evaluation.name, "sha256": evaluation.sha256, "metric": evaluation.metric,
               "target_points": evaluation.target_points, "tables": []}
    try:
        bases = {c.name: c for c in map(load_config, names)}
        # the ledger is checked for every model before anything is scored
        models = {}
        entries = read_ledger(ledger)
        for name in bases:
            for seed in evaluation.training_seeds:
                weights = run_folder(evaluation, name, seed, runs_root) / "weights.pt"
                if weights.exists():
                    ident = model_identity(weights, evaluation)
                    ident["earlier"] = check_ledger(entries, evaluation, name, ident, args.rescore)
                    models[(name, seed)] = ident
        if not models:
            raise ScoringRefused(f"no model trained for {evaluation.name} under {root}: raspv learn train CONFIG "
                                 f"--evaluation {evaluation.name} --seed S")
        for name, base in bases.items():
            seeds = [s for s in evaluation.training_seeds if (name, s) in models]
            missing = [s for s in evaluation.training_seeds if s not in seeds]
            if missing:
                print(f"{name}: no model for seed(s) {missing}: scored with {len(seeds)} of "
                      f"{len(evaluation.training_seeds)} seeds", file=sys.stderr)
            if not seeds:
                continue
            for cond in conditions:
                table = _score_condition(args, evaluation, base, cond, seeds, models, root, ledger)
                results["tables"].append(table)
                print(render_table(table), flush=True)
                _write_results(root / "results.json", results)      # after every table: a later one may fail
    except (ScoringRefused, LedgerError) as exc:
        print(f"raspv learn: {exc}", file=sys.stderr)
        return 2
    print(f"summary: {root / 'results.json'}")
    return 0


def _write_results(path: Path, results: dict) -> None:
    """Merge ``results``' tables into ``path`` (tables of other configurations or depths, from
    another invocation of the same evaluation, are kept)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    kept = []
    if path.exists():
        old = json.loads(path.read_text())
        if old.get("sha256") == results["sha256"]:
            ours = {(t["configuration"], t["depth"]) for t in results["tables"]}
            kept = [t for t in old["tables"] if (t["configuration"], t["depth"]) not in ours]
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps({**results, "tables": kept + results["tables"]}, indent=1))
    tmp.replace(path)


def _score_condition(args, evaluation: Evaluation, base, cond: str, seeds: list[int], models: dict, root: Path,
                     ledger: Path) -> dict:
    rows = [*evaluation.modes, LEARNED]
    confusions = np.zeros((len(rows), len(seeds), evaluation.test_frames_per_world * len(evaluation.test_worlds),
                           3, 3), np.int64)
    rescored = False
    for j, seed in enumerate(seeds):
        config = configuration_for(base, evaluation, seed, cond)
        ident = models[(base.name, seed)]
        for i, row in enumerate(rows):
            confusions[i, j] = _row_confusions(args, evaluation, config, row, ident, root, cond)
        for w in evaluation.test_worlds:
            append({"evaluation": evaluation.name, "sha256": evaluation.sha256, "world": w,
                    "configuration": base.name, "seed": seed, "depth": cond, "model": ident["model"],
                    "trained_at": ident["trained_at"], "rescore": bool(ident["earlier"])}, ledger)
        rescored |= bool(ident["earlier"])
    counts = class_counts(confusions, evaluation.metric)                     # (rows, seeds, frames, [tp fp fn])
    root.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(root / f"per_frame-{base.name}-{cond}.npz", counts=counts.astype(np.int32),
                        rows=np.array(rows), seeds=np.array(seeds))
    s = summarise(counts, rows, LEARNED, evaluation.resamples, evaluation.confidence, evaluation.bootstrap_seed)
    gain = s.gain.points()
    return {"configuration": base.name, "depth": cond, "primary": cond == evaluation.primary_depth, "seeds": seeds,
            "frames": int(confusions.shape[2]), "rows": [
                {"row": r, "per_seed": [float(x) for x in s.per_seed[i]], "mean": s.rows_ci[r].mean,
                 "low": s.rows_ci[r].low, "high": s.rows_ci[r].high} for i, r in enumerate(rows)],
            "best_hand_designed": s.best, "gain_points": {"mean": gain.mean, "low": gain.low, "high": gain.high},
            "target_met": bool(gain.low >= evaluation.target_points), "rescored": rescored,
            "confidence": evaluation.confidence, "resamples": evaluation.resamples}


def _row_confusions(args, evaluation: Evaluation, config, row: str, ident: dict, root: Path, cond: str
                    ) -> np.ndarray:
    """(F, 3, 3) per-frame confusions of the observer of ``row`` (cached by everything they depend on)."""
    key = hashlib.sha256(json.dumps([config.observer_key(), row, ident["model"] if row == LEARNED else ""]
                                    ).encode()).hexdigest()[:16]
    cache = root / "scores" / f"{config.name}-seed{config.train.seed}-{cond}-{row}-{key}.npy"
    if cache.exists():
        return np.load(cache)
    from raspv_learn.learn_cli import _data_dir, _twin
    from raspv_learn.train import Pipeline, encoder_levels, train_observer

    data = _prepared(args, config, _data_dir(args, config), evaluation.modes)
    twin = _twin(config)
    if row == LEARNED:
        model = Pipeline(config, twin, data.grid, data.inside)
        model.encoder.load_state_dict(ident["state"]["encoder"])
        levels = {p: encoder_levels(model, getattr(data, p)) for p in ("train", "val", "test")}
    else:
        levels = {p: getattr(data, p).levels[row] for p in ("train", "val", "test")}
    r = train_observer(levels, data, twin, config.target.stride_px, config.decoder.features, config.observer,
                       config.train.seed, config.train.threads, f"{config.name} seed {config.train.seed} {cond} {row}",
                       progress=not args.quiet, per_frame=True)
    cache.parent.mkdir(parents=True, exist_ok=True)
    tmp = cache.with_suffix(".tmp.npy")
    np.save(tmp, r.test_confusions)
    tmp.replace(cache)
    print(f"  {config.name} seed {config.train.seed} {cond:9s} {row:22s} {r.test[evaluation.metric]:.3f} "
          f"({r.seconds / 60:.1f} min)", flush=True)
    return r.test_confusions


_PREPARED: dict = {}


def _prepared(args, config, data_dir, modes: tuple[str, ...]):
    """The prepared frames of (configuration, depth) — kept across seeds, which only split them."""
    from dataclasses import replace

    from raspv_learn.prepare import prepare_frames, split_by_seed

    key = (replace(config, train=replace(config.train, seed=0)).key(), modes)
    if key not in _PREPARED:
        _PREPARED.clear()
        _PREPARED[key] = prepare_frames(config, data_dir, modes, progress=not args.quiet)
    return split_by_seed(_PREPARED[key], config.train.seed, config.train.val_fraction)


def render_table(t: dict) -> str:
    """The table of one (configuration, depth condition), in points of the metric."""
    seeds = t["seeds"]
    head = (f"{t['configuration']}, {t['depth']} depth{' (primary)' if t['primary'] else ''}: obstacle IoU ×100 on "
            f"{t['frames']} test frames, seeds {seeds}; mean over seeds [{100 * t['confidence']:.0f} % bootstrap CI, "
            f"{t['resamples']} resamples over seeds and frames]"
            + ("  — RESCORED: a test world scored before this model was trained" if t["rescored"] else ""))
    lines = [head, "| row | " + " | ".join(f"seed {s}" for s in seeds) + " | mean [CI] |",
             "|---|" + "---|" * len(seeds) + "---|"]
    for r in t["rows"]:
        mark = " (best hand-designed)" if r["row"] == t["best_hand_designed"] else ""
        lines.append(f"| {r['row']}{mark} | " + " | ".join(f"{100 * x:.1f}" for x in r["per_seed"])
                     + f" | {100 * r['mean']:.1f} [{100 * r['low']:.1f}, {100 * r['high']:.1f}] |")
    g = t["gain_points"]
    lines.append(f"gain learned − {t['best_hand_designed']}: {g['mean']:+.1f} points [{g['low']:+.1f}, {g['high']:+.1f}]"
                 f"; target +10 on the lower bound: {'met' if t['target_met'] else 'NOT met'}")
    return "\n".join(lines) + "\n"
