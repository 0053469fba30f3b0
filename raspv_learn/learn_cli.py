"""``raspv learn``: render the dataset, train an encoder end to end, compare it with the
hand-designed modes through the computational observer (docs/learn.md).

    raspv learn dataset optimist            # the data recipe of raspv_learn/configs/optimist.yaml
    raspv learn train optimist              # → runs/learn/optimist/ (checkpoints, encoder.onnx)
    raspv learn train optimist --resume     # continue a killed run
    raspv learn compare optimist            # observer scores of every mode on the held-out world
    raspv learn compare optimist --shipped  # the table shipped with the encoder (no training)
    raspv learn patient-data                # demonstrations for the learned virtual patient (expert in quick_trial)
    raspv learn patient-train [--ship]      # behaviour cloning → ONNX (raspv_experiments/models/learned_patient.onnx)

CONFIG is a YAML file or the name of a shipped one (``raspv_learn/configs/NAME.yaml``).
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

COMPARE_MODES = ("depth", "edges", "chess_floor", "wall_obstacles", "chess_wall_obstacles")
CEILING = "ground_truth_classes"      # a diagnostic row (--ceiling), not a mode: never the best hand-designed
MODELS_DIR = Path(__file__).resolve().parent / "models"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="learn", metavar="COMMAND", required=True)
    for name, text in (("dataset", "render the dataset of a configuration's data recipe from the shipped worlds"),
                       ("train", "train the encoder end to end through the twin; export it to ONNX"),
                       ("compare", "the computational observer: every hand-designed mode and the learned encoder "
                                   "scored on the held-out worlds")):
        p = sub.add_parser(name, help=text, description=text)
        p.add_argument("config", nargs="?" if name == "compare" else None,
                       help="training configuration: YAML file or shipped name (optimist, argus_iii)"
                            + ("; with --evaluation: one of its configurations (default: all)" if name == "compare"
                               else ""))
        p.add_argument("--data", help="dataset folder (default data/learn/<recipe key>)")
        p.add_argument("--quiet", action="store_true", help="no progress bars")
        p.add_argument("--evaluation", metavar="NAME",
                       help="a pre-registered evaluation (raspv_learn/evaluations/NAME.yaml): its test worlds, "
                            "frames and depth; train records its sha256; compare scores it (docs/learn.md)")
        if name in ("dataset", "compare"):
            p.add_argument("--depth", help="with --evaluation: the depth condition (default: the evaluation's "
                                           "primary one; compare scores every condition unless given)")
        if name == "train":
            p.add_argument("--seed", type=int, help="with --evaluation: the training seed (one of its seeds)")
        if name in ("train", "compare"):
            p.add_argument("--out", help="run folder (default runs/learn/<name>)")
        if name == "train":
            p.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint")
            p.add_argument("--ship", action="store_true",
                           help="copy the encoder, weights and scores into raspv_learn/models/ (what the learned "
                                "mode loads by default)")
        if name == "compare":
            p.add_argument("--rescore", action="store_true",
                           help="with --evaluation: score a test world against a model trained after that world "
                                "was scored with another model of the same configuration (the table says so)")
            p.add_argument("--modes", nargs="+", default=list(COMPARE_MODES), help="hand-designed modes to score")
            p.add_argument("--encoder", help="weights .pt of the learned encoder (default: --out's, else the "
                                             "shipped one)")
            p.add_argument("--no-learned", action="store_true", help="score the hand-designed modes only")
            p.add_argument("--shipped", action="store_true",
                           help="print the comparison shipped in raspv_learn/models/ (no data, no training)")
            p.add_argument("--ship", action="store_true",
                           help="copy the finished comparison into raspv_learn/models/<device>.compare.json")
            p.add_argument("--ceiling", action="store_true",
                           help=f"also score '{CEILING}': each phosphene shows the ground-truth walker class of its "
                                "ray (floor off, walls half, obstacles full) — what the phosphenes can carry, not a "
                                "mode")
            p.add_argument("--fresh", action="store_true",
                           help="score every row again (default: rows of --out/compare.json with the same "
                                "configuration, observer and encoder are kept: a killed comparison resumes)")


    p = sub.add_parser("patient-data", help="demonstrations for the learned virtual patient: an expert walks the "
                                            "shipped tasks in quick_trial (one process)")
    p.add_argument("--out", default="data/learn/patient", help="folder of episode shards (default data/learn/patient)")
    p.add_argument("--episodes", type=int, default=12, help="episodes per task (default 12)")
    p.add_argument("--seed", type=int, default=1)
    p = sub.add_parser("patient-train", help="train the learned virtual patient on demonstrations; export ONNX")
    p.add_argument("--data", default="data/learn/patient", help="demonstrations folder (default data/learn/patient)")
    p.add_argument("--out", default="runs/learn/patient", help="run folder (default runs/learn/patient)")
    p.add_argument("--epochs", type=int, default=30)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--ship", action="store_true", help="copy the model and its figures into raspv_experiments/models/")


def _data_dir(args, config) -> Path:
    return Path(args.data) if args.data else Path("data") / "learn" / config.data.key()


def _out_dir(args, config) -> Path:
    return Path(args.out) if args.out else Path("runs") / "learn" / config.name


def run(args: argparse.Namespace) -> int:
    from raspv_learn.config import ConfigError, load_config
    from raspv_learn.dataset import DataError

    if args.learn in ("patient-data", "patient-train"):
        return _patient(args)
    from raspv_learn.evaluation import EvaluationError

    try:
        if getattr(args, "evaluation", None):
            return _evaluation_command(args)
        if args.config is None:
            print("raspv learn: compare needs CONFIG (or --evaluation NAME)", file=sys.stderr)
            return 2
        if getattr(args, "seed", None) is not None or getattr(args, "depth", None) or getattr(args, "rescore", False):
            print("raspv learn: --seed, --depth and --rescore go with --evaluation NAME", file=sys.stderr)
            return 2
        config = load_config(args.config)
        return {"dataset": _dataset, "train": _train, "compare": _compare}[args.learn](args, config)
    except (ConfigError, DataError, EvaluationError) as exc:
        print(f"raspv learn: {exc}", file=sys.stderr)
        return 2


def _evaluation_command(args) -> int:
    """dataset / train / compare for a pre-registered evaluation."""
    from raspv_learn.config import load_config
    from raspv_learn.evaluation import configuration_for, load_evaluation, run_folder

    ev = load_evaluation(args.evaluation)
    if args.learn == "compare":
        from raspv_learn.scoring import compare_evaluation

        if args.data or args.out:
            print("raspv learn: compare --evaluation reads data/learn/<recipe key> and runs/learn/<evaluation>/ "
                  "(no --data or --out)", file=sys.stderr)
            return 2
        return compare_evaluation(args, ev)
    base = load_config(args.config)
    if args.learn == "dataset":
        config = configuration_for(base, ev, ev.shipped_seed, args.depth)
        return _dataset(args, config)
    if args.seed is None:
        print(f"raspv learn: --evaluation {ev.name} needs --seed (one of {list(ev.training_seeds)})", file=sys.stderr)
        return 2
    config = configuration_for(base, ev, args.seed)
    if not args.out:
        args.out = str(run_folder(ev, config.name, args.seed))
    return _train(args, config, evaluation=ev)


def _patient(args) -> int:
    from raspv_experiments.demonstrations import collect, default_recipe, load_demonstrations

    if args.learn == "patient-data":
        if args.episodes < 1:
            print(f"raspv learn: --episodes must be >= 1, got {args.episodes}", file=sys.stderr)
            return 2
        started = time.monotonic()
        figures = collect(default_recipe(args.episodes, args.seed), args.out)
        print(f"{figures['frames']} frames in {figures['episodes']} episodes ({figures['expert_successes']} reached "
              f"the goal) in {(time.monotonic() - started) / 60:.1f} min: {args.out}")
        return 0
    from raspv_learn.patient import PatientTraining, export_patient, train_patient

    try:
        data = load_demonstrations(args.data)
    except FileNotFoundError as exc:
        print(f"raspv learn: {exc}", file=sys.stderr)
        return 2
    recipe = json.loads((Path(args.data) / "recipe.json").read_text())
    net, figures = train_patient(data, PatientTraining(epochs=args.epochs, seed=args.seed))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    meta = {"spv": recipe["spv"], "tasks": [Path(t["world"]).stem for t in recipe["tasks"]],
            "episodes": figures["episodes"], "frames": figures["frames"], "epochs": args.epochs, "seed": args.seed}
    diff = export_patient(net, out / "learned_patient.onnx", meta)
    figures["onnx_max_difference"] = diff
    (out / "learned_patient.json").write_text(json.dumps({**meta, **figures}, indent=1))
    print(f"validation loss {figures['best_val_loss']:.4f} (always the mean command: "
          f"{figures['mean_command_val_loss']:.4f}); {out / 'learned_patient.onnx'}")
    if args.ship:
        from raspv_experiments.learned_policy import MODELS

        MODELS.mkdir(parents=True, exist_ok=True)
        shutil.copy(out / "learned_patient.onnx", MODELS / "learned_patient.onnx")
        shutil.copy(out / "learned_patient.json", MODELS / "learned_patient.json")
        print(f"shipped: {MODELS / 'learned_patient.onnx'}")
    return 0


def _dataset(args, config) -> int:
    from raspv_learn.dataset import render_dataset

    t0 = time.perf_counter()
    folder = render_dataset(config.data, _data_dir(args, config), progress=not args.quiet)
    print(f"dataset {folder}: {sum(config.data.frames_of(w) for w in (*config.data.train_worlds, *config.data.test_worlds))}"
          f" frames (train {', '.join(config.data.train_worlds)}; held out {', '.join(config.data.test_worlds)}), "
          f"{time.perf_counter() - t0:.0f} s")
    return 0


def _twin(config):
    from raspv_learn.twin import PhospheneTwin

    return PhospheneTwin.from_config(config.spv_config())


def _train(args, config, evaluation=None) -> int:
    import torch

    from raspv_learn.export import export_encoder
    from raspv_learn.prepare import prepare
    from raspv_learn.train import TrainError, train_end_to_end

    out = _out_dir(args, config)
    t0 = time.perf_counter()
    data = prepare(config, _data_dir(args, config), progress=not args.quiet)
    prep_s = time.perf_counter() - t0
    twin = _twin(config)
    try:
        model, result = train_end_to_end(config, data, twin, out, resume=args.resume, progress=not args.quiet,
                                         score_test=evaluation is None)
    except TrainError as exc:
        print(f"raspv learn: {exc}", file=sys.stderr)
        return 2
    from datetime import datetime, timezone

    trained_at = datetime.now(timezone.utc).isoformat(timespec="microseconds")
    record = {"evaluation": evaluation.record(), "seed": config.train.seed} if evaluation is not None else {}
    torch.save({"encoder": model.encoder.state_dict(), "decoder": model.decoder.state_dict(),
                "config": config.as_dict(), "config_key": config.key(), "trained_at": trained_at, **record},
               out / "weights.pt")
    diff = export_encoder(model.encoder, config, twin.num_levels, out / "encoder.onnx", data.test.inputs[0])
    summary = {"config": config.name, "config_key": config.key(), "recipe_key": config.data.key(),
               "phosphenes": data.count, "best_epoch": result.best_epoch, "val": result.val, "test": result.test,
               "train_minutes": result.seconds / 60.0, "train_cpu_minutes": result.cpu_seconds / 60.0,
               "prepare_minutes": prep_s / 60.0, "onnx_max_diff": diff,
               "threads": config.train.threads, "trained_at": trained_at, **record}
    (out / "result.json").write_text(json.dumps(summary, indent=1))
    print(f"{config.name}: {data.count} phosphenes, best epoch {result.best_epoch}/{config.train.epochs}; "
          + (f"held-out ({', '.join(config.data.test_worlds)}) obstacle IoU {result.test['iou_obstacle']:.3f}, "
             f"mIoU {result.test['miou']:.3f}" if result.test else
             f"validation mIoU {result.val['miou']:.3f}; {', '.join(config.data.test_worlds)} not scored (evaluation "
             f"{evaluation.name}: raspv learn compare --evaluation {evaluation.name})")
          + f"; training {result.seconds / 60:.1f} min wall, "
          f"{result.cpu_seconds / 60:.1f} min CPU on {config.train.threads} thread(s) "
          f"(+ {prep_s / 60:.1f} min preparing the data); {out / 'encoder.onnx'}")
    if args.ship:
        MODELS_DIR.mkdir(exist_ok=True)
        stem = Path(config.device).stem
        shutil.copyfile(out / "encoder.onnx", MODELS_DIR / f"{stem}.onnx")
        shutil.copyfile(out / "weights.pt", MODELS_DIR / f"{stem}.pt")
        (MODELS_DIR / f"{stem}.json").write_text(json.dumps(summary, indent=1))
        print(f"shipped as {MODELS_DIR / stem}.onnx/.pt/.json")
    return 0


def _compare(args, config) -> int:
    if args.shipped:
        path = MODELS_DIR / f"{Path(config.device).stem}.compare.json"
        if not path.exists():
            print(f"raspv learn: no comparison shipped for {config.device} ({path}); run raspv learn compare "
                  f"{config.name} --ship", file=sys.stderr)
            return 2
        record = json.loads(path.read_text())
        _report(config, record["phosphenes"], record["rows"])
        return 0
    return _compare_run(args, config)


def _compare_run(args, config) -> int:
    import hashlib

    import numpy as np
    import torch

    from raspv_learn.metrics import stimulation_cost
    from raspv_learn.prepare import prepare
    from raspv_learn.train import Pipeline, encoder_levels, ground_truth_levels, train_observer

    out = _out_dir(args, config)
    out.mkdir(parents=True, exist_ok=True)
    # the rows' scores depend on the data, device, targets and observer, not on how the encoder
    # was trained: a retrained encoder rescores its own row only
    run_key = config.observer_key()
    record = out / "compare.json"
    kept = {}
    if record.exists() and not args.fresh:
        previous = json.loads(record.read_text())
        kept = {r["row_key"]: r for r in previous.get("rows", []) if previous.get("run_key") == run_key}
    scored = [m for m in args.modes if m not in kept]                 # kept rows need no levels
    data = prepare(config, _data_dir(args, config), tuple(scored), progress=not args.quiet)
    twin = _twin(config)
    weights = Path(args.encoder) if args.encoder else out / "weights.pt"
    if not weights.exists() and not args.encoder:
        weights = MODELS_DIR / f"{Path(config.device).stem}.pt"
    candidates = {m: ({p: getattr(data, p).levels[m] for p in ("train", "val", "test")} if m in scored else None)
                  for m in args.modes}
    keys = {m: m for m in args.modes}
    if args.no_learned:
        pass
    elif weights.exists():
        state = torch.load(weights, weights_only=False)
        model = Pipeline(config, twin, data.grid, data.inside)
        model.encoder.load_state_dict(state["encoder"])
        candidates["learned"] = {p: encoder_levels(model, getattr(data, p)) for p in ("train", "val", "test")}
        keys["learned"] = "learned:" + hashlib.sha256(weights.read_bytes()).hexdigest()[:16]
    else:
        print(f"no learned encoder at {weights}: scoring the hand-designed modes only", file=sys.stderr)
    if args.ceiling:
        candidates[CEILING] = {p: ground_truth_levels(getattr(data, p), twin.num_levels) for p in ("train", "val", "test")}
        keys[CEILING] = CEILING
    d = config.spv_config().device
    rows = []
    for name, levels in candidates.items():
        row = kept.get(keys[name])
        if row is None:
            r = train_observer(levels, data, twin, config.target.stride_px, config.decoder.features, config.observer,
                               config.train.seed, config.train.threads, name, progress=not args.quiet)
            cost = stimulation_cost(levels["test"], data.inside, d.num_levels, d.pulse_amplitude_ua,
                                    d.pulse_phase_ms)
            row = {"mode": name, "row_key": keys[name], **r.test, **cost, "best_epoch": r.best_epoch,
                   "minutes": r.seconds / 60.0, "cpu_minutes": r.cpu_seconds / 60.0}
        rows.append(row)
        merged = {**kept, **{x["row_key"]: x for x in rows}}
        record.write_text(json.dumps({"config": config.name, "run_key": run_key, "phosphenes": data.count,
                                      "rows": list(merged.values())}, indent=1))
        print(f"  {name:22s} obstacle IoU {row['iou_obstacle']:.3f}  floor {row['iou_floor']:.3f}  "
              f"wall {row['iou_wall']:.3f}  mIoU {row['miou']:.3f}  on {100 * row['active_fraction']:.0f} %  "
              f"({row['minutes']:.1f} min)", flush=True)
    (out / "compare.md").write_text(_report(config, data.count, rows))
    if args.ship:
        shipped = MODELS_DIR / f"{Path(config.device).stem}.compare.json"
        shipped.write_text(json.dumps({"config": config.name, "run_key": run_key, "phosphenes": data.count,
                                       "test_worlds": list(config.data.test_worlds), "rows": rows}, indent=1))
        print(f"shipped as {shipped}")
    return 0 if np.isfinite([r["miou"] for r in rows]).all() else 1


def _report(config, count: int, rows: list[dict]) -> str:
    """Print (and return) the table, and the learned encoder's gain over the best hand-designed mode."""
    hand = [r for r in rows if r["mode"] not in ("learned", CEILING)]
    best = max(hand, key=lambda r: r["iou_obstacle"]) if hand else None
    table = _markdown(config, count, rows, best)
    learned = next((r for r in rows if r["mode"] == "learned"), None)
    if learned and best:
        gain = 100 * (learned["iou_obstacle"] - best["iou_obstacle"])
        table += (f"\nlearned vs best hand-designed ({best['mode']}): {gain:+.1f} points obstacle IoU "
                  f"(target +10: {'met' if gain >= 10 else 'MISSED'})\n")
    print(table)
    return table


def _markdown(config, count: int, rows: list[dict], best: dict | None) -> str:
    lines = [f"{config.device}, {count} phosphenes, held out: {', '.join(config.data.test_worlds)}", "",
             "| representation | obstacle IoU | floor IoU | wall IoU | mIoU | phosphenes on | charge/frame |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        mark = " (best hand-designed)" if best is not None and r is best else ""
        mark = " (ceiling: the true classes, not a mode)" if r["mode"] == CEILING else mark
        lines.append(f"| {r['mode']}{mark} | {r['iou_obstacle']:.3f} | {r['iou_floor']:.3f} | {r['iou_wall']:.3f} | "
                     f"{r['miou']:.3f} | {100 * r['active_fraction']:.0f} % | {r['charge_nc']:.0f} nC |")
    return "\n".join(lines) + "\n"
