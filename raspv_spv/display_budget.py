"""Can a phosphene configuration run at its display rate on this machine? (no ROS)

Every display frame the spv node advances the temporal model, renders the sprites and builds
and publishes the image, whatever the inputs do. That work grows with three counts of the
configuration, known before anything is built:

- ``phosphenes`` N: levels → brightness, the temporal look-up (or the recursive temporal model,
  timed itself on a frame that delivers a pulse), the per-phosphene message arrays;
- ``sprite_pixels``: lit pixels summed over the visible phosphenes (≈ N·(1 − dropout)·area of one
  sprite) — the sparse product that draws them;
- ``image_bytes``: width · height · channels — clearing, the 8-bit conversion, copies into the
  message and its serialisation.

:class:`DisplayCost` holds the time per unit of each, **measured on this machine** by timing
the same NumPy/SciPy/OpenCV operations the renderer uses on synthetic inputs of realistic size
(≈ 0.3 s, once per process; the CPU time of the measuring thread, fastest of several repeats,
so that other processes' load inflates it as little as possible).
:func:`check_display_rate` predicts a configuration's frame time, compares it with the display
period and, when it does not fit, says how many phosphenes of that size would. Verdicts:

- refused: the predicted frame time exceeds the period — the display cannot keep the rate even
  on an idle machine;
- accepted with a warning: it exceeds half the period — the display thread shares the process
  (input callbacks computing levels) and the cores with the rest of the graph, so frames will
  be dropped whenever those are busy;
- accepted.

The publish is counted as one more copy of the image bytes (rclpy serialises an Image with a
copy of its data); what the model does not see (message headers, the middleware) the running
node measures on its own display loop and adds (:func:`observed_overhead_ms`). Measured here
(``raspv bench budget``, two runs on a shared 2-core VM), the CPU time of the display work was
0.74–1.52 × the prediction over ten configurations (median 0.99); the factor of two between
"warn" and "refuse" absorbs that.
"""
from __future__ import annotations

import array
import math
import time
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

WARN_FRACTION = 0.5        # predicted frame time above this fraction of the period: warn
REFUSE_FRACTION = 1.0      # above the whole period: refuse
HEADSET_RATES = (50.0, 72.0, 90.0, 120.0)   # display rates /spv/status prices (the paper's 50 Hz, headsets')


@dataclass(frozen=True)
class DisplayLoad:
    """Per-frame work of a configuration: counts, not times."""

    phosphenes: int
    sprite_pixels: int         # lit pixels over all visible phosphenes
    image_bytes: int           # width · height · channels of the published image
    rate_hz: float
    recursive: bool = False    # the recursive temporal model (else the look-up table, or none)

    @property
    def period_ms(self) -> float:
        return 1e3 / self.rate_hz


