"""The twin: its agreement with the live renderer, and batched phosphene images per second on
CPU, ours vs dynaphos, same run.

Part 0 runs random levels through the live temporal model and renderer and through the twin
built from the same simulator (:mod:`raspv_learn.fidelity`), for every sprite model, and prints
the largest per-pixel difference as a fraction of the peak (target ≤ 1e-4). Part 1 times the twin (:mod:`raspv_learn.twin`) rendering batches of random stimulation —
forward only, and forward + backward (what training costs) — for the default preset at 256²
(the phosphenes of ``raspv bench spv``'s dynaphos part) and at dynaphos' published setting,
10,000 phosphenes at 256² (≥ 28.7 frames/s on an A30 GPU, van der Grinten et al. 2024), and
the temporal twin over a sequence. Part 2 runs dynaphos' ``GaussianSimulator`` (CPU torch,
its published parameters) batched, on the very same phosphene positions and image size.
Both on ``--threads`` torch threads (default 1). Module imports are light (``raspv bench``
builds every bench's arguments); torch is imported when it runs.
"""
from __future__ import annotations

import argparse
import os
import statistics
import time

from raspv_common.extras import require

PEER_MAX_GB = 1.0       # dynaphos holds N dense H×W maps (float32) and temporaries of their size


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--batch", type=int, default=32, help="frames per batch of the twin (default 32)")
    parser.add_argument("--repeats", type=int, default=10, help="timed batches per setting (default 10)")
    parser.add_argument("--peer-batch", type=int, default=4, help="frames per dynaphos batch (default 4)")
    parser.add_argument("--peer-repeats", type=int, default=2, help="timed dynaphos batches (default 2)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads for both (default 1)")
    parser.add_argument("--quick", action="store_true", help="tiny settings (the test suite runs this)")
    parser.add_argument("--no-peers", action="store_true", help="skip dynaphos")
    parser.add_argument("--no-fidelity", action="store_true", help="skip the comparison with the live renderer")
    parser.add_argument("--peer-max-gb", type=float, default=PEER_MAX_GB,
                        help=f"skip dynaphos where its N dense maps exceed this (default {PEER_MAX_GB:g} GB)")


def _median_s(fn, repeats: int) -> float:
    fn()                                                    # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def _settings(args) -> list[tuple[str, dict]]:
    if args.quick:
        return [("default preset, 64x64", {"width": 64, "num_phosphenes": 100})]
    return [("default preset, 256x256", {"width": 256}),
            ("10,000 requested, 256x256 (dynaphos' setting; whole-pixel hexagonal spacing gives more)",
             {"width": 256, "num_phosphenes": 10000})]


def part_fidelity(args) -> bool:
    from raspv_learn.fidelity import SPRITE_CASES, TOLERANCE, agreement

    cases = SPRITE_CASES[:1] + SPRITE_CASES[-1:] if args.quick else SPRITE_CASES
    frames = 3 if args.quick else 14
    print(f"Part 0 - the twin vs the live renderer and temporal model, {frames} frames of random levels each")
    ok = True
    for what, device, width, defects in cases:
        r = agreement(device, width, frames=frames, **defects)
        ok &= r.max_error <= TOLERANCE
        print(f"  {what:34s} {device:18s} {r.sim.count:5d} phosphenes {width}px: max |twin - live| "
              f"{r.max_error:.1e} of the peak; rounded: max {r.max_rounded_diff} grey level(s) on "
              f"{100 * r.rounded_share:.3f} % of pixels")
    print(f"  target <= {TOLERANCE:g} of the peak per pixel: {'met' if ok else 'MISSED'}")
    return ok


