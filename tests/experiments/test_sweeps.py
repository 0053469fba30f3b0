"""Sweeps of scripted subjects: worker processes on this machine (each graph on its own ROS domain) and
the same sweep file on a local Ray instance; then the report on the sweep's sessions. The worker-process
sweep is the first of the two runs tests/experiments/test_exact_repetition.py compares (the session
fixture ``repeated_sweep``): one sweep run, checked by both."""
from __future__ import annotations

import pytest
import yaml

from raspv_experiments.protocol import EXPERIMENTS_DIR
from raspv_experiments.report import build_report
from raspv_experiments.session import read_jsonl
from raspv_experiments.sweep import _store, load_sweep, run_sweep
from raspv_bringup.testing import dev_requirement
from raspv_common.ros_domains import HIGH, LOW

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def short_sweep(tmp_path, subjects: int = 2, policy: str = "wander_avoid", repetitions: int = 1,
                name: str = "short_sweep"):
    """The example protocol with 5 s trials, swept over two modes."""
    (tmp_path / "worlds").mkdir(exist_ok=True)
    (tmp_path / "worlds" / "hallway.yaml").write_text((EXPERIMENTS_DIR / "worlds" / "hallway.yaml").read_text())
    doc = yaml.safe_load((EXPERIMENTS_DIR / "example.yaml").read_text())
    doc["tasks"]["hallway"]["time_limit"] = 5
    (tmp_path / "short.yaml").write_text(yaml.safe_dump(doc))
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump({
        "name": name, "protocol": "short.yaml", "policy": policy, "subjects": subjects,
        "factors": {"spv.mode": ["depth", "grey"]}, "repetitions": repetitions}))
    return load_sweep(tmp_path / "sweep.yaml")


def check_sessions(results, out, subjects, ros_domain, policy: str = "wander_avoid", repetitions: int = 1,
                   name: str = "short_sweep"):
    assert sorted(r["subject"] for r in results) == [f"scripted-{policy}-{n}" for n in range(1, subjects + 1)]
    assert all(r["code"] == 0 for r in results), [r["log"] for r in results]
    domains = [r["domain"] for r in results]
    assert len(set(domains)) == len(domains), domains                  # each graph on a domain of its own,
    assert all(LOW <= d < HIGH and d != ros_domain for d in domains), domains   # claimed, not the test's
    for r in results:
        records = read_jsonl(out / "sessions" / name / r["subject"] / "trials.jsonl")
        assert [x["condition"] for x in records] and {x["status"] for x in records} == {"completed"}
        assert sorted(x["condition"] for x in records) == sorted(["mode=depth", "mode=grey"] * repetitions)
        assert all(0 < x["metrics"]["duration_s"] <= 5.2 for x in records)


def test_sweep_on_worker_processes(repeated_sweep, tmp_path, ros_domain):
    """2 virtual subjects (navigate) × 2 modes × 2 repetitions on 2 worker processes."""
    _, out, results = repeated_sweep
    check_sessions(results, out, 2, ros_domain, policy="navigate", repetitions=2, name="repeat")
    page = build_report([out], tmp_path / "report").read_text()
    assert "8 trial records" in page and "mode=depth" in page


def test_the_same_sweep_on_a_local_ray_instance(tmp_path, ros_domain):
    ray = dev_requirement("ray")
    sweep = short_sweep(tmp_path, subjects=1)
    out = tmp_path / "out"
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    try:
        results = run_sweep(sweep, out, ray_address="local", say=lambda s: None)
    finally:
        ray.shutdown()
    check_sessions(results, out, 1, ros_domain)
    # a cluster without a shared disk: the node wrote the session on its own disk; the driver
    # stores it from the records the Ray task returned (through Ray's object store)
    driver = tmp_path / "driver_disk"
    for r in results:
        _store(r, driver)
    node_session = out / "sessions" / "short_sweep" / results[0]["subject"]
    stored = driver / "sessions" / "short_sweep" / results[0]["subject"]
    assert read_jsonl(stored / "trials.jsonl") == read_jsonl(node_session / "trials.jsonl")
    assert (stored / "session.json").read_text() == (node_session / "session.json").read_text()
    assert "2 trial records" in build_report([driver], tmp_path / "driver_report").read_text()
