"""Shared helpers of the experiment tests: the documented example protocol, writing variants of it, and
one sweep run on worker processes that two test files check (``repeated_sweep``)."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "experiments" / "example.yaml"


@pytest.fixture
def example_doc() -> dict:
    return yaml.safe_load(EXAMPLE.read_text())


@pytest.fixture
def write_protocol(tmp_path):
    """Write a protocol dict next to a copy of the example's world; returns its path."""
    (tmp_path / "worlds").mkdir(exist_ok=True)
    (tmp_path / "worlds" / "hallway.yaml").write_text((REPO / "experiments" / "worlds" / "hallway.yaml").read_text())

    def write(doc: dict | str, name: str = "protocol.yaml") -> Path:
        path = tmp_path / name
        path.write_text(doc if isinstance(doc, str) else yaml.safe_dump(doc, sort_keys=False))
        return path
    return write


@pytest.fixture(scope="session")
def repeated_sweep(tmp_path_factory, ros_domain):
    """The example protocol with 5 s trials swept by 2 virtual subjects (navigate) over 2 modes × 2
    repetitions on 2 worker processes, run once per session: tests/experiments/test_sweeps.py checks
    the sessions and the report, tests/experiments/test_exact_repetition.py runs it again and compares.
    Returns (sweep, out, results)."""
    from raspv_experiments.sweep import run_sweep
    from tests.experiments.test_sweeps import short_sweep

    root = tmp_path_factory.mktemp("repeated_sweep")
    sweep = short_sweep(root, policy="navigate", repetitions=2, name="repeat")
    out = root / "run1"
    return sweep, out, run_sweep(sweep, out, workers=2, say=print)
