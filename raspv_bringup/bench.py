"""`raspv bench <name>`: benchmarks that print figures and ratios against peers.

Each entry is a module exposing ``add_arguments(parser)`` and ``run(args) -> int``, and a quick
mode (``--quick``: a smoke run in seconds that the test suite runs, its figures printed, not the
README's): its own ``--quick`` option, or a ``QUICK`` mapping of option → value that this
dispatcher applies.
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
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="bench", metavar="NAME", required=True)
    for name, module in sorted(BENCHES.items()):
        mod = importlib.import_module(module)
        p = sub.add_parser(name, help=(mod.__doc__ or "").strip().splitlines()[0] if mod.__doc__ else None)
        mod.add_arguments(p)
        quick = getattr(mod, "QUICK", None)
        if quick is not None:
            settings = ", ".join(f"--{k.replace('_', '-')} {v}" if not isinstance(v, bool) else f"--{k.replace('_', '-')}"
                                 for k, v in quick.items())
            p.add_argument("--quick", action="store_true", help=f"a smoke run in seconds (the test suite's): {settings}")
        p.set_defaults(_bench_module=mod)


def run(args: argparse.Namespace) -> int:
    mod = args._bench_module
    if getattr(args, "quick", False) and getattr(mod, "QUICK", None) is not None:
        for key, value in mod.QUICK.items():
            setattr(args, key, value)
        print(f"raspv bench {args.bench} --quick: a smoke run (small sizes, short times); not the README's figures")
    return mod.run(args)
