"""Run a ``raspv`` command with one core slowed 5× — every call of it repeated five times: the
suite's proof that the benchmark ratio gates trip (tests/bench/test_bench_ratios.py). A test
helper: nothing in the product imports it.

usage: python tests/bench/slowed_core.py CORE RASPV-ARGS…
CORE: renderer (Renderer.render_float, under every phosphene image), levels_encoder
(levels_stream.pack_levels_payload, the bridge's levels frames), scene_pipeline
(ScenePerception.process).
"""
from __future__ import annotations

import functools
import sys

FACTOR = 5


def slowed(fn, times: int = FACTOR):
    """``fn`` doing its work ``times`` times per call."""
    @functools.wraps(fn)
    def slow(*args, **kwargs):
        for _ in range(times - 1):
            fn(*args, **kwargs)
        return fn(*args, **kwargs)
    return slow


def slow_down(core: str) -> None:
    if core == "renderer":
        from raspv_spv.renderer import Renderer

        Renderer.render_float = slowed(Renderer.render_float)
    elif core == "levels_encoder":
        from raspv_hmd import levels_stream

        levels_stream.pack_levels_payload = slowed(levels_stream.pack_levels_payload)
    elif core == "scene_pipeline":
        from raspv_perception.scene_perception import ScenePerception

        ScenePerception.process = slowed(ScenePerception.process)
    else:
        raise SystemExit(f"slowed_core.py: unknown core {core!r} (renderer, levels_encoder, scene_pipeline)")


if __name__ == "__main__":
    slow_down(sys.argv[1])
    from raspv_bringup.cli import main

    sys.exit(main(sys.argv[2:]))
