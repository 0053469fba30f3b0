"""Base class and entry point for every RASPV node.

``RaspvNode`` declares the node's parameters from its schema (type, range, description as
ROS descriptors), checks every run-time change with the same schema, and hands validated
changes to :meth:`RaspvNode.on_parameters`, which applies them atomically or refuses with a
reason. ``run_node`` is the ``main()`` of every node module: it initialises rclpy, spins,
turns configuration mistakes into one clear line, and shuts down cleanly on SIGINT/SIGTERM.
"""
from __future__ import annotations

import faulthandler
import os
import signal
import sys
import threading
import time
from typing import Any, Callable, Sequence

import numpy as np
import rclpy
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Header

from raspv_common.conversions import (ImageEncodingError, camera_info_to_intrinsics, depth_from_image,
                                      seconds_to_stamp)
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.liveliness import AliveAnnouncement
from raspv_common.malloc_tuning import keep_freed_buffers
from raspv_common.params import Param, ParamSchema
from raspv_common.shutdown_errors import SHUTDOWN_ERRORS, during_shutdown
from raspv_common.startup_timing import startup_mark
from raspv_common.thread_priority import BACKGROUND_NICE, lower_process_priority, raise_process_priority


class ConfigurationError(Exception):
    """A configuration the node cannot run with; reported as one line, exit code 2."""


_ARRAY_TYPES = {bool: Parameter.Type.BOOL_ARRAY, int: Parameter.Type.INTEGER_ARRAY,
                float: Parameter.Type.DOUBLE_ARRAY, str: Parameter.Type.STRING_ARRAY}


def _plain(value: Any) -> Any:
    """rclpy returns arrays as array.array/tuples; the schema works with lists."""
    if isinstance(value, (tuple, bytes)) or type(value).__name__ == "array":
        return list(value)
    return value


def _descriptor(p: Param) -> ParameterDescriptor:
    desc = p.description + (f" [{p.unit}]" if p.unit else "")
    constraints = f"allowed: {p.allowed()}"
    d = ParameterDescriptor(name=p.name, description=desc, additional_constraints=constraints,
                            read_only=not p.dynamic)
    if p.kind is float and p.minimum is not None and p.maximum is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float(p.minimum), to_value=float(p.maximum), step=0.0)]
    elif p.kind is int and p.minimum is not None and p.maximum is not None:
        d.integer_range = [IntegerRange(from_value=int(p.minimum), to_value=int(p.maximum), step=0)]
    return d


