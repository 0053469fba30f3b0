"""`raspv bench <name>`: benchmarks that print figures and ratios against peers.

Each entry is a module exposing ``add_arguments(parser)`` and ``run(args) -> int``, and a quick
mode (``--quick``: a smoke run in seconds that the test suite runs, its figures printed, not the
speed page's): its own ``--quick`` option, or a ``QUICK`` mapping of option → value that this
dispatcher applies.
"""
from __future__ import annotations

import argparse
import importlib

BENCHES: dict[str, str] = {
    "sim": "raspv_bench.sim",
    "scene": "raspv_bench.scene",
    "spv": "raspv_bench.spv",
    "bag": "raspv_bench.bag",
    "camera": "raspv_bench.camera",
    "hmd": "raspv_bench.hmd",
    "e2e": "raspv_bench.e2e",
    "qoe": "raspv_bench.qoe",
    "seg": "raspv_bench.segmentation",
    "nav": "raspv_bench.nav",
    "restart": "raspv_bench.restart",
    "spv-kills": "raspv_bench.spv_kills",
    "budget": "raspv_bench.budget",
    "soak": "raspv_bench.soak",
    "foxglove": "raspv_bench.foxglove",
    "twin": "raspv_bench.twin",
    "learned": "raspv_bench.learned",
    "ratios": "raspv_bench.ratios",
    "slam": "raspv_bench.slam",
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
        if hasattr(mod, "measure"):
            p.add_argument("--ratios", metavar="FILE",
                           help="also write the ratios against the peers run side by side as JSON to FILE")
        p.set_defaults(_bench_module=mod)


def run(args: argparse.Namespace) -> int:
    mod = args._bench_module
    if getattr(args, "quick", False) and getattr(mod, "QUICK", None) is not None:
        for key, value in mod.QUICK.items():
            setattr(args, key, value)
        print(f"raspv bench {args.bench} --quick: a smoke run (small sizes, short times); not the speed page's figures")
    return mod.run(args)