def part_twin(args) -> dict[str, float]:
    torch = require("torch", "raspv bench twin")

    from raspv_learn.temporal_twin import TemporalTwin
    from raspv_learn.twin import PhospheneTwin
    from raspv_spv.config import spv_config

    batch = 4 if args.quick else args.batch
    repeats = 2 if args.quick else args.repeats
    print(f"Part 1 - the twin, batches of {batch}, {torch.get_num_threads()} torch thread(s), CPU")
    fps = {}
    for name, kw in _settings(args):
        config = spv_config("default", temporal=True, **kw)
        twin = PhospheneTwin.from_config(config)
        b = torch.rand(batch, twin.count)
        with torch.no_grad():
            forward = _median_s(lambda: twin(b), repeats)
        x = b.clone().requires_grad_()
        backward = _median_s(lambda: twin(x).sum().backward(), repeats)
        fps[name] = batch / forward
        print(f"  {name}: {twin.count} phosphenes")
        print(f"    render forward           {batch / forward:10.0f} frames/s ({1e3 * forward / batch:.3f} ms/frame)")
        print(f"    render forward+backward  {batch / backward:10.0f} frames/s")
        if name == _settings(args)[0][0]:
            # the multilinear extension reads all 1024 table entries per phosphene and frame
            # (a (batch, N, 1024) temporary): timed at the first setting only
            temporal = TemporalTwin.from_config(config)
            seq = (torch.rand(batch, 10, twin.count) > 0.5).float()
            with torch.no_grad():
                recurrence = _median_s(lambda: temporal(seq), max(1, repeats // 2))
            print(f"    temporal recurrence      {10 * batch / recurrence:10.0f} frames/s (10-frame sequences; "
                  f"{10 * batch * twin.count / recurrence / 1e6:.2f} M phosphene-frames/s)")
    return fps


def part_dynaphos(args, ours: dict[str, float]) -> float | None:
    """Part 2, printed; the ratio at the first setting (twin forward frames/s ÷ dynaphos', the
    two timed in alternation), None without dynaphos."""
    import numpy as np

    from raspv_common.extras import MissingExtra
    try:
        torch = require("torch", "the dynaphos comparison")
        require("dynaphos", "the dynaphos comparison")
    except MissingExtra as exc:
        print(f"Part 2 - dynaphos not available: {exc}")
        return None
    from dynaphos.simulator import GaussianSimulator
    from dynaphos.utils import Map

    from raspv_bench.ratios import side_by_side
    from raspv_bench.spv import DYNAPHOS_PARAMS
    from raspv_learn.twin import PhospheneTwin
    from raspv_spv.config import spv_config
    from raspv_spv.phosphene_map import PhospheneMap

    batch = 2 if args.quick else args.peer_batch
    repeats = 1 if args.quick else args.peer_repeats
    print(f"Part 2 - dynaphos GaussianSimulator, batches of {batch}, same phosphenes and size, CPU torch")
    gated = None
    for i, (name, kw) in enumerate(_settings(args)):
        m = PhospheneMap.build(spv_config("default", **kw).map_spec())
        size = m.width
        gb = m.count * size * size * 4 / 1e9
        if gb > args.peer_max_gb:
            print(f"  {name}: skipped: dynaphos would hold {m.count} dense {size}x{size} maps ({gb:.1f} GB, "
                  f"more than --peer-max-gb {args.peer_max_gb:g}) on this shared machine")
            continue
        x = np.degrees(np.arctan((m.centres[:, 0] - size / 2) / m.focal_px))
        y = -np.degrees(np.arctan((m.centres[:, 1] - size / 2) / m.focal_px))
        params = {k: dict(v) for k, v in DYNAPHOS_PARAMS.items()}
        params["run"].update(resolution=[size, size], view_angle=20.0, batch_size=batch)
        rng = np.random.default_rng(0)
        try:
            sim = GaussianSimulator(params, Map(x=x, y=y), rng)
        except RuntimeError as exc:                      # its dense (N, H, W) maps may not fit in memory
            print(f"  {name}: dynaphos cannot build it ({str(exc).splitlines()[0][:120]})")
            continue
        amp = torch.tensor(rng.uniform(0.0, 100e-6, (batch, sim.num_phosphenes)), dtype=torch.float32)

        def step():
            sim.reset()
            sim(amp)

        with torch.no_grad():
            if i == 0:                                   # the gated ratio: the twin timed in alternation
                twin = PhospheneTwin.from_config(spv_config("default", temporal=True, **kw))
                ours_batch = 4 if args.quick else args.batch
                b = torch.rand(ours_batch, twin.count)
                r = side_by_side(lambda: twin(b), step, rounds=max(5, repeats), ours_calls=20)
                fps_ours, fps = ours_batch / r.ours_s, batch / r.peer_s
                gated = fps_ours / fps
            else:
                fps_ours, fps = ours[name], batch / _median_s(step, repeats)
        print(f"  {name}: {sim.num_phosphenes} phosphenes: {fps:10.2f} frames/s "
              f"({1e3 / fps:.0f} ms/frame); the twin is {fps_ours / fps:,.0f}x faster"
              f"{' (in alternation with it)' if i == 0 else ''}")
    return gated


def measure(args: argparse.Namespace) -> dict[str, float]:
    """The parts asked for, printed; the twin's ratio against dynaphos (``dynaphos``: times
    faster per frame, forward) when it runs."""
    torch = require("torch", "raspv bench twin")

    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, str(args.threads))
    torch.set_num_threads(max(1, args.threads))
    if not args.no_fidelity:
        part_fidelity(args)
    ours = part_twin(args)
    ratio = None if args.no_peers else part_dynaphos(args, ours)
    return {} if ratio is None else {"dynaphos": ratio}


def run(args: argparse.Namespace) -> int:
    from raspv_bench.ratios import report

    report(args, measure(args))
    return 0
