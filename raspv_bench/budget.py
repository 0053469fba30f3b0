"""Display budget: the cost model's predicted display frame time against the measured one.

Measures this machine's :class:`~raspv_spv.display_budget.DisplayCost`, then for a range of
configurations (presets, 5 000–21 000 phosphenes, large phosphenes, green output) times the
display loop's own work — levels → brightness with the temporal model, the sprite render, the
image and frame arrays copied into messages — and prints the prediction beside it, with the
verdict the spv node would give at 50 Hz and the phosphene limit. The fastest frame in CPU time
of the measuring thread compares with the prediction; the wall-clock median shows what the
load of other processes adds.
"""
from __future__ import annotations

import argparse
import array
import statistics
import time

import numpy as np

CASES = [
    dict(device="default"), dict(device="optimist"), dict(device="alpha_ims"), dict(device="argus_ii"),
    dict(device="default", num_phosphenes=5000), dict(device="default", num_phosphenes=10000),
    dict(device="default", num_phosphenes=20000), dict(device="default", num_phosphenes=5000, output_format="green"),
    dict(device="optimist", phosphene_fov_deg=3.0), dict(device="default", width=400, num_phosphenes=3000),
]


# --quick (raspv_bench.bench_cli): a smoke run in seconds, run by tests/bench
QUICK = {"frames": 5}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", type=int, default=40, help="display frames timed per configuration (default 40)")


def _frame_work(sim, levels: np.ndarray) -> None:
    b = sim.brightness(levels, 1)
    image = sim.render(b)
    bytes(array.array("B", image.tobytes()))
    array.array("B", levels.tobytes())
    array.array("f", b.astype(np.float32).tobytes())


def measure(args: argparse.Namespace) -> dict[str, float]:
    """Every configuration, printed; ``predicted_vs_measured``: the median over configurations
    of the prediction from the bare operations (the peer, timed in the same run) ÷ the measured
    frame work — how close the display loop stays to what its operations cost alone."""
    from raspv_spv.config import spv_config
    from raspv_spv.display_budget import DisplayCost, check_display_rate, load_of_config
    from raspv_spv.simulator import PhospheneSimulator

    t0 = time.perf_counter()
    cost = DisplayCost.measure()
    print(f"raspv bench budget: measured in {1e3 * (time.perf_counter() - t0):.0f} ms: "
          f"{cost.per_sprite_pixel_ns:.2f} ns per sprite pixel, {cost.per_phosphene_ns:.2f} ns per phosphene, "
          f"{cost.per_image_byte_ns:.3f} ns per image byte, {cost.fixed_us:.0f} us fixed")
    print(f"  {'configuration':<46} {'N':>6} {'sprite px':>9} {'predicted':>9} {'CPU min':>9} {'wall p50':>9} "
          f"{'CPU/pred':>8}  verdict at 50 Hz")
    rng = np.random.default_rng(0)
    ratios = []
    for case in CASES:
        config = spv_config(temporal=True, **case)
        load = load_of_config(config)
        verdict = check_display_rate(load, cost)
        sim = PhospheneSimulator(config)
        levels = rng.integers(0, config.device.num_levels, sim.count).astype(np.uint8)
        times, cpu = [], []
        for _ in range(args.frames):
            t, c = time.perf_counter(), time.thread_time()
            _frame_work(sim, levels)
            cpu.append(1e3 * (time.thread_time() - c))
            times.append(1e3 * (time.perf_counter() - t))
        measured = min(cpu)
        ratios.append(measured / verdict.frame_ms)
        label = ", ".join(f"{k}={v}" for k, v in case.items())
        state = "refused" if verdict.refuse else "warning" if verdict.warn else "ok"
        print(f"  {label:<46} {load.phosphenes:>6} {load.sprite_pixels / 1e6:>8.2f}M {verdict.frame_ms:>7.2f}ms "
              f"{measured:>7.2f}ms {statistics.median(times):>7.2f}ms {measured / verdict.frame_ms:>8.2f}  {state} "
              f"(limit ~{verdict.max_phosphenes})")
    print(f"  CPU min / predicted: median {statistics.median(ratios):.2f}, range {min(ratios):.2f}-{max(ratios):.2f}; "
          "wall p50 above it is other processes' load (the model is this machine's cost when the display thread runs; "
          "the node adds the overhead it measures on its own display loop)")
    return {"predicted_vs_measured": statistics.median(1 / r for r in ratios)}


def run(args: argparse.Namespace) -> int:
    from raspv_bench.ratios import report

    report(args, measure(args))
    return 0
