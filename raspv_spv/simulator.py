"""The phosphene simulator: one object from a configuration, frames in, phosphene images out.

The ``spv`` node, ``raspv bench spv``, the figure scripts and notebooks all use this class —
there is no second implementation. A frame goes through:

1. the representation mode (and overlays) → integer level per phosphene, sampled through
   P_i^C = K_C·K_P⁻¹·P_i for the frame's camera model (:mod:`raspv_spv.sampling`);
2. the temporal model (optional): with the look-up table a level > 0 delivers a pulse this frame
   and the 10-frame pulse history picks a gain g ∈ [0, 1] (:mod:`raspv_spv.temporal_lut`); the
   recursive model pulses at its own rate and gives g at any display time
   (:mod:`raspv_spv.temporal_recursive`);
   brightness = g · a, with a = level/(N_L−1) of the phosphene's latest pulse (the level sets
   how bright it can get, the pulse history how much of it is perceived now, and a phosphene
   switched off fades from the level it had); without it brightness = level/(N_L−1);
   dropped phosphenes are 0;
3. the renderer → mono8 or green rgb8 image (:mod:`raspv_spv.renderer`), whose sprites the
   device's sprite model precomputed (:mod:`raspv_spv.sprite_models`: the paper's Gaussian,
   scoreboard, axon map, biphasic axon map, dynaphos); levelled models draw each phosphene
   with the sprite of its latest pulse's level.

Building is split so a caller can refuse a configuration at once and build the rest in the
background (the spv node does): :func:`check_config` builds the map and the mode (cheap, and
where configuration mistakes show); the constructor adds sprites and the temporal table,
which may take seconds the first time (both are cached on disk).

Offline use::

    from raspv_spv.simulator import render_frame
    image = render_frame(rgb, depth, camera, device="argus_ii", mode="depth")
"""
from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_spv.config import SpvConfig, spv_config
from raspv_spv.frame_inputs import FrameInputs, check_inputs
from raspv_spv.modes import mode_class, overlay_class
from raspv_spv.phosphene_map import PhospheneMap
from raspv_spv.sprite_atlas import AtlasTooLarge, SpriteAtlas, atlas_of_renderer
from raspv_spv.renderer import Renderer
from raspv_spv.sampling import Sampling
from raspv_spv.sprite_models import build_sprite_bank
from raspv_spv.sprites import Sprite
from raspv_spv.temporal_lut import TemporalState, load_table
from raspv_spv.temporal_recursive import RecursiveTemporalState, recursive_model


class InputError(ValueError):
    """A frame the simulator cannot use (wrong array types, missing inputs)."""


@dataclass
class SpvFrame:
    """One simulated frame: ``levels`` (N,) uint8 requested by the mode, ``brightness`` (N,)
    float32 displayed in [0, 1] (after the temporal model and dropout), and the ``image``."""

    levels: np.ndarray
    brightness: np.ndarray
    image: np.ndarray


