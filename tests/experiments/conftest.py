"""Shared helpers of the experiment tests: the documented example protocol, and writing variants of it."""
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
