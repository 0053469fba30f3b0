#!/usr/bin/env python
"""Figure of the no-data pattern: what the display shows while the camera is stale.

    .venv/bin/python tools/figures/no_data_ring.py          # → docs/figures/no_data_ring.png

The default preset's phosphene field at 400 px with the pattern in its "on" half period
(raspv_spv.no_data: every other phosphene of the border band at full level, blinking at 2 Hz),
drawn by the same renderer as the spv node (temporal model off: the levels as drawn).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from raspv_spv.config import spv_config  # noqa: E402
from raspv_spv.no_data import NoDataPattern  # noqa: E402
from raspv_spv.simulator import PhospheneSimulator  # noqa: E402


def no_data_image(width: int = 400):
    """(width, width) uint8: the default preset's field showing the no-data pattern (on)."""
    sim = PhospheneSimulator(spv_config("default", width=width, temporal=False))
    levels = NoDataPattern.for_simulator(sim).levels(0.0)
    return sim.render(sim.brightness(levels))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "figures"))
    args = parser.parse_args()
    path = Path(args.out) / "no_data_ring.png"
    if not cv2.imwrite(str(path), no_data_image()):
        sys.exit(f"no_data_ring: cannot write {path}")
    print(path)


if __name__ == "__main__":
    main()
