"""The experimenter's keys on a real session (graph, scripted subject): pause holds the world (the
simulation clock stops), repeat re-runs a trial, skip records it as skipped; bags are recorded per
trial when asked."""
from __future__ import annotations

import io
import threading
import time

import pytest
import yaml

from raspv_experiments.protocol import EXPERIMENTS_DIR, load_protocol
from raspv_experiments.session import read_jsonl
from raspv_experiments.session_runner import RunOptions, SessionRunner

pytestmark = [pytest.mark.integration, pytest.mark.slow]


class Recorder:
    def __init__(self) -> None:
        self.states: list[tuple[int, str]] = []
        self.lines = io.StringIO()

    def show(self, state) -> None:
        self.states.append((state.index, state.phase))

    def say(self, text: str) -> None:
        self.lines.write(text + "\n")


def wait_for(predicate, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise TimeoutError(what)
        time.sleep(0.05)


def test_pause_repeat_skip_and_bags(tmp_path, ros_domain):
    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "hallway.yaml").write_text((EXPERIMENTS_DIR / "worlds" / "hallway.yaml").read_text())
    doc = yaml.safe_load((EXPERIMENTS_DIR / "example.yaml").read_text())
    doc["design"].update(repetitions=1, order="fixed")
    doc["tasks"]["hallway"]["time_limit"] = 8
    doc["record"] = {"bag": True, "bag_topics": ["/odom", "/spv/frame"]}
    path = tmp_path / "keys.yaml"
    path.write_text(yaml.safe_dump(doc))
    view = Recorder()
    runner = SessionRunner(load_protocol(path), RunOptions(tmp_path / "out", "scripted-wander_avoid-1", "wander_avoid",
                                                           number=1, keys=False), view)
    result: list[int] = []
    thread = threading.Thread(target=lambda: result.append(runner.run()), daemon=True)
    thread.start()
    try:
        wait_for(lambda: (1, "running") in view.states, 180, "trial 1 did not start")
        runner.control.key("p")
        wait_for(lambda: view.states[-1][1] == "paused", 30, "no pause")
        t0, _, _ = runner.client.state()
        time.sleep(1.0)     # wall time passes while paused …
        t1, _, still = runner.client.state()
        assert t1 == t0 and still >= 0.9                              # … the simulation clock does not
        runner.control.key("p")
        wait_for(lambda: runner.client.state()[0] > t1, 30, "the clock did not resume")
        runner.control.key("r")                                        # repeat trial 1
        folder = runner.folder
        wait_for(lambda: len(read_jsonl(folder.trials_path)) >= 2, 120, "the repeated trial 1 did not end")
        wait_for(lambda: (2, "running") in view.states, 120, "trial 2 did not start")
        runner.control.key("s")                                        # skip trial 2
        thread.join(timeout=120)
    finally:
        runner.options.stop.set()
        thread.join(timeout=60)
        runner.close()
    assert result == [0]
    records = read_jsonl(runner.folder.trials_path)
    assert [(r["index"], r["status"], r["attempt"]) for r in records] == [
        (1, "repeated", 1), (1, "completed", 2), (2, "skipped", 1)]
    assert "metrics" in records[1] and "metrics" not in records[0]
    events = [e["event"] for e in read_jsonl(runner.folder.events_path)]
    assert events == ["started", "repeated", "skipped", "finished"]
    bag = runner.folder.root / "trials" / "001-depth-hallway-r1-a2" / "bag"
    assert bag.is_dir() and any(bag.iterdir()), "a bag per trial"
    for log in sorted((runner.folder.root / "trials").glob("*/bag.log")):     # each recorder stopped by its SIGINT,
        assert " messages over " in log.read_text(), log.read_text()[-2000:]     # its summary printed (not killed)
    assert records[1]["bag"] == str(bag)
