"""The ``learned`` mode's cost per frame in the live simulator, one core, beside hand-designed modes.

Frames: the held-out office rendered with the simulator core and scene perception (what the sim
and scene nodes publish), as ``raspv learn dataset`` renders them. Per camera frame the spv
node runs the mode (encoder inputs, the ONNX network on one onnxruntime thread, bilinear
sampling, levels), the temporal model and the renderer — :meth:`PhospheneSimulator.step` on a
new frame each time, so nothing is cached. Per display tick while the head turns it re-samples
the frame with turned rays (the network's output is cached per frame). Target: ≤ 5 ms per
camera frame. Beside the wall time, the thread's CPU time per frame (everything runs on the
calling thread: onnxruntime and OpenCV with one thread) — what a frame costs whatever else the
machine runs. Modules import lightly; onnxruntime is loaded when it runs.
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import time

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

TARGET_MS = 5.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--device", default="optimist", help="device preset (default optimist)")
    parser.add_argument("--model", default="", help="encoder ONNX (default: the shipped one for the device)")
    parser.add_argument("--size", type=int, default=800, help="phosphene image width [px] (default 800, the node's)")
    parser.add_argument("--frames", type=int, default=8, help="office frames rendered (default 8)")
    parser.add_argument("--repeats", type=int, default=300, help="timed steps per mode (default 300)")
    parser.add_argument("--modes", nargs="+", default=["learned", "depth", "chess_wall_obstacles"],
                        help="modes timed (default: learned, depth, chess_wall_obstacles)")
    parser.add_argument("--quick", action="store_true", help="few frames and steps (the test suite runs this)")


def office_frames(count: int, seed: int = 0):
    """(FrameInputs list, camera) of ``count`` office views with scene perception."""
    import numpy as np

    from raspv_learn.dataset import DataRecipe, WorldFrames, WorldRenderer
    from raspv_spv.frame_inputs import FrameInputs

    recipe = DataRecipe(train_worlds=("apartment",), test_worlds=("office",))
    renderer = WorldRenderer("office", recipe)
    try:
        rng = np.random.default_rng(seed)
        frames = [renderer.frame(rng) for _ in range(count)]
    finally:
        renderer.close()
    stacked = WorldFrames("office", {k: np.stack([f[k] for f in frames]) for k in frames[0]})
    camera = recipe.camera
    a = stacked.arrays

    def inputs(i: int) -> FrameInputs:
        return FrameInputs(color=a["rgb"][i], depth=stacked.depth(i), camera=camera,
                           camera_pose=a["world_from_camera"][i].astype(np.float64), scene=stacked.scene(i),
                           scene_labels=a["scene_labels"][i])

    return inputs, camera


def _ms(values: list[float]) -> tuple[float, float]:
    v = sorted(values)
    return 1e3 * statistics.median(v), 1e3 * v[min(len(v) - 1, int(round(0.95 * (len(v) - 1))))]


def time_mode(mode: str, args, inputs, count: int) -> dict[str, float]:
    import numpy as np

    from raspv_spv.config import spv_config
    from raspv_spv.simulator import PhospheneSimulator

    settings = {"learned_model": args.model, "device": args.device}
    sim = PhospheneSimulator(spv_config(args.device, width=args.size, mode=mode, temporal=True,
                                        mode_settings=settings))
    repeats = 20 if args.quick else args.repeats
    levels_t, rest_t, total_t, tick_t, cpu_t, mode_cpu_t = [], [], [], [], [], []
    turn = math.radians(5.0)
    R = np.array([[math.cos(turn), 0.0, math.sin(turn)], [0.0, 1.0, 0.0], [-math.sin(turn), 0.0, math.cos(turn)]])
    for i in range(repeats + 5):
        frame = inputs(i % count)                       # a new FrameInputs: nothing cached from before
        c0, t0 = time.thread_time(), time.perf_counter()
        lv = sim.levels(frame)
        t1, c1 = time.perf_counter(), time.thread_time()
        sim.render(sim.brightness(lv))
        t2, c2 = time.perf_counter(), time.thread_time()
        sim.levels(frame, capture_from_display=R)       # a display tick with the head turned
        t3 = time.perf_counter()
        if i >= 5:
            levels_t.append(t1 - t0)
            rest_t.append(t2 - t1)
            total_t.append(t2 - t0)
            tick_t.append(t3 - t2)
            cpu_t.append(c2 - c0)
            mode_cpu_t.append(c1 - c0)
    out = {}
    for name, values in (("mode", levels_t), ("temporal+render", rest_t), ("frame", total_t), ("tick", tick_t),
                         ("cpu", cpu_t), ("mode_cpu", mode_cpu_t)):
        out[name], out[name + "_p95"] = _ms(values)
    out["count"] = sim.count
    return out


def run(args: argparse.Namespace) -> int:
    import cv2

    from raspv_spv.modes.learned import ModelError

    cv2.setNumThreads(1)
    count = 2 if args.quick else args.frames
    if args.quick:
        args.size = min(args.size, 200)
    inputs, camera = office_frames(count)
    print(f"learned mode vs hand-designed modes: {args.device}, {args.size} px wide, temporal model on, "
          f"{count} office frames {camera.width}x{camera.height}, one thread")
    learned = None
    for mode in args.modes:
        try:
            r = time_mode(mode, args, inputs, count)
        except ModelError as exc:
            print(f"raspv bench learned: {exc}")
            return 2
        print(f"  {mode:22s} per camera frame: mode {r['mode']:6.2f} ms + temporal/render {r['temporal+render']:5.2f}"
              f" = {r['frame']:6.2f} ms median (p95 {r['frame_p95']:.2f}; CPU {r['mode_cpu']:.2f} + "
              f"{r['cpu'] - r['mode_cpu']:.2f}); per display tick "
              f"turned {r['tick']:5.2f} ms ({r['count']} phosphenes)")
        if mode == "learned":
            learned = r
    if learned is not None:
        # judged on the mode's CPU time (what it takes of one core; wall time on a loaded machine adds
        # the time other processes held the core), both printed
        ok = learned["mode_cpu"] <= TARGET_MS
        print(f"  target learned <= {TARGET_MS:g} ms per camera frame on one core (the mode's CPU time): "
              f"{'met' if ok else 'MISSED'} ({learned['mode_cpu']:.2f} ms CPU, {learned['mode']:.2f} ms median wall; "
              f"with temporal model and "
              f"renderer {learned['frame']:.2f} ms wall, {learned['cpu']:.2f} ms CPU; load average "
              f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)")
    return 0
