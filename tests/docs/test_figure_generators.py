"""Every figure in docs/figures has the script that draws it (tools/figures/), and the no-data
ring's script draws the shipped image."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[2]
FIGURES = REPO / "docs" / "figures"
TOOLS = REPO / "tools" / "figures"


def test_every_figure_is_named_by_its_generator():
    scripts = "\n".join(p.read_text() for p in TOOLS.glob("*.py"))
    orphans = [p.name for p in sorted(FIGURES.glob("*.png")) if p.stem not in scripts]
    assert not orphans, f"figures without a script in tools/figures/: {orphans}"


def test_the_no_data_ring_figure_is_what_its_script_draws():
    spec = importlib.util.spec_from_file_location("no_data_ring_figure", TOOLS / "no_data_ring.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    drawn = module.no_data_image()
    shipped = cv2.imread(str(FIGURES / "no_data_ring.png"), cv2.IMREAD_GRAYSCALE)
    assert drawn.shape == shipped.shape and drawn.dtype == np.uint8
    assert np.abs(drawn.astype(int) - shipped).max() <= 1