@dataclass(frozen=True)
class DisplayCost:
    """Measured time per unit of display work on this machine."""

    per_sprite_pixel_ns: float
    per_phosphene_ns: float
    per_image_byte_ns: float
    fixed_us: float
    recursive_per_phosphene_ns: float = 0.0    # the recursive temporal model, a frame with a pulse
    recursive_fixed_us: float = 0.0

    def frame_ms(self, load: DisplayLoad) -> float:
        """Predicted time of one display frame of ``load`` [ms]."""
        ns = (self.per_sprite_pixel_ns * load.sprite_pixels + self.per_phosphene_ns * load.phosphenes
              + self.per_image_byte_ns * load.image_bytes)
        if load.recursive:
            ns += self.recursive_per_phosphene_ns * load.phosphenes + self.recursive_fixed_us * 1e3
        return ns * 1e-6 + self.fixed_us * 1e-3

    @classmethod
    def measure(cls, repeats: int = 25) -> "DisplayCost":
        """Time the renderer's operations on synthetic inputs at two sizes each; the slope
        between the sizes is the cost per unit (the fastest of ``repeats`` runs of each)."""
        import cv2
        import scipy.sparse as sp

        rng = np.random.default_rng(0)

        def best(fn, times: int = repeats) -> float:
            # CPU time of this thread: time the thread spent preempted by other processes
            # does not count (every operation timed here runs in the calling thread)
            out = math.inf
            for _ in range(times):
                t0 = time.thread_time()
                fn()
                out = min(out, time.thread_time() - t0)
            return out

        # sparse product: square 21x21 px sprites at random places of an 800x800 image, in raster
        # order like a map's phosphenes — the renderer's memory access pattern (runs of a row,
        # then the next row); 1.5 and 6 M
        # entries (12-48 MB with their indices), beyond the caches, where large configurations
        # are: there the product streams from memory (measured here: 4-5x the cost per entry
        # of a matrix that fits the cache, which a smaller calibration missed)
        width, side = 800, 21
        off = (np.arange(side)[:, None] * width + np.arange(side)[None, :]).ravel()
        sizes = (3400, 13600)
        mats = []
        for n in sizes:
            corners = rng.integers(0, width - side, (n, 2))
            corners = corners[np.lexsort((corners[:, 0], corners[:, 1]))]    # row by row, as maps are laid out
            indices = (corners[:, 1:2] * width + corners[:, 0:1] + off[None, :]).astype(np.int32).ravel()
            indptr = np.arange(n + 1, dtype=np.int32) * off.size
            mats.append((sp.csc_matrix((rng.random(indices.size, dtype=np.float32), indices, indptr),
                                       shape=(width * width, n)), rng.random(n, dtype=np.float32)))
        t_small, t_large = (best(lambda m=m, b=b: m @ b, max(5, repeats // 3)) for m, b in mats)
        per_sprite_pixel = max(0.0, (t_large - t_small) / ((sizes[1] - sizes[0]) * off.size))

        # per phosphene: level scaling, temporal look-up (uint16 history registers), visibility,
        # and the levels/brightness arrays copied into the frame message
        table = rng.random(1024, dtype=np.float32)

        def phosphene_work(n: int) -> float:
            levels = rng.integers(0, 8, n).astype(np.uint8)
            hist = np.zeros(n, np.uint16)
            amp = np.zeros(n, np.float32)
            visible = np.ones(n, np.float32)

            def once():
                b = levels.astype(np.float32) * np.float32(1 / 7)
                on = b > 0
                np.left_shift(hist, np.uint16(1), out=hist)
                hist[...] |= on.astype(np.uint16)
                hist[...] &= np.uint16(1023)
                np.copyto(amp, b, where=on)
                out = table[hist] * amp * visible
                array.array("B", levels.tobytes())
                array.array("f", out.tobytes())
            return best(once)

        p_small, p_large = phosphene_work(2000), phosphene_work(20000)
        per_phosphene = max(0.0, (p_large - p_small) / 18000)

        # per image byte: the float image → uint8, the copies into the message (×2: tobytes,
        # array) and the publish's serialisation (one more)
        def image_work(w: int) -> float:
            summed = rng.random(w * w, dtype=np.float32) * 255

            def once():
                img = cv2.convertScaleAbs(summed.reshape(w, w))
                data = array.array("B", img.tobytes())
                bytes(data)                      # stands for the serialisation copy
            return best(once)

        # the recursive temporal model (raspv_spv/temporal_recursive.py), itself: a frame that
        # delivers a pulse (every frame at the pulse rate; the dearer case)
        from raspv_spv.temporal_recursive import RecursiveConfig, RecursiveTemporalState, recursive_model

        model = recursive_model(RecursiveConfig())

        def recursive_work(n: int) -> float:
            state = RecursiveTemporalState(model, n)
            amp = (rng.random(n) > 0.5).astype(np.float32)
            clock = [0.0]

            def once():
                clock[0] += model.config.period_ms
                state.advance(clock[0], amp)
            once()
            return best(once)

        r_small, r_large = recursive_work(2000), recursive_work(20000)
        per_recursive = max(0.0, (r_large - r_small) / 18000)
        recursive_fixed = max(0.0, r_small - per_recursive * 2000)

        i_small, i_large = image_work(200), image_work(800)
        per_byte = max(0.0, (i_large - i_small) / (800 * 800 - 200 * 200))
        fixed = max(0.0, i_small - per_byte * 200 * 200) + max(0.0, p_small - per_phosphene * 2000)
        return cls(per_sprite_pixel * 1e9, per_phosphene * 1e9, per_byte * 1e9, fixed * 1e6,
                   per_recursive * 1e9, recursive_fixed * 1e6)


@dataclass(frozen=True)
class RateVerdict:
    """``refuse``: the configuration cannot run at its rate; ``warn``: it will drop frames when
    the machine is busy; ``message``: one line with the figures (empty when fine)."""

    refuse: bool
    warn: bool
    frame_ms: float
    period_ms: float
    max_phosphenes: int
    message: str


_measured: DisplayCost | None = None


def machine_cost() -> DisplayCost:
    """This process's measured :class:`DisplayCost` (measured on first use, ≈ 0.3 s)."""
    global _measured
    if _measured is None:
        _measured = DisplayCost.measure()
    return _measured


def sprite_pixel_count(diameter_px: float) -> int:
    """Lit pixels of one Gaussian sprite of this phosphene diameter (the renderer's own sprite,
    sampled on the pixel grid), averaged over where its centre falls within a pixel; the image
    border is ignored."""
    from raspv_spv.sprites import GaussianSprite

    sprite = GaussianSprite(diameter_px)
    reach = int(math.ceil(sprite.radius_px)) + 1
    off = np.arange(-reach, reach + 1, dtype=float)
    counts = []
    for fx in (0.125, 0.375, 0.625, 0.875):          # the centre's position inside its pixel
        for fy in (0.125, 0.375, 0.625, 0.875):
            dx, dy = np.meshgrid(off + 0.5 - fx, off + 0.5 - fy)
            counts.append(np.count_nonzero(sprite.weights(dx, dy) > 0))
    return int(round(float(np.mean(counts))))


def load_of_config(config: Any) -> DisplayLoad:
    """The :class:`DisplayLoad` of an :class:`~raspv_spv.config.SpvConfig` (builds only its
    phosphene map, milliseconds; MapError when the map itself is impossible)."""
    from raspv_spv.phosphene_map import PhospheneMap

    m = PhospheneMap.build(config.map_spec())
    visible = int(np.count_nonzero(~m.dropped))
    channels = 3 if config.output_format == "green" else 1
    per_sprite = min(sprite_pixel_count(m.diameter_px), config.width * config.height)   # no larger than the image
    recursive = bool(config.temporal) and config.temporal_update == "recursive"
    return DisplayLoad(m.count, visible * per_sprite, config.width * config.height * channels, config.frame_rate,
                       recursive)


def observed_overhead_ms(tick_ms: Sequence[float], current: DisplayLoad, cost: DisplayCost | None = None,
                         min_samples: int = 50) -> float:
    """What a running display loop spends beyond the model's prediction for its current
    configuration (message headers, rclpy's publish, scheduling): the median measured tick
    minus the predicted frame time, ≥ 0; 0 until ``min_samples`` ticks were measured."""
    if len(tick_ms) < min_samples:
        return 0.0
    cost = cost or machine_cost()
    return max(0.0, float(np.median(np.asarray(tick_ms, dtype=float))) - cost.frame_ms(current))


def check_display_rate(load: DisplayLoad, cost: DisplayCost | None = None, overhead_ms: float = 0.0) -> RateVerdict:
    """Whether ``load`` fits its display period on this machine (see the module docstring).
    ``overhead_ms``: per-frame time the model does not see, measured on the running node
    (:func:`observed_overhead_ms`)."""
    cost = cost or machine_cost()
    frame = cost.frame_ms(load) + overhead_ms
    period = load.period_ms
    per_phosphene_ns = cost.per_phosphene_ns + cost.per_sprite_pixel_ns * load.sprite_pixels / max(1, load.phosphenes)
    fixed_ms = cost.fixed_us * 1e-3 + cost.per_image_byte_ns * load.image_bytes * 1e-6 + overhead_ms
    if load.recursive:
        per_phosphene_ns += cost.recursive_per_phosphene_ns
        fixed_ms += cost.recursive_fixed_us * 1e-3
    max_n = int(max(0.0, (REFUSE_FRACTION * period - fixed_ms) * 1e6 / per_phosphene_ns)) if per_phosphene_ns > 0 else 0
    refuse = frame > REFUSE_FRACTION * period
    warn = not refuse and frame > WARN_FRACTION * period
    message = ""
    if refuse or warn:
        what = "cannot run" if refuse else "will drop frames when the machine is busy"
        message = (f"{load.phosphenes} phosphenes ({load.sprite_pixels / 1e6:.2f} M sprite pixels, "
                   f"{load.image_bytes / 1e6:.2f} MB image) {what} at {load.rate_hz:g} Hz on this machine: "
                   f"a display frame takes ~{frame:.1f} ms of the {period:.1f} ms period; at most ~{max_n} "
                   f"phosphenes of this size fit (or lower rate, width, phosphene_fov_deg)")
    return RateVerdict(refuse, warn, frame, period, max_n, message)


def rate_costs(load: DisplayLoad, cost: DisplayCost | None = None, overhead_ms: float = 0.0,
               rates: Sequence[float] = HEADSET_RATES) -> dict[str, Any]:
    """What ``load`` costs at its own rate and at each of ``rates`` on this machine, for
    ``/spv/status``: predicted frame time [ms], the period, the share of it, and the verdict
    (``ok``, ``warn``: drops frames when the machine is busy, ``refused``: cannot keep it)."""
    import dataclasses

    def one(rate: float) -> dict[str, Any]:
        v = check_display_rate(dataclasses.replace(load, rate_hz=rate), cost, overhead_ms)
        return {"frame_ms": round(v.frame_ms, 3), "period_ms": round(v.period_ms, 3),
                "share": round(v.frame_ms / v.period_ms, 3), "verdict": "refused" if v.refuse else "warn" if v.warn else "ok"}

    out = {"rate_hz": load.rate_hz, **one(load.rate_hz), "temporal": "recursive" if load.recursive else "lut or off",
           "rates": {f"{r:g}": one(r) for r in rates}}
    return out


def check_node_params(params: Mapping[str, Any], cost: DisplayCost | None = None,
                      overhead_ms: float = 0.0) -> RateVerdict | None:
    """The verdict for the spv node's parameter values (``spv_params.py``), or None when the
    configuration is invalid for another reason (building it reports that reason)."""
    from raspv_spv.config import config_from_node_params

    try:
        load = load_of_config(config_from_node_params(params))
    except (ValueError, KeyError):
        return None
    return check_display_rate(load, cost, overhead_ms)
