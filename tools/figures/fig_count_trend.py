#!/usr/bin/env python
"""Figure of the obstacle-course sweep: success, time and collisions against the phosphene count.

    .venv/bin/python tools/figures/fig_count_trend.py       # → docs/figures/fig_count_trend.png

From the shipped rows (experiments/results/obstacle_course_sweep.quick.csv, written by
``raspv experiment quick-sweep obstacle_course_sweep``): means over the virtual patients with
percentile-bootstrap 95 % CIs over subjects, as ``quick-sweep --figure`` draws them.
"""
from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from raspv_experiments.protocol import EXPERIMENTS_DIR  # noqa: E402
from raspv_experiments.quick_sweep import read_quick_csv, summarise  # noqa: E402
from raspv_experiments.report_figures import level_summaries  # noqa: E402
from raspv_experiments.sweep import load_sweep  # noqa: E402

ROWS = EXPERIMENTS_DIR / "results" / "obstacle_course_sweep.quick.csv"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "figures"))
    args = parser.parse_args()
    sweep = load_sweep(EXPERIMENTS_DIR / "obstacle_course_sweep.yaml")
    factor = next(iter(sweep.protocol.factors))
    summaries = summarise(read_quick_csv([ROWS]), {t.name: t.time_limit for t in sweep.protocol.tasks}, factor,
                          [str(v) for v in sweep.protocol.factors[factor]])
    with tempfile.TemporaryDirectory() as tmp:
        png = level_summaries(summaries, "phosphenes", Path(tmp), name="fig_count_trend")
        shutil.copy(Path(tmp) / Path(png).name, Path(args.out) / "fig_count_trend.png")
    print(Path(args.out) / "fig_count_trend.png")


if __name__ == "__main__":
    main()