class PhospheneSimulator:
    """Map, sprites, renderer, mode, overlays and temporal state of one configuration.

    Building costs tens of milliseconds (plus a few seconds the first time a temporal table is
    computed; tables are cached on disk); :meth:`step` is the per-frame work.
    """

    def __init__(self, config: SpvConfig, sprite: Sprite | None = None, phosphene_map: PhospheneMap | None = None) -> None:
        self.config = config
        self.map = phosphene_map if phosphene_map is not None else check_config(config)
        self.sprite = sprite
        if sprite is not None:                          # a custom shape (e.g. a BitmapSprite)
            self.renderer = Renderer(self.map.display_centres, ~self.map.dropped, config.width, config.height,
                                     sprite, config.output_format)
        else:
            bank = build_sprite_bank(self.map, config.sprite_spec())
            self.renderer = Renderer.from_bank(bank, ~self.map.dropped, config.output_format)
        self.mode = mode_class(config.mode)(config.mode_settings)
        self.overlays = [overlay_class(name)(config.mode_settings) for name in config.overlays]
        self.num_levels = config.device.num_levels
        self._visible = (~self.map.dropped).astype(np.float32)
        self._level_scale = np.float32(1.0 / (self.num_levels - 1))
        self.temporal: TemporalState | RecursiveTemporalState | None = None
        if config.temporal and config.temporal_update == "recursive":
            self.temporal = RecursiveTemporalState(recursive_model(config.recursive_config()), self.map.count,
                                                   frame_ms=1000.0 / config.frame_rate)
        elif config.temporal:
            self.temporal = TemporalState(load_table(config.lut_config()), self.map.count)
        self._samplings: dict[CameraIntrinsics, Sampling] = {}
        self._pulse_levels = np.zeros(self.map.count, np.uint8)   # level of each phosphene's latest pulse

    # -- configuration --------------------------------------------------------------------------
    @property
    def count(self) -> int:
        """Number of phosphenes N."""
        return self.map.count

    @property
    def needs(self) -> frozenset[str]:
        """Inputs the mode and overlays read."""
        out = set(self.mode.needs)
        for o in self.overlays:
            out |= o.needs
        return frozenset(out)

    @property
    def optional_inputs(self) -> frozenset[str]:
        """Inputs the mode and overlays use when present."""
        out = set(self.mode.optional_inputs)
        for o in self.overlays:
            out |= o.optional_inputs
        return frozenset(out)

    def adopt_state(self, previous: "PhospheneSimulator") -> None:
        """Continue ``previous``'s pulse histories (after a rebuild with the same phosphenes),
        so a run-time change of, say, the mode does not restart the temporal model."""
        mine, theirs = self.temporal, previous.temporal
        if mine is None or theirs is None or previous.count != self.count or type(mine) is not type(theirs):
            return
        if isinstance(mine, TemporalState) or mine.model is theirs.model:
            mine.adopt(theirs)

    def variant(self, mode: str, overlays: tuple[str, ...]) -> "PhospheneSimulator":
        """This simulator with another mode and overlays, sharing its map, sprites, samplings
        and temporal state (cheap: only the mode and overlays are built). The spv node shows a
        fallback with it when inputs are stale (:mod:`raspv_spv.staleness`)."""
        other = copy.copy(self)
        other.config = dataclasses.replace(self.config, mode=mode, overlays=tuple(overlays))
        other.mode = mode_class(mode)(self.config.mode_settings)
        other.overlays = [o for name, o in zip(self.config.overlays, self.overlays) if name in overlays]
        return other

    def sampling(self, camera: CameraIntrinsics) -> Sampling:
        """The phosphenes' camera pixels for ``camera`` (cached for the last few cameras)."""
        s = self._samplings.get(camera)
        if s is None:
            if len(self._samplings) >= 4:
                self._samplings.clear()
            s = self._samplings[camera] = Sampling.build(self.map, camera)
        return s

    # -- per frame ------------------------------------------------------------------------------
    def levels(self, inputs: FrameInputs, capture_from_display: np.ndarray | None = None) -> np.ndarray:
        """Levels (N,) uint8 from the mode and overlays. ``capture_from_display`` (3×3, display
        optical frame → the camera's) samples the frame for a view turned from the camera's
        (display-time reprojection, :meth:`Sampling.turned`). Raises :class:`InputError` when
        the inputs are malformed or lack something the mode or an overlay needs."""
        problems = check_inputs(inputs)
        if problems:
            raise InputError("; ".join(problems))
        missing = inputs.missing(sorted(self.needs))
        if missing:
            raise InputError(f"mode {self.config.mode!r}{' with overlays' if self.overlays else ''} needs "
                             f"{', '.join(missing)}, not in this frame")
        sampling = self.sampling(inputs.camera) if inputs.camera is not None else None
        if sampling is not None and capture_from_display is not None:
            sampling = sampling.turned(capture_from_display)
        levels = np.asarray(self.mode.levels(inputs, sampling, self.num_levels))
        if levels.shape != (self.count,):
            raise ValueError(f"mode {self.config.mode} returned {levels.shape} levels for {self.count} phosphenes")
        levels = np.clip(levels, 0, self.num_levels - 1).astype(np.uint8)
        for overlay in self.overlays:
            levels = overlay.apply(levels, inputs, sampling, self.num_levels)
        return levels

    def inside(self, inputs: FrameInputs, capture_from_display: np.ndarray) -> np.ndarray | None:
        """(N,) bool: the phosphenes whose rays, turned by ``capture_from_display``, fall inside
        the frame's camera image (the others :meth:`levels` leaves dark); None without a camera."""
        if inputs.camera is None:
            return None
        return self.sampling(inputs.camera).turned(capture_from_display).inside

    def brightness(self, levels: np.ndarray, frames: int = 1, at_s: float | None = None) -> np.ndarray:
        """Displayed brightness (N,) float32 in [0, 1] for ``levels`` held over the last
        ``frames`` display frames (advances the temporal model when it is on). The recursive
        model takes the display time ``at_s`` [s, any increasing clock] when given: the
        brightness at that moment, ``levels`` requested from then on; else ``frames`` frames."""
        b = np.asarray(levels, dtype=np.float32) * self._level_scale
        if isinstance(self.temporal, RecursiveTemporalState) and at_s is not None:
            b = self.temporal.advance(1000.0 * at_s, b)
        elif self.temporal is not None:
            b = self.temporal.step(b, frames)
            if self.renderer.levels > 1:
                self._pulse_levels = np.rint(self.temporal.amplitude * (self.num_levels - 1)).astype(np.uint8)
        elif self.renderer.levels > 1:
            self._pulse_levels = np.asarray(levels, dtype=np.uint8)
        b *= self._visible
        return b

    def sprite_atlas(self) -> tuple["SpriteAtlas | None", str]:
        """(the renderer's sprites as one texture atlas, or None and why not) — built once
        (0.02–0.2 s), for clients that draw the phosphenes themselves (:mod:`raspv_spv.sprite_atlas`)."""
        cached = getattr(self, "_atlas", None)
        if cached is None:
            try:
                cached = (atlas_of_renderer(self.renderer, self.num_levels), "")
            except AtlasTooLarge as exc:
                cached = (None, str(exc))
            self._atlas = cached
        return cached

    @property
    def sprite_levels(self) -> np.ndarray:
        """(N,) uint8: the sprite level each phosphene is drawn with by a levelled sprite model
        (its latest pulse's level; 0: not drawn) — what :meth:`render` uses with the brightness."""
        return self._pulse_levels

    def render(self, brightness: np.ndarray) -> np.ndarray:
        """The phosphene image of ``brightness`` (mono8 (H, W) or green rgb8 (H, W, 3)); a
        levelled sprite model draws each phosphene with the sprite of its latest pulse's level,
        scaled by the perceived fraction of it."""
        return self.renderer.render(*self._sprite_gains(brightness))

    def render_float(self, brightness: np.ndarray) -> np.ndarray:
        """The mono image of ``brightness`` as float32 grey levels before the conversion to uint8
        (what :meth:`render` rounds and saturates at 255)."""
        return self.renderer.render_float(*self._sprite_gains(brightness))

    def _sprite_gains(self, brightness: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        if self.renderer.levels > 1:
            with np.errstate(divide="ignore", invalid="ignore"):
                gain = np.where(self._pulse_levels > 0,
                                brightness / (self._pulse_levels * self._level_scale), 0.0).astype(np.float32)
            return gain, self._pulse_levels
        return brightness, None

    def step(self, inputs: FrameInputs, frames: int = 1) -> SpvFrame:
        """Levels, brightness and image of one frame."""
        levels = self.levels(inputs)
        brightness = self.brightness(levels, frames)
        return SpvFrame(levels, brightness, self.render(brightness))

    def reset(self) -> None:
        """Forget the pulse histories."""
        if self.temporal is not None:
            self.temporal.reset()


def describe_layout(sim: PhospheneSimulator) -> str:
    """'hexagonal (rectangular field)' or 'argus_ii (retina at (x, y) µm, 30 deg)' for logs."""
    d, implant = sim.config.device, sim.map.implant
    if implant is None:
        return f"{d.grid} ({d.field} field)"
    s = implant.spec
    out = f"{implant.layout.name} ({implant.layout.target} at ({s.x_um:g}, {s.y_um:g}) um, {s.rotation_deg:g} deg"
    if implant.left_out:
        out += f"; {len(implant.left_out)} electrode(s) outside the visual-field map left out"
    return out + ")"


def describe_sprites(sim: PhospheneSimulator) -> str:
    """The sprite model and its parameters, for logs."""
    spec, bank = sim.config.sprite_spec(), sim.renderer.bank
    if sim.sprite is not None:
        return f"{type(sim.sprite).__name__} sprites"
    if spec.model == "gaussian":
        return f"gaussian sprites {sim.config.device.phosphene_fov_deg:g} deg"
    target = sim.map.target
    parts = {"scoreboard": f"rho {spec.rho(target, sim.map):.0f} um",
             "axon_map": f"rho {spec.rho(target):g} um, axlambda {spec.axlambda():g} um",
             "biphasic_axon_map": f"rho {spec.rho(target):g} um, axlambda {spec.axlambda():g} um, "
                                  f"up to {spec.max_amplitude_xth:g} xTh",
             "dynaphos": f"up to {spec.current_ua:g} uA"}[spec.model]
    how = "cached" if bank.cached else f"built in {bank.build_s:.1f} s"
    grid = f"1/{bank.scale} resolution" + (" and full resolution for the smallest" if bank.fine is not None else "")
    return f"{spec.model} sprites ({parts}; {bank.nnz} px at {grid}, {bank.nbytes / 1e6:.1f} MB, {how})"


def check_config(config: SpvConfig) -> PhospheneMap:
    """The map of ``config``, after checking everything that does not take long: the map (or
    the implant layout), the sprite model against it, the mode and overlays. Raises
    ``ValueError`` (or a subclass) naming what is wrong."""
    phosphene_map = PhospheneMap.build(config.map_spec())
    config.sprite_spec().check(phosphene_map)
    mode_class(config.mode)(config.mode_settings)
    for name in config.overlays:
        overlay_class(name)(config.mode_settings)
    return phosphene_map


def render_frame(color: np.ndarray | None, depth: np.ndarray | None, camera: CameraIntrinsics,
                 device: str = "default", *, temporal: bool = False, **settings: Any) -> np.ndarray:
    """One RGB-D frame → phosphene image (offline API for notebooks and batch rendering).

    ``color`` (H, W, 3) uint8 RGB and/or ``depth`` (H, W) float32 m (NaN = no reading),
    ``camera`` their intrinsics; ``device`` a preset name or YAML path; ``settings`` any
    argument of :func:`raspv_spv.config.spv_config` (``mode``, ``width``, ``fov_deg``,
    ``num_phosphenes``, ``dropout``, ``mode_settings={"max_depth": 4.0}`` …). The temporal
    model is off by default: a single frame would only show the first frame of a rising
    response; for sequences keep one :class:`PhospheneSimulator` and call ``step``.
    """
    sim = PhospheneSimulator(spv_config(device, temporal=temporal, **settings))
    return sim.step(FrameInputs(color=color, depth=depth, camera=camera)).image
