"""`raspv bench <name>`: benchmarks that print figures and ratios against peers.

Each entry is a module exposing ``add_arguments(parser)`` and ``run(args) -> int``.
"""
from __future__ import annotations

import argparse
import importlib

BENCHES: dict[str, str] = {
    "sim": "raspv_sim.bench",
    "scene": "raspv_perception.bench",
    "spv": "raspv_spv.bench",
    "bag": "raspv_bags.bench",
    "camera": "raspv_camera.bench",
    "hmd": "raspv_hmd.bench",
    "e2e": "raspv_hmd.e2e_bench",
    "qoe": "raspv_hmd.qoe_bench",
    "seg": "raspv_perception.segmentation_bench",
    "nav": "raspv_nav.bench",
    "restart": "raspv_bringup.restart_bench",
    "budget": "raspv_spv.budget_bench",
    "soak": "raspv_bringup.soak_bench",
    "foxglove": "raspv_viz.bench",
    "twin": "raspv_learn.bench_twin",
    "learned": "raspv_learn.bench_learned",
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="bench", metavar="NAME", required=True)
    for name, module in sorted(BENCHES.items()):
        mod = importlib.import_module(module)
        p = sub.add_parser(name, help=(mod.__doc__ or "").strip().splitlines()[0] if mod.__doc__ else None)
        mod.add_arguments(p)
        p.set_defaults(_bench_module=mod)


def run(args: argparse.Namespace) -> int:
    return args._bench_module.run(args)