class RaspvNode(Node):
    """A node whose parameters come from a :class:`Param` list.

    Subclasses read ``self.params`` (current values by name) and override
    :meth:`on_parameters` to apply run-time changes. Every node announces that it lives on
    ``/raspv/alive/<name>`` (:mod:`raspv_common.liveliness`); a source tells what it is doing
    with :meth:`announce_source` (delivering, paused, down).
    """

    def __init__(self, name: str, params: Sequence[Param], **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self._schema = ParamSchema.of(params)
        self._throttle: dict[str, float] = {}
        self.intrinsics: CameraIntrinsics | None = None   # kept by on_camera_info
        self.exit_code = 0     # set before shutting the context down to make the process exit non-zero
        # run_node(priority="headset") raises a node's threads to real time once it is built,
        # unless it does so itself when its real-time work starts (then this is True)
        self.defers_realtime = False
        for p in self._schema:
            default = list(p.default) if isinstance(p.default, tuple) else p.default
            descriptor = _descriptor(p)
            # ROS infers an empty list as a byte array; let the schema check the elements instead.
            descriptor.dynamic_typing = isinstance(default, list) and not default
            self.declare_parameter(p.name, default, descriptor)
        # rcl reads `name: []` in a parameter file as "not set": that is an empty list.
        empty = [Parameter(p.name, _ARRAY_TYPES[p.element_kind], []) for p in self._schema
                 if p.kind is list and self.get_parameter(p.name).type_ == Parameter.Type.NOT_SET]
        if empty:
            self.set_parameters(empty)
        raw = {p.name: _plain(self.get_parameter(p.name).value) for p in self._schema}
        values, errors = self._schema.validate(raw)
        errors = errors or self._schema.check_together(values)
        if errors:
            raise ConfigurationError("; ".join(f"parameter '{k}': {m}" for k, m in errors))
        self.params: dict[str, Any] = values
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._alive = AliveAnnouncement(self)

    def announce_source(self, state: str) -> None:
        """Tell consumers what this node's source is doing: ``delivering``, ``paused`` (a known
        pause: they hold the last frame) or ``down`` (nothing will come: they show it at once)."""
        self._alive.set(state)

    # -- parameters -------------------------------------------------------------------------
    def on_parameters(self, changes: dict[str, Any]) -> str | None:
        """Apply validated ``changes`` (name → new value) atomically, or return a reason to
        refuse them (the old values stay). ``self.params`` still holds the old values while
        this runs and is updated after it returns None."""
        return None

    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        changes: dict[str, Any] = {}
        for prm in parameters:
            if prm.name == "use_sim_time":
                continue
            if prm.name not in self._schema:
                return SetParametersResult(successful=False, reason=f"unknown parameter '{prm.name}'")
            spec = self._schema[prm.name]
            if not spec.dynamic:
                return SetParametersResult(successful=False, reason=f"'{prm.name}' cannot change while the node runs")
            try:
                changes[prm.name] = spec.coerce(_plain(prm.value))
            except ValueError as exc:
                return SetParametersResult(successful=False, reason=f"'{prm.name}': {exc}")
        if not changes:
            return SetParametersResult(successful=True)
        together = self._schema.check_together({**self.params, **changes})
        if together:
            return SetParametersResult(successful=False, reason="; ".join(f"'{k}': {m}" for k, m in together))
        try:
            reason = self.on_parameters(changes)
        except Exception as exc:  # a failure to apply must not kill the node nor half-apply
            self.get_logger().error(f"applying {changes} failed: {exc!r}")
            reason = f"could not apply: {exc}"
        if reason:
            return SetParametersResult(successful=False, reason=reason)
        self.params.update(changes)
        return SetParametersResult(successful=True)

    # -- helpers ----------------------------------------------------------------------------
    def warn_throttled(self, key: str, message: str, period_s: float = 5.0) -> None:
        """Log ``message`` as a warning at most once per ``period_s`` for a given ``key``."""
        now = time.monotonic()
        if now - self._throttle.get(key, -1e9) >= period_s:
            self._throttle[key] = now
            self.get_logger().warning(message)

    def take_pending(self, sub) -> Any | None:
        """The next message already waiting on subscription ``sub``, taken now rather than when
        the executor gets to it; None when none waits or the handle was destroyed at shutdown."""
        try:
            with sub.handle:
                taken = sub.handle.take_message(sub.msg_type, sub.raw)
        except SHUTDOWN_ERRORS as exc:          # a destroyed handle at shutdown: nothing to take
            if during_shutdown(exc, self.context):
                return None
            raise
        return None if taken is None else taken[0]

    def header(self, frame_id: str, stamp_s: float | None = None) -> Header:
        """A header stamped now (node clock) or at ``stamp_s`` seconds."""
        stamp = self.get_clock().now().to_msg() if stamp_s is None else seconds_to_stamp(stamp_s)
        return Header(stamp=stamp, frame_id=frame_id)

    def on_camera_info(self, msg: CameraInfo) -> None:
        """Subscription callback keeping the latest camera model in ``self.intrinsics``; an
        invalid one is warned about (throttled) and ignored."""
        try:
            self.intrinsics = camera_info_to_intrinsics(msg)
        except ValueError as exc:
            self.warn_throttled("camera-info", f"ignoring camera info: {exc}")

    def read_depth(self, msg: Image) -> np.ndarray | None:
        """Depth in metres (NaN holes) from ``msg``, or None — warned about, throttled — when its
        encoding is not a depth encoding or its size differs from ``self.intrinsics``."""
        try:
            depth = depth_from_image(msg)
        except ImageEncodingError as exc:
            self.warn_throttled("depth", f"ignoring depth image: {exc}")
            return None
        K = self.intrinsics
        if K is not None and depth.shape != (K.height, K.width):
            self.warn_throttled("depth-size", f"depth {depth.shape[1]}x{depth.shape[0]} does not match camera info "
                                              f"{K.width}x{K.height}; ignoring it")
            return None
        return depth

    def close(self) -> None:
        """Release resources (flush logs, close files); called once at shutdown."""


STOP_HANG_S = 6.0     # s: a node's ROS teardown (destroy, rclpy shutdown) longer than this is a hang


def run_node(node_factory: Callable[[], RaspvNode], argv: Sequence[str] | None = None,
             threads: int = 1, priority: str = "normal") -> None:
    """Run a node until SIGINT/SIGTERM; exit 0 on clean shutdown, 2 on a configuration error,
    or the node's ``exit_code`` when it shut itself down with one. ``priority``: a node on the
    path from the wearer's head to the phosphenes ("headset": spv, bridge) runs real-time where
    allowed — all its threads, from when it is built, or from when it calls
    ``raise_process_priority`` itself if it sets ``defers_realtime`` (spv: its display's first
    frame), so that its start-up does not hold up the headset path of a running graph; cameras
    and the simulator ("source") and perception ("perception") yield to it when the machine is
    short (``raspv_common.thread_priority``)."""
    args = list(sys.argv if argv is None else argv)
    keep_freed_buffers()              # before rclpy's threads start allocating (raspv_common.malloc_tuning)
    if priority in BACKGROUND_NICE:
        if os.environ.get("RASPV_BACKGROUND_PRIORITY", "on") != "off":     # "off": comparison runs (bench qoe)
            lower_process_priority(BACKGROUND_NICE[priority])
    elif priority not in ("normal", "headset"):
        raise ValueError(f"priority must be normal, headset, {' or '.join(BACKGROUND_NICE)}, got {priority!r}")
    _remember_stop_signals()
    rclpy.init(args=args)
    startup_mark("rclpy initialised")
    node = None
    code = 0
    try:
        node = node_factory()
        startup_mark("node built")
        if priority == "headset" and not getattr(node, "defers_realtime", False):
            raise_process_priority()
        executor = MultiThreadedExecutor(num_threads=threads) if threads > 1 else SingleThreadedExecutor()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ConfigurationError as exc:
        print(f"[{_node_label(node, args)}] configuration error: {exc}", file=sys.stderr, flush=True)
        code = 2
    except (rclpy.exceptions.ParameterException, rclpy.exceptions.InvalidParameterTypeException) as exc:
        print(f"[{_node_label(node, args)}] parameter error: {exc}", file=sys.stderr, flush=True)
        code = 2
    except RuntimeError:
        # SIGINT/SIGTERM shut the context down while the executor was taking a message (rclpy
        # then fails inside take_message), or SIGINT's KeyboardInterrupt was raised inside the
        # message's conversion to Python (pybind11 then raises "Unable to convert call argument
        # '0' to Python object" while the context is still ok: the scene node's log at a stop in
        # the clean-shutdown test, CI of 7 Dec): a clean stop, not a crash
        if rclpy.ok() and not _STOP_SIGNAL.is_set():
            raise
    finally:
        try:
            if node is not None:
                code = code or node.exit_code
                node.close()            # finishing recordings and logs: bounded by the launcher's grace only
        finally:
            # a ROS teardown that hangs prints every thread's stack to the node's log and exits,
            # before the launcher's SIGINT grace (8 s) runs out and SIGKILL leaves nothing to go on
            faulthandler.dump_traceback_later(STOP_HANG_S, exit=True)
            if node is not None:
                node.destroy_node()
            rclpy.try_shutdown()
            faulthandler.cancel_dump_traceback_later()
    if code:
        sys.exit(code)


_STOP_SIGNAL = threading.Event()        # set when SIGINT reached this process


def _remember_stop_signals() -> None:
    """Keep SIGINT a KeyboardInterrupt but note that it came (run_node's RuntimeError case).
    Installed before rclpy.init so that rclpy's signal handler chains to it; only from the
    main thread and over Python's default handler (a caller with its own handler keeps it)."""
    if threading.current_thread() is not threading.main_thread():
        return
    if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        return

    def interrupt(signum, frame):
        _STOP_SIGNAL.set()
        raise KeyboardInterrupt
    signal.signal(signal.SIGINT, interrupt)


def _node_label(node: Node | None, args: Sequence[str]) -> str:
    if node is not None:
        return node.get_name()
    for a in args:
        if a.startswith("__node:="):
            return a.split(":=", 1)[1]
    return args[0] if args else "node"
