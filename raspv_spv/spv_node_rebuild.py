"""The spv node's run-time reconfiguration (a mixin of :class:`raspv_spv.spv_node.SpvNode`):
a parameter change is checked at once — refused with the reason when it cannot be built or
cannot keep the display rate (:mod:`raspv_spv.display_budget`) — and the new simulator is built
in the background (:mod:`raspv_spv.background_build`; what the disk caches lack by a
lower-priority subprocess, :mod:`raspv_spv.prebuild`), with its levels for the newest frame,
then swapped in between two display ticks.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from rclpy.parameter import Parameter

from raspv_spv import display_budget
from raspv_spv.config import SpvConfig, config_from_node_params
from raspv_spv.device import DeviceError
from raspv_spv.phosphene_map import MapError, PhospheneMap as PhospheneMapCore
from raspv_spv.prebuild import missing_from_cache, prebuild_in_subprocess
from raspv_spv.reprojection import DisplayFrame
from raspv_spv.spv_node_gaze import GAZE_PARAMS
from raspv_spv.simulator import InputError, PhospheneSimulator, check_config, describe_layout, describe_sprites

STARTUP_RATE_CHECK_S = 3.0     # the start-up configuration's display budget is checked this long after start
_BUILD_ERRORS = (DeviceError, MapError, ValueError, KeyError)


def _reason(exc: Exception) -> str:
    """The message of a build error (KeyError's str() adds quotes)."""
    return str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)


def checked_config(params: dict) -> tuple[SpvConfig, PhospheneMapCore]:
    """The configuration and map of the node's parameter values, checked (raises one of
    ``_BUILD_ERRORS``); quick — what takes long is left to :class:`PhospheneSimulator`."""
    if params["edge_low"] > params["edge_high"]:
        raise ValueError(f"edge_low ({params['edge_low']}) must not exceed edge_high ({params['edge_high']})")
    config = config_from_node_params(params)
    return config, check_config(config)


def drawing_spec(config: SpvConfig) -> tuple:
    """What /spv/map and /spv/sprites show: the map, the sprites and the output format — a new
    ``map_id`` whenever it changes (a client drawing the sprites needs the new ones)."""
    return config.map_spec(), config.sprite_spec(), config.output_format


def build_simulator(params: dict) -> PhospheneSimulator:
    """The simulator for the node's parameter values (raises one of ``_BUILD_ERRORS``)."""
    config, phosphene_map = checked_config(params)
    return PhospheneSimulator(config, phosphene_map=phosphene_map)


@dataclass
class _Rebuild:
    """A checked parameter change waiting for its simulator (built in the background)."""

    params: dict
    config: SpvConfig
    phosphene_map: PhospheneMapCore
    map_id: int
    sim: PhospheneSimulator | None = None
    levels: tuple[DisplayFrame, np.ndarray] | None = None   # (newest frame, its levels by the new simulator)


