"""Display-time reprojection and simulated device latency (no ROS): what the display shows at a tick.

VR headsets hide their rendering latency with *timewarp*: just before the display refreshes,
the last rendered image is re-sampled for the newest head orientation. The spv display loop
does the same with the last camera frame: at every display tick the phosphene rays of the view
the display should show (C1) are turned into the camera that took the frame (C0) and sampled
there, at K_C·R·K_P⁻¹·P_i with R = R_{C0←C1} (:meth:`~raspv_spv.sampling.Sampling.turned`).
World-fixed content follows: Chess-Floor intersects the turned rays with the frame's floor and
maps them with the frame's camera pose; the path and stair overlays project their points into
the turned view. Phosphenes whose turned ray leaves the camera image are dark; the simulator
renders a margin around its field of view so small turns stay inside (`sim` ``margin_deg``).

Frames: camera optical C (x right, y down, z forward); head H and base B (x forward, y left,
z up; ``/head/orientation`` is B ← H, identity looks ahead); world W (``/camera/pose`` W ← C,
``/odom`` W ← B). With t0 the frame's capture stamp and t1 the display time::

    R_{C0←C1} = R_{B←C0}(t0)ᵀ · R_{B0←B1} · R_{B←H}(t1) · R_{H←C}

- R_{B←C0}(t0), the head the frame was really rendered with: from ``/camera/pose`` and
  ``/odom`` at the frame's stamp when the source publishes both (the simulator does, stamped
  like the images); otherwise from ``/head/orientation`` interpolated at the stamp (a camera
  on the subject's head).
- R_{B0←B1}: the base's turn since t0, from ``/odom`` (extrapolated with its yaw rate for at
  most :data:`MAX_BASE_EXTRAPOLATION_S`); identity without odometry.
- R_{B←H}(t1): the newest head orientation (held since the last message), or the one at
  now − latency.
- R_{H←C} = :data:`OPTICAL_IN_HEAD`: the camera looks along the head's x axis.

Only the rotation is reprojected: when the head turns about the neck, the eye also moves a
few centimetres, and that parallax is not (near objects shift by up to a degree or two until the
next frame). The reprojection assumes ``/head/orientation`` turns the camera, so it is decided
from the images' source (:mod:`raspv_spv.camera_source`), not by the ``reprojection`` switch alone: the
simulator's head camera and a real camera mounted on the head follow the viewer's head; a
recording (a replayed bag, a camera node playing a file) and a camera on the chest, in the hand
or on a robot never do. The launcher sets the spv node's ``camera_source`` from the graph
(:func:`~raspv_spv.camera_source.camera_source_of`).

Simulated device latency L: the display shows the newest frame captured at or before now − L,
turned to the head orientation at now − L — a device whose camera-to-implant delay is L for
head rotations whatever this graph's own latency (as long as that is shorter than L; without
reprojection the graph's latency adds to L up to the next frame).

All times are float seconds on the clock that stamped the messages (ROS time: the system clock,
or ``/clock`` of a replayed bag).
"""
from __future__ import annotations

import math
import threading
from collections import deque
from dataclasses import dataclass

import numpy as np

from raspv_common.pose_buffer import PoseBuffer
from raspv_common.rotations import quaternion_to_matrix
from raspv_spv.camera_source import head_turns_camera
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.view_memory import MAX_FILL_VIEWS, SceneResult, ViewMemory, fill_outside, remembered_scene_labels

# R_{H←C}: the optical frame's axes (x right, y down, z forward) in the head frame (x forward,
# y left, z up) — the same convention as the simulator's avatar (raspv_sim.avatar).
OPTICAL_IN_HEAD = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])

MAX_BASE_EXTRAPOLATION_S = 0.25   # the base's yaw is predicted from its rate at most this far [s]
STAMP_TOLERANCE_S = 0.002         # a pose this close to a frame's stamp is the frame's pose [s]
MAX_POSE_PREDICTION_S = 0.2       # a camera pose is predicted at most this far past the newest [s]
MIN_TURN_DEG = 0.05               # smaller turns show the frame as captured (≪ a camera pixel)
HISTORY_S = 3.0                   # poses kept [s]


