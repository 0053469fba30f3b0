"""The check of issue 15, as a new user would do it: write a 2-condition × 3-repetition protocol from
the documented example, run it to the end with a scripted subject, run a second subject (at the same
time, on another ROS domain) and kill the runner in the middle of a trial, resume it, make the report
and open it in a browser.

Real processes throughout: ``raspv experiment run`` (its graph: sim in lockstep, headless spv,
the scripted subject node) and ``raspv experiment report``; the report is opened in Debian's
chromium with Playwright.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time

import psutil
import pytest
import yaml

from raspv_experiments.protocol import EXPERIMENTS_DIR
from raspv_experiments.session import read_jsonl
from raspv_bringup.testing import CHROMIUM, dev_requirement
from raspv_common.ros_domains import lock_free_domain
from raspv_bringup.testing import CHROMIUM_ARGS as ARGS

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def raspv(*args: str, **kw) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "raspv_bringup.cli", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True, **kw)


def finish(proc: subprocess.Popen, timeout: float) -> str:
    try:
        out, _ = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, _ = proc.communicate()
        pytest.fail(f"{proc.args} did not finish within {timeout:.0f} s:\n{out[-3000:]}")
    assert proc.returncode == 0, out[-3000:]
    return out


def wait_for(predicate, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise TimeoutError(f"{what} within {timeout:.0f} s")
        time.sleep(0.1)


@pytest.fixture(scope="module")
def study(tmp_path_factory, ros_domain):
    root = tmp_path_factory.mktemp("study")
    (root / "worlds").mkdir()
    (root / "worlds" / "hallway.yaml").write_text((EXPERIMENTS_DIR / "worlds" / "hallway.yaml").read_text())
    doc = yaml.safe_load((EXPERIMENTS_DIR / "example.yaml").read_text())     # the documented example …
    doc["name"] = "my_study"                                                 # … edited by a new user
    doc["conditions"] = {"depth": {"spv": {"mode": "depth"}}, "depth_edges": {"spv": {"mode": "edges_depth"}}}
    doc["design"]["repetitions"] = 3
    doc["tasks"]["hallway"]["time_limit"] = 6                                # short trials
    protocol = root / "my_study.yaml"
    protocol.write_text(yaml.safe_dump(doc, sort_keys=False))
    out = root / "sessions"
    check = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "experiment", "check", str(protocol)],
                           capture_output=True, text=True, timeout=60)
    assert check.returncode == 0 and "2 conditions × 1 tasks × 3 repetitions" in check.stdout, check.stderr

    # subject 1 runs to the end, meanwhile (its graph on a ROS domain of its own, as a sweep's workers) …
    domain1, domain1_lock = lock_free_domain()
    log1_path = root / "subject1.log"                  # a file, not a pipe nobody reads while subject 2 runs
    with open(log1_path, "w") as log1_file:
        run1 = subprocess.Popen([sys.executable, "-m", "raspv_bringup.cli", "experiment", "run", str(protocol),
                                 "--subject", "scripted:wander_avoid:1", "--out", str(out)], stdout=log1_file,
                                stderr=subprocess.STDOUT, text=True, start_new_session=True,
                                env={**os.environ, "ROS_DOMAIN_ID": str(domain1)})
    try:
        # … subject 2 is killed in the middle of its third trial …
        s2 = out / "my_study" / "scripted-wander_avoid-2"
        run2 = raspv("experiment", "run", str(protocol), "--subject", "scripted:wander_avoid:2", "--out", str(out))
        try:
            third = lambda: [p for p in (s2 / "trials").glob("003-*-a1") if (p / "trajectory.csv").exists()  # noqa: E731
                             and len((p / "trajectory.csv").read_text().splitlines()) > 5]
            wait_for(lambda: len(read_jsonl(s2 / "trials.jsonl")) >= 2 and third(), 180, "the third trial did not start")
            nodes = psutil.Process(run2.pid).children(recursive=True)
            assert len(nodes) >= 3, "the runner should have its graph's node processes"
            os.kill(run2.pid, signal.SIGKILL)
            run2.wait(timeout=30)
            killed_records = read_jsonl(s2 / "trials.jsonl")
            wait_for(lambda: not any(p.is_running() and p.status() != psutil.STATUS_ZOMBIE for p in nodes), 30,
                     "the graph's nodes did not die with the killed runner")
        finally:
            if run2.poll() is None:
                os.killpg(run2.pid, signal.SIGKILL)
            run2.stdout.close()
        # … and resumed
        log2 = finish(raspv("experiment", "run", str(protocol), "--subject", "scripted:wander_avoid:2", "--out",
                            str(out), "--resume"), timeout=240)
        try:
            run1.wait(timeout=240)
        except subprocess.TimeoutExpired:
            pytest.fail(f"subject 1's run did not finish within 240 s:\n{log1_path.read_text()[-3000:]}")
        log1 = log1_path.read_text()
        assert run1.returncode == 0, log1[-3000:]
    finally:
        if run1.poll() is None:
            os.killpg(run1.pid, signal.SIGKILL)
            run1.wait()
        domain1_lock.close()
    report_log = finish(raspv("experiment", "report", str(out), "-o", str(root / "report")), timeout=120)
    return {"root": root, "out": out, "s2": s2, "killed_records": killed_records, "logs": (log1, log2, report_log),
            "report": root / "report" / "report.html"}


def test_sessions_run_to_the_end_and_resume_after_a_kill(study):
    out, s2 = study["out"], study["s2"]
    s1 = out / "my_study" / "scripted-wander_avoid-1"
    r1, r2 = read_jsonl(s1 / "trials.jsonl"), read_jsonl(s2 / "trials.jsonl")
    assert [r["index"] for r in r1] == [1, 2, 3, 4, 5, 6] and {r["status"] for r in r1} == {"completed"}
    # subjects 1 and 2 get the two counterbalanced orders of the Latin square
    assert [r["condition"] for r in r1] == ["depth"] * 3 + ["depth_edges"] * 3
    assert [r["condition"] for r in r2] == ["depth_edges"] * 3 + ["depth"] * 3
    # nothing recorded before the kill was lost; the cut trial ran again as attempt 2
    killed = study["killed_records"]
    assert len(killed) == 2 and r2[:2] == killed
    assert [r["index"] for r in r2] == [1, 2, 3, 4, 5, 6]
    assert r2[2]["attempt"] == 2 and (s2 / "trials" / "003-depth_edges-hallway-r3-a1").is_dir()
    events = [e["event"] for e in read_jsonl(s2 / "events.jsonl")]
    assert events == ["started", "resumed", "finished"]
    assert "resuming" in study["logs"][1] and "2 of 6 trials done, next: trial 3" in study["logs"][1]
    for r in r1 + r2:
        m = r["metrics"]
        assert m["outcome"] in ("goal", "time_limit", "aborted") and 0 < m["duration_s"] <= 6.0
        assert m["path_length_m"] >= 0 and m["samples"] >= 2 and len(r["trajectory"]["x"]) == m["samples"]
        assert r["params"] == {"spv": {"mode": r["params"]["spv"]["mode"]}}
        assert r["trajectory"]["x"][0] == pytest.approx(1.0, abs=0.05)       # every trial starts at the start
        assert m["shortest_path_m"] == pytest.approx(6.8, abs=0.2)
    info = json.loads((s2 / "session.json").read_text())
    assert info["subject"] == "scripted-wander_avoid-2" and info["software"]["raspv"]
    assert (s2 / "protocol.yaml").read_text() == (study["root"] / "my_study.yaml").read_text()


def test_the_report_lists_every_trial_once(study):
    rows = (study["report"].parent / "trials.csv").read_text().splitlines()
    assert len(rows) == 1 + 12                                      # header and 12 trials (the cut attempt left no record)


def test_report_opens_in_a_browser(study):
    if not os.path.exists(CHROMIUM):
        pytest.skip(f"{CHROMIUM} is not installed (Debian: apt-get install -y chromium)")
    sync_api = dev_requirement("playwright.sync_api")
    report = study["report"]
    with sync_api.sync_playwright() as p, tempfile.TemporaryDirectory(prefix="raspv-chromium-") as profile:
        ctx = p.chromium.launch_persistent_context(profile, executable_path=CHROMIUM, args=ARGS, headless=True,
                                                   viewport={"width": 1200, "height": 900})
        try:
            page = ctx.new_page()
            page.goto(report.as_uri())
            page.wait_for_function("[...document.images].every(i => i.complete)", timeout=30_000)
            images = page.evaluate("[...document.images].map(i => [i.getAttribute('src'), i.naturalWidth])")
            assert len(images) == 7 and all(w > 200 for _, w in images), images      # + Kaplan–Meier
            assert "figures/trajectories-hallway.png" in [src for src, _ in images]
            text = page.inner_text("body")
            assert "12 trial records" in text and "depth_edges" in text and "Wilcoxon" in text
            assert page.locator("table.summary tr").count() == 3
            page.screenshot(path=str(report.parent / "report.png"), full_page=True)
        finally:
            ctx.close()