class SpvReconfiguration:
    """Parameter changes of the spv node: checked, built in the background, swapped in."""

    # -- configuration ------------------------------------------------------------------------
    def _describe(self, sim: PhospheneSimulator) -> str:
        c = sim.config
        return (f"{c.device.name}: {sim.count} {describe_layout(sim)} phosphenes, "
                f"FOV {c.device.fov_deg:g} deg, {describe_sprites(sim)}, {c.width}x{c.height} "
                f"{c.output_format}, mode {c.mode}, temporal {c.temporal_model if c.temporal else 'off'}, "
                f"{c.frame_rate:g} Hz")

    def on_parameters(self, changes):
        if set(changes) <= GAZE_PARAMS:             # eye gaze: nothing to rebuild (raspv_spv.spv_node_gaze)
            self.apply_gaze_params(changes)
            return None
        merged = {**self.params, **changes}
        verdict = self.display_rate_verdict(merged)     # refused before building what cannot keep the rate
        if verdict is not None and verdict.refuse:
            return verdict.message
        if "rate" in changes and (refused := self.page_refusal(float(changes["rate"]))):
            return refused
        try:
            config, phosphene_map = checked_config(merged)
        except _BUILD_ERRORS as exc:
            return _reason(exc)
        self.update_display_costs(config)
        spec, map_id = self._requested
        if drawing_spec(config) != spec:             # one map id per accepted change of the map or its sprites
            map_id += 1
        self._requested = (drawing_spec(config), map_id)
        self._builder.submit(_Rebuild(merged, config, phosphene_map, map_id))
        if "rate" in changes:
            self._last_tick = None                  # the display loop picks up the new period
        if {"reprojection", "device_latency_ms", "camera_source", "view_memory_s"} & set(changes):
            self.view.configure(merged["reprojection"], merged["device_latency_ms"], merged["camera_source"],
                                merged["view_memory_s"])
            self._update_subscriptions(self.sim.needs, self.view.reprojection)
        if verdict is not None and verdict.warn:
            self.get_logger().warning(verdict.message)
        self.apply_gaze_params(changes)
        return None

    # -- background rebuild (worker thread) ---------------------------------------------------
    def _build(self, request: _Rebuild) -> _Rebuild:
        """Build the new simulator and its levels for the latest frame, so the swap shows the
        new configuration at once instead of blank phosphenes until the next camera frame.
        What is not in the disk caches yet is built by a lower-priority subprocess first, so
        this process only reads it back (no GIL or CPU taken from the display thread)."""
        missing = missing_from_cache(request.config, request.phosphene_map)
        if missing:
            self.get_logger().info(f"building the {' and '.join(missing)} of {request.config.device.name} "
                                   "in the background")
            prebuild_in_subprocess(request.config)
        request.sim = PhospheneSimulator(request.config, phosphene_map=request.phosphene_map)
        request.sim.sprite_atlas()                  # for clients drawing the sprites themselves (/spv/sprites)
        frame = self.view.newest_frame()
        if frame is not None:
            try:
                request.levels = (frame, request.sim.levels(frame.inputs))
            except InputError:
                pass
        return request

    def _swap_in(self, request: _Rebuild, _result) -> None:
        with self._sim_lock:
            old = self.sim
            request.sim.adopt_state(old)
            map_changed = request.map_id != self.map_id
            self.sim, self.map_id = request.sim, request.map_id
            if request.levels is not None and self.view.newest_frame() is request.levels[0]:
                frame, levels = request.levels
                self.view.add_frame(DisplayFrame(frame.stamp, frame.inputs, levels, request.map_id, request.sim))
            self._applied_params = dict(request.params)
            self._swap_pending = True
            self._map_pending |= map_changed
        self._after_build.trigger()

    def _build_failed(self, request: _Rebuild, exc: Exception) -> None:
        self._failed = (request, exc)
        self._after_build.trigger()

    def _on_build_done(self) -> None:
        """Executor thread: subscriptions, /spv/map and the log after a swap; after a failed
        build, the parameters go back to the values on display."""
        with self._sim_lock:
            swapped, publish = self._swap_pending, self._map_pending
            self._swap_pending = self._map_pending = False
        if swapped:
            self._update_subscriptions(self.sim.needs)
            if publish:
                self.publish_map()
            self.get_logger().info(self._describe(self.sim))
        failed, self._failed = self._failed, None
        if failed is not None:
            request, exc = failed
            self.get_logger().error(f"could not build {request.config.device.name}: {exc}; "
                                    f"keeping {self.sim.config.device.name}")
            back = {k: v for k, v in self._applied_params.items() if self.params.get(k) != v}
            if back:
                self.set_parameters([Parameter(k, value=v) for k, v in back.items()])

    def display_rate_verdict(self, params: dict) -> display_budget.RateVerdict | None:
        """Can ``params`` run at their display rate here? (:mod:`raspv_spv.display_budget`: a cost
        model measured on this machine, plus the overhead measured on this node's display loop).
        """
        try:
            current = display_budget.load_of_config(self.sim.config)
            overhead = display_budget.observed_overhead_ms(list(self._tick_ms), current)
        except ValueError:
            overhead = 0.0
        self._overhead_ms = overhead
        return display_budget.check_node_params(params, overhead_ms=overhead)

    def update_display_costs(self, config: SpvConfig) -> None:
        """What ``config``'s rate and the headset rates cost on this machine, into ``/spv/status``."""
        try:
            load = display_budget.load_of_config(config)
        except ValueError:
            return
        self.display_costs = display_budget.rate_costs(load, overhead_ms=getattr(self, "_overhead_ms", 0.0))
        args = getattr(self, "_status_args", None)
        if args is not None:
            self._publish_status(*args)

    def _check_rate_after_start(self) -> None:
        """Once, a few seconds after start: warn when the configuration the node started with
        cannot keep its display rate. (At the node's own priority: ~0.3 s of measuring at a low
        one held the GIL while other processes ran, stalling the display thread for 100-300 ms.)"""
        if self._stop_display.wait(STARTUP_RATE_CHECK_S):
            return
        verdict = self.display_rate_verdict(dict(self.params))
        self.update_display_costs(self.sim.config)
        if verdict is not None and (verdict.refuse or verdict.warn) and not self._stop_display.is_set():
            self.get_logger().warning(verdict.message)