def rotation_angle_deg(R: np.ndarray) -> float:
    """Angle of the rotation ``R`` (3×3) [deg]."""
    c = (float(np.trace(R)) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def _yaw_matrix(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class ViewTracker:
    """Stamped head, base and camera orientations → R_{C0←C1} between a frame's capture and a
    display time (see the module's docstring). Thread-safe: inputs arrive in ROS callbacks, the
    display thread asks."""

    def __init__(self, history_s: float = HISTORY_S) -> None:
        self._lock = threading.Lock()
        # head commands hold until the next one: answered however far past the newest
        self.head = PoseBuffer(max_age_s=history_s, max_extrapolation_s=1e9)
        self.camera = PoseBuffer(max_age_s=history_s, max_extrapolation_s=STAMP_TOLERANCE_S)
        self.base = PoseBuffer(max_age_s=history_s, max_extrapolation_s=STAMP_TOLERANCE_S)
        self._yaw_rate = 0.0                        # rad/s of the newest odometry

    # -- inputs (raise ValueError for non-finite values) -------------------------------------------
    def add_head(self, stamp: float, quaternion) -> None:
        """Head orientation B ← H, quaternion (x, y, z, w), at ``stamp`` [s]."""
        T = np.eye(4)
        T[:3, :3] = quaternion_to_matrix(*(float(v) for v in quaternion))
        with self._lock:
            self.head.add(stamp, T)

    def add_camera_pose(self, stamp: float, world_from_camera: np.ndarray) -> None:
        with self._lock:
            self.camera.add(stamp, world_from_camera)

    def add_odometry(self, stamp: float, world_from_base: np.ndarray, yaw_rate: float) -> None:
        """Base pose W ← B and its yaw rate [rad/s] (``/odom`` twist angular.z)."""
        if not math.isfinite(yaw_rate):
            raise ValueError(f"yaw rate must be finite, got {yaw_rate}")
        with self._lock:
            self.base.add(stamp, world_from_base)
            if self.base.latest().stamp == stamp:
                self._yaw_rate = float(yaw_rate)

    def camera_pose_at(self, stamp: float) -> np.ndarray | None:
        """W ← C at ``stamp`` (interpolated; None when no pose within the tolerance)."""
        with self._lock:
            return self.camera.lookup_or_none(stamp)

    def camera_pose_predicted(self, stamp: float, max_ahead_s: float = MAX_POSE_PREDICTION_S) -> np.ndarray | None:
        """W ← C at ``stamp``, continued past the newest pose at its velocity (a frame that
        arrived before its pose); None without poses."""
        with self._lock:
            return self.camera.predict(stamp, max_ahead_s)

    def newest_camera_pose_stamp(self) -> float | None:
        with self._lock:
            latest = self.camera.latest()
        return None if latest is None else latest.stamp

    # -- the answer ---------------------------------------------------------------------------------
    def capture_from_display(self, capture_stamp: float, display_stamp: float) -> np.ndarray | None:
        """R_{C0←C1} (3×3) from the camera at ``capture_stamp`` to the view at ``display_stamp``,
        or None when no head orientation is known (nothing to reproject to)."""
        with self._lock:
            if not len(self.head):
                return None
            head_now = self.head.lookup(display_stamp)[:3, :3]
            base_from_camera = self._base_from_camera(capture_stamp)
            if base_from_camera is None:
                return None
            turn = self._base_turn(capture_stamp, display_stamp)
        return base_from_camera.T @ turn @ head_now @ OPTICAL_IN_HEAD

    # -- world orientations (the view memory, raspv_spv.view_memory) -----------------------------
    def world_from_camera(self, t0: float) -> tuple[np.ndarray, np.ndarray] | None:
        """(R_{W←C0} (3×3), the base's position (3,) [m]) at the capture stamp ``t0``; None
        without odometry at ``t0`` (a remembered view needs the base: rotations are re-projected,
        walking is not)."""
        with self._lock:
            base0 = self.base.lookup_or_none(t0)
            base_from_camera = None if base0 is None else self._base_from_camera(t0)
        if base_from_camera is None:
            return None
        return base0[:3, :3] @ base_from_camera, base0[:3, 3].copy()

    def world_from_view(self, t1: float) -> tuple[np.ndarray, np.ndarray] | None:
        """(R_{W←C1} (3×3) of the view the display shows at ``t1``, the base's newest position
        (3,) [m]); None without a head orientation or odometry. With :meth:`world_from_camera`,
        R_{C0←C1} = R_{W←C0}ᵀ·R_{W←C1} — :meth:`capture_from_display` for frames of any age."""
        with self._lock:
            if not len(self.head) or not len(self.base):
                return None
            head_now = self.head.lookup(t1)[:3, :3]
            base1 = self._base_rotation(t1)
            position = self.base.latest().matrix[:3, 3].copy()
        return base1 @ head_now @ OPTICAL_IN_HEAD, position

    def _base_from_camera(self, t0: float) -> np.ndarray | None:
        world_from_camera = self.camera.lookup_or_none(t0)
        world_from_base = self.base.lookup_or_none(t0)
        if world_from_camera is not None and world_from_base is not None:
            return world_from_base[:3, :3].T @ world_from_camera[:3, :3]
        head = self.head.lookup_or_none(t0)
        return None if head is None else head[:3, :3] @ OPTICAL_IN_HEAD

    def _base_turn(self, t0: float, t1: float) -> np.ndarray:
        """R_{B0←B1}: how the base turned from t0 to t1 (identity without odometry)."""
        base0 = self.base.lookup_or_none(t0)
        if base0 is None:
            return np.eye(3)
        return base0[:3, :3].T @ self._base_rotation(t1)

    def _base_rotation(self, t1: float) -> np.ndarray:
        """R_{W←B} at ``t1``: looked up, or past the newest odometry extrapolated at the base's
        yaw rate for at most MAX_BASE_EXTRAPOLATION_S (odometry present)."""
        latest = self.base.latest()
        if t1 <= latest.stamp:
            return self.base.lookup(t1)[:3, :3]
        ahead = min(t1 - latest.stamp, MAX_BASE_EXTRAPOLATION_S)
        return latest.matrix[:3, :3] @ _yaw_matrix(self._yaw_rate * ahead)


@dataclass(frozen=True)
class DisplayFrame:
    """A camera frame the display can show: its capture ``stamp`` [s], ``inputs``, the
    ``levels`` its mode gave at the capture orientation, the map they belong to, and the
    ``simulator`` that computed them (after a run-time change the display re-runs the new
    mode on the frame instead of showing the old mode's levels)."""

    stamp: float
    inputs: FrameInputs
    levels: np.ndarray
    map_id: int
    simulator: object = None


class FrameHistory:
    """The recent frames, for a display that shows the frame captured ``latency`` ago."""

    def __init__(self, keep_s: float = 0.5) -> None:
        self.keep_s = keep_s
        self._frames: deque[DisplayFrame] = deque()
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return len(self._frames)

    def add(self, frame: DisplayFrame, latency_s: float = 0.0) -> None:
        """Append ``frame`` and forget frames no display ``latency_s`` behind needs. A frame
        stamped > 1 s before the newest (a bag looping) starts over; one less before it (a scene
        result that came after a newer frame was shown) is dropped: the display never goes back."""
        with self._lock:
            if self._frames and frame.stamp < self._frames[-1].stamp:
                if frame.stamp >= self._frames[-1].stamp - 1.0:
                    return
                self._frames.clear()
            if self._frames and frame.stamp == self._frames[-1].stamp:
                self._frames[-1] = frame          # the same frame again, recomputed (its pose came)
                return
            self._frames.append(frame)
            horizon = frame.stamp - latency_s - self.keep_s
            while len(self._frames) > 1 and self._frames[1].stamp <= horizon:
                self._frames.popleft()

    def newest(self) -> DisplayFrame | None:
        with self._lock:
            return self._frames[-1] if self._frames else None

    def pick(self, display_stamp: float, latency_s: float = 0.0) -> DisplayFrame | None:
        """The newest frame captured at or before ``display_stamp − latency_s`` (with no latency:
        the newest frame, whatever the clocks); None when there is none yet."""
        with self._lock:
            if not self._frames:
                return None
            if latency_s <= 0.0:
                return self._frames[-1]
            due = display_stamp - latency_s
            for frame in reversed(self._frames):
                if frame.stamp <= due:
                    return frame
            return None


class DisplayView:
    """What the display shows at each tick: the frame for the device latency, turned to the
    head orientation of the display time (when ``reprojection`` is on and the viewer's head
    turns the camera of ``camera_source``, :func:`~raspv_spv.camera_source.head_turns_camera`).

    The node feeds poses into :attr:`tracker` and frames with :meth:`add_frame`, and asks
    :meth:`levels_at` at every tick. A turn re-runs the mode on the frame with turned rays
    (the mode's per-frame work is cached in the frame's inputs), only when the view turned by
    more than :data:`MIN_TURN_DEG` since the last time; so does a new simulator (a mode or
    setting changed at run time), so the change shows on the last frame at once.
    """

    def __init__(self, reprojection: bool = True, latency_ms: float = 0.0, camera_source: str = "sim",
                 memory_s: float = 0.0) -> None:
        self.reprojection = reprojection and head_turns_camera(camera_source)
        self.latency_s = latency_ms / 1000.0
        self.tracker = ViewTracker(history_s=max(HISTORY_S, self.latency_s + 1.0))
        self.frames = FrameHistory()
        self.memory = ViewMemory(max_age_s=memory_s)
        self.scenes = ViewMemory(max_age_s=memory_s)      # scene perception's own results, by direction
        self._last: tuple[object, DisplayFrame, np.ndarray | None, np.ndarray] | None = None
        self.turned_ticks = 0                     # ticks whose levels were re-sampled
        self.filled_ticks = 0                     # ... of them with phosphenes filled from remembered views
        self.gaze_rotation: np.ndarray | None = None   # the eye's G (gaze-contingent), set for each display tick

    def configure(self, reprojection: bool, latency_ms: float, camera_source: str = "sim",
                  memory_s: float | None = None) -> None:
        self.reprojection = reprojection and head_turns_camera(camera_source)
        self.latency_s = latency_ms / 1000.0
        if memory_s is not None and memory_s != self.memory.max_age_s:
            self.memory = ViewMemory(max_age_s=memory_s)
            self.scenes = ViewMemory(max_age_s=memory_s)
        self._last = None

    @property
    def remembering(self) -> bool:
        """Whether turned views are filled from remembered frames: reprojection on, no device latency."""
        return self.reprojection and self.latency_s == 0.0 and self.memory.enabled

    def add_frame(self, frame: DisplayFrame) -> None:
        self.frames.add(frame, self.latency_s)
        if self.remembering:
            seen = self.tracker.world_from_camera(frame.stamp)
            if seen is not None:
                self.memory.remember(frame, *seen)

    def remember_scene(self, stamp: float, labels: np.ndarray) -> None:
        """Keep scene perception's own ``labels`` of the depth frame captured at ``stamp`` [s], by
        the direction the camera looked then (as :meth:`add_frame` keeps frames)."""
        if not self.remembering or labels is None:
            return
        seen = self.tracker.world_from_camera(stamp)
        pose = self.tracker.camera_pose_at(stamp)
        if seen is not None and pose is not None:
            self.scenes.remember(SceneResult(stamp, labels, pose), *seen)

    def remembered_scenes(self, stamp: float, world_from_camera: np.ndarray | None,
                          exclude: float | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
        """Scene perception's own results remembered before ``stamp`` [s] (without the one of
        stamp ``exclude``) and their motion to a depth frame taken then with camera pose W ← C
        ``world_from_camera`` (4×4), for carrying a scene result into it
        (:func:`~raspv_spv.view_memory.remembered_scene_labels`); [] when nothing is remembered
        or the pose or the base is not known."""
        if world_from_camera is None or not self.remembering:
            return []
        view = self.tracker.world_from_view(stamp)
        if view is None:
            return []
        return remembered_scene_labels(self.scenes.candidates(stamp, view[1]), world_from_camera,
                                       before=stamp - STAMP_TOLERANCE_S, exclude=exclude)

    def newest_frame(self) -> DisplayFrame | None:
        """The newest frame added (whatever the device latency), or None."""
        return self.frames.newest()

    def levels_at(self, sim, map_id: int, display_stamp: float,
                  gaze_rotation: np.ndarray | None = None) -> tuple[np.ndarray, DisplayFrame] | None:
        """(levels (N,) uint8, the frame they show: its capture stamp, inputs) at ``display_stamp`` with
        simulator ``sim`` (a :class:`~raspv_spv.simulator.PhospheneSimulator`) and map
        ``map_id``; None when no frame of this map is due yet, or the current mode cannot run
        on it (a scene mode switched on before the scene arrived). ``gaze_rotation`` (3×3, eye
        optical → display optical, :func:`raspv_spv.gaze.gaze_rotation_optical`) turns the
        sampling rays with the eye too (gaze-contingent): R = R_{C0←C1}·G; None: :attr:`gaze_rotation`."""
        if gaze_rotation is None:
            gaze_rotation = self.gaze_rotation
        frame = self.frames.pick(display_stamp, self.latency_s)
        if frame is None:
            return None
        if (frame.map_id != map_id or frame.levels.shape != (sim.count,)) and frame.simulator in (sim, None):
            return None                 # levels of another map and no other simulator to re-run
        R = None
        if self.reprojection:
            R = self.tracker.capture_from_display(frame.stamp, display_stamp - self.latency_s)
            if R is not None and rotation_angle_deg(R) < MIN_TURN_DEG:
                R = None
        if gaze_rotation is not None:
            R = gaze_rotation if R is None else R @ gaze_rotation
            if rotation_angle_deg(R) < MIN_TURN_DEG:
                R = None
        if R is None and (frame.simulator is sim or frame.simulator is None):
            return frame.levels, frame                           # as captured, by this very mode
        last = self._last
        if last is not None and last[0] is sim and last[1] is frame and _same_turn(last[2], R):
            return last[3], frame
        try:
            levels = sim.levels(frame.inputs, capture_from_display=R)
        except ValueError:              # a mode this frame cannot feed (InputError is a ValueError)
            return (frame.levels, frame) if frame.simulator in (sim, None) else None
        if R is not None and self.remembering:
            levels = self._fill_from_memory(sim, frame, R, levels, display_stamp, gaze_rotation)
        self._last = (sim, frame, R, levels)
        if R is not None:
            self.turned_ticks += 1
        return levels, frame


    def _fill_from_memory(self, sim, frame: DisplayFrame, R: np.ndarray, levels: np.ndarray, display_stamp: float,
                          gaze_rotation: np.ndarray | None) -> np.ndarray:
        """``levels`` of ``frame`` turned by R, with the phosphenes outside it sampled from the
        newest remembered frames that saw them (:mod:`raspv_spv.view_memory`)."""
        inside = sim.inside(frame.inputs, R)
        if inside is None or inside.all():
            return levels
        view = self.tracker.world_from_view(display_stamp)
        if view is None:
            return levels
        world_from_display, position = view
        if gaze_rotation is not None:
            world_from_display = world_from_display @ gaze_rotation

        def sources():
            for remembered in self.memory.candidates(display_stamp, position, exclude=frame)[:MAX_FILL_VIEWS]:
                R_old = remembered.world_from_camera.T @ world_from_display
                try:
                    yield sim.levels(remembered.frame.inputs, capture_from_display=R_old), \
                        sim.inside(remembered.frame.inputs, R_old)
                except ValueError:      # a frame the current mode cannot feed
                    continue

        levels, filled = fill_outside(levels, inside, sources())
        if filled:
            self.filled_ticks += 1
        return levels


def _same_turn(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return rotation_angle_deg(a.T @ b) < MIN_TURN_DEG
