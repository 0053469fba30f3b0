"""A quick sweep seeds every subject's trials as a session of that subject does: each trial with
the seed of its position in the session's plan (the Latin-square order of the conditions, the
practice trials counted), so a graph sweep and a quick sweep of the same seeds walk the same
trials for every subject, not only for those whose order is the sweep's."""
from __future__ import annotations

import yaml

from raspv_experiments import quick_trial as quick_trial_module
from raspv_experiments.design import plan_session, scripted_subject_id, trial_seed
from raspv_experiments.protocol import EXPERIMENTS_DIR
from raspv_experiments.quick_sweep import run_quick_sweep
from raspv_experiments.sweep import load_sweep


def test_every_subjects_conditions_get_the_seeds_of_its_session_plan(tmp_path, monkeypatch):
    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "hallway.yaml").write_text((EXPERIMENTS_DIR / "worlds" / "hallway.yaml").read_text())
    doc = yaml.safe_load((EXPERIMENTS_DIR / "example.yaml").read_text())
    doc["design"].update(practice=1, order="latin_square", blocks="condition")
    (tmp_path / "short.yaml").write_text(yaml.safe_dump(doc))
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump({
        "name": "order", "protocol": "short.yaml", "policy": "navigate", "subjects": [1, 2, 3, 4],
        "factors": {"spv.num_phosphenes": [16, 36, 64]}, "repetitions": 2, "time_limit": 0.3}))
    sweep = load_sweep(tmp_path / "sweep.yaml")

    seeds = []                                   # the seed each trial's subject was given, in run order
    real = quick_trial_module.quick_trial

    def seeded(*args, config, **kw):
        seeds.append(config.seed)
        return real(*args, config=config, **kw)
    monkeypatch.setattr(quick_trial_module, "quick_trial", seeded)
    records = run_quick_sweep(sweep, progress=None)
    assert len(records) == len(seeds) == 4 * 3 * 2

    orders = set()
    for n in sweep.subjects:
        plan = plan_session(sweep.protocol, scripted_subject_id(sweep.policy, n))
        planned = sorted((t.condition, t.repetition, trial_seed(n, t.index)) for t in plan if not t.practice)
        quick = sorted((r.condition, r.repetition, s) for r, s in zip(records, seeds) if r.subject == n)
        assert quick == planned, f"subject {n}"
        orders.add(tuple(dict.fromkeys(t.condition for t in plan)))
    assert len(orders) == 4                      # four subjects, four different condition orders
