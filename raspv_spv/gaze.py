"""Eye gaze on the phosphene display (no ROS): gaze-locked and gaze-contingent phosphenes.

A retinal implant moves with the eye while its camera sits on the glasses: when the eye turns,
the phosphenes move with it on the display (the field is drawn where the eye looks) but still
show what is straight ahead of the head camera. The spv node's ``gaze_mode`` says which of three
devices is simulated:

- ``ignored`` — the phosphenes sit fixed on the display (no eye tracking: what the paper does);
- ``locked`` — the field is drawn displaced to where the eye looks, the scene is still sampled
  straight ahead of the head camera (what implant users get today);
- ``contingent`` — the field is displaced *and* the sampling follows the gaze (an eye-tracking-
  compensated device): each phosphene's ray r_i = K_P⁻¹·P_i turns by the gaze rotation G, so it
  samples the camera at K_C·R·G·K_P⁻¹·P_i — the head's display-time reprojection R
  (:mod:`raspv_spv.reprojection`) and the eye's G compose into one rotation, the same path.

Frames: gaze directions are unit vectors in the head frame H (x forward, y left, z up; like
``/head/orientation``); the eye's rotation from straight ahead is Fick's (yaw about z, then
pitch about the turned y axis, no torsion: the gimbal eye trackers report). In the display's
optical frame (x right, y down, z forward, :data:`raspv_spv.reprojection.OPTICAL_IN_HEAD`) the
direction g_opt projects through K_P to the point the eye looks at; the field's centre (the
principal point) is drawn there: offset = f_P·(g_opt,x/g_opt,z, g_opt,y/g_opt,z) px. The whole
field is *translated* by that offset (the levels stream carries one offset, not a warp): exact at
the field's centre; a phosphene φ off-centre lands f_P·(tan(θ+φ) − tan θ − tan φ) from where the
rotation would put it (0.22° for θ = 5°, φ = 10°; 0.57° for θ = φ = 10°; 2.7° for θ = 20°, φ = 15°):
for the default 20° device (spacing 0.68°) within one phosphene spacing up to a gaze of ~11°.

Saccades (the eye's fast jumps, 20–80 ms, up to 500°/s) are found by a velocity threshold
between successive samples (I-VT, Salvucci & Goldberg 2000, ETRA; 30°/s is Tobii's I-VT default,
Olsen 2012). During a saccade vision is suppressed (saccadic suppression: Matin 1974, Psychol.
Bull. 81; Burr, Morrone & Ross 1994, Nature 371): ``saccade_display`` ``blank`` shows no
phosphenes until the eye lands (default: a device cannot stimulate a moving retina usefully, and a
sighted viewer must not see the field slide), ``hold`` keeps the field where the last fixation
put it, ``follow`` draws every sample as it comes. Invalid samples (blinks, lost tracking) keep
the last valid direction; without any valid sample the field stays centred.
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

GAZE_MODES = ("ignored", "locked", "contingent")
SACCADE_DISPLAYS = ("blank", "hold", "follow")
SACCADE_THRESHOLD_DEG_S = 30.0      # I-VT velocity threshold (Olsen 2012: Tobii's default) [deg/s]
MAX_SAMPLE_GAP_S = 0.1              # samples further apart than this give no velocity [s]
MAX_SACCADE_S = 0.15                # a saccade with no sample for this long is over (the eye landed) [s]
VISIBLE_CHANGE_DEG = 0.1            # a gaze change smaller than this is not worth an extra display frame [deg]
MAX_ECCENTRICITY_DEG = 80.0         # directions further from straight ahead are refused [deg]

# R_{H←C} of raspv_spv.reprojection (repeated here so this module imports nothing of the node's)
_OPTICAL_IN_HEAD = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


class GazeError(ValueError):
    """A gaze direction that is not one (zero length, not finite, behind the head)."""


_MIN_FORWARD = math.cos(math.radians(MAX_ECCENTRICITY_DEG))


def unit_direction(direction) -> tuple[float, float, float]:
    """``direction`` (3 numbers) in the head frame → unit vector (x, y, z); raises :class:`GazeError`.
    Plain floats, not numpy: this runs for every sample (120 Hz and more) beside the display thread."""
    try:
        x, y, z = (float(c) for c in direction)
    except (TypeError, ValueError):
        raise GazeError(f"a gaze direction is 3 finite numbers, got {direction!r}") from None
    n = math.sqrt(x * x + y * y + z * z)
    if not math.isfinite(n):
        raise GazeError(f"a gaze direction is 3 finite numbers, got {direction!r}")
    if n < 1e-9:
        raise GazeError("a gaze direction of zero length (an invalid sample is sent with valid: false)")
    if x / n < _MIN_FORWARD:
        raise GazeError(f"gaze {[round(c / n, 3) for c in (x, y, z)]} is more than {MAX_ECCENTRICITY_DEG:g} deg "
                        "from straight ahead (x forward, y left, z up)")
    return (x / n, y / n, z / n)


def direction_from_angles(yaw_deg: float, pitch_deg: float) -> np.ndarray:
    """Unit gaze direction (head frame) of Fick angles: yaw > 0 looks left, pitch > 0 looks down [deg]."""
    y, p = math.radians(yaw_deg), math.radians(pitch_deg)
    return np.array([math.cos(p) * math.cos(y), math.cos(p) * math.sin(y), -math.sin(p)])


def gaze_angles_deg(direction) -> tuple[float, float]:
    """(yaw, pitch) [deg] of a head-frame direction (yaw > 0 left, pitch > 0 down)."""
    d = np.asarray(direction, dtype=float)
    return math.degrees(math.atan2(d[1], d[0])), math.degrees(math.atan2(-d[2], math.hypot(d[0], d[1])))


def angle_between_deg(a, b) -> float:
    """Angle between two 3-vectors [deg] (atan2 of |a×b| and a·b: stable for small angles)."""
    ax, ay, az = (float(c) for c in a)
    bx, by, bz = (float(c) for c in b)
    cx, cy, cz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    return math.degrees(math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ax * bx + ay * by + az * bz))


def gaze_rotation_head(direction) -> np.ndarray:
    """R_{H←E} (3×3): the eye's rotation from straight ahead, Fick (yaw about z, then pitch about
    the turned y, no torsion); maps the x axis to ``direction``."""
    yaw, pitch = (math.radians(a) for a in gaze_angles_deg(direction))
    cy, sy, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch)
    Rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    Ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    return Rz @ Ry


def gaze_rotation_optical(direction) -> np.ndarray:
    """G (3×3): from the eye's optical frame to the display's (head camera's) optical frame; a
    phosphene ray r (eye) samples the head camera along G·r (gaze-contingent sampling)."""
    return _OPTICAL_IN_HEAD.T @ gaze_rotation_head(direction) @ _OPTICAL_IN_HEAD


def field_offset_px(direction, focal_px: float) -> tuple[float, float]:
    """Where the field's centre is drawn for ``direction`` (head frame), relative to the display's
    principal point: (x right, y down) [px] = f_P·(g_opt,x/g_opt,z, g_opt,y/g_opt,z)."""
    d = unit_direction(direction)
    return (float(focal_px * -d[1] / d[0]), float(focal_px * -d[2] / d[0]))


def shift_image(image: np.ndarray, dx: int, dy: int) -> np.ndarray:
    """``image`` (H, W[, C]) translated by (dx right, dy down) whole px, black where nothing moved in."""
    dx, dy = int(dx), int(dy)
    if dx == 0 and dy == 0:
        return image
    h, w = image.shape[:2]
    out = np.zeros_like(image)
    if abs(dx) >= w or abs(dy) >= h:
        return out
    out[max(dy, 0):h + min(dy, 0), max(dx, 0):w + min(dx, 0)] = image[max(-dy, 0):h - max(dy, 0),
                                                                      max(-dx, 0):w - max(dx, 0)]
    return out


@dataclass(frozen=True)
class GazeState:
    """The gaze at a display time: ``direction`` (unit (x, y, z), head frame; None: no valid sample yet),
    ``fixated`` (the direction of the last fixation, for ``hold``), ``saccade`` under way,
    ``valid``: the newest sample was valid."""

    direction: tuple[float, float, float] | None
    fixated: tuple[float, float, float] | None
    saccade: bool
    valid: bool


class GazeTracker:
    """Gaze samples in (ROS callbacks), the gaze at display time out (the display thread). The
    velocity between successive valid samples uses their stamps [s] (the sender's clock mapped
    onto ours: its timing, not the network's); ``now`` values are a monotonic clock of receipt."""

    def __init__(self, saccade_threshold_deg_s: float = SACCADE_THRESHOLD_DEG_S) -> None:
        self.threshold = float(saccade_threshold_deg_s)
        self._lock = threading.Lock()
        self._direction: tuple[float, float, float] | None = None
        self._fixated: tuple[float, float, float] | None = None
        self._stamp: float | None = None
        self._received = -math.inf
        self._saccade = False
        self._valid = False
        self._shown: tuple[tuple[float, float, float] | None, bool] = (None, False)
        self.samples = self.invalid = self.saccades = 0

    def add(self, stamp: float, direction, valid: bool, now: float) -> bool:
        """One sample (``direction`` ignored when not ``valid``); True when the display should show it
        at once (the gaze moved by more than :data:`VISIBLE_CHANGE_DEG`, or a saccade began or ended).
        Raises :class:`GazeError` for a valid sample that is not a direction."""
        d = unit_direction(direction) if valid else None
        with self._lock:
            self.samples += 1
            self._received = now
            self._valid = bool(valid)
            if d is None:
                self.invalid += 1
            else:
                moving = False
                if self._direction is not None and self._stamp is not None:
                    dt = stamp - self._stamp
                    if 0.0 < dt <= MAX_SAMPLE_GAP_S:
                        moving = angle_between_deg(self._direction, d) / dt > self.threshold
                if moving and not self._saccade:
                    self.saccades += 1
                    self._fixated = self._direction          # where the eye was before it jumped
                self._saccade = moving
                if not moving:
                    self._fixated = d
                self._direction, self._stamp = d, stamp
            return self._changed(now)

    def _changed(self, now: float) -> bool:
        state = self._state(now)
        shown_dir, shown_saccade = self._shown
        new_dir = state.direction
        moved = (shown_dir is None) != (new_dir is None) or (
            new_dir is not None and angle_between_deg(shown_dir, new_dir) > VISIBLE_CHANGE_DEG)
        if moved or shown_saccade != state.saccade:
            self._shown = (new_dir, state.saccade)
            return True
        return False

    def state(self, now: float) -> GazeState:
        with self._lock:
            return self._state(now)

    def _state(self, now: float) -> GazeState:
        saccade = self._saccade and now - self._received < MAX_SACCADE_S
        return GazeState(self._direction, self._fixated if saccade else self._direction, saccade, self._valid)


@dataclass(frozen=True)
class GazeDisplay:
    """What a display frame does with the gaze: the field's ``offset_px`` (whole px, x right, y
    down), the gaze rotation G for the sampling (``contingent``; None: straight ahead), ``blank``
    (no phosphenes: a saccade with ``saccade_display`` blank) and ``saccade`` under way."""

    offset_px: tuple[int, int] = (0, 0)
    sampling_rotation: np.ndarray | None = None
    blank: bool = False
    saccade: bool = False


NO_GAZE = GazeDisplay()


def gaze_display(mode: str, saccade_display: str, state: GazeState | None, focal_px: float) -> GazeDisplay:
    """The :class:`GazeDisplay` of ``state`` for ``gaze_mode`` ``mode`` and ``saccade_display``."""
    if mode not in GAZE_MODES:
        raise ValueError(f"gaze_mode must be one of {', '.join(GAZE_MODES)}, got {mode!r}")
    if saccade_display not in SACCADE_DISPLAYS:
        raise ValueError(f"saccade_display must be one of {', '.join(SACCADE_DISPLAYS)}, got {saccade_display!r}")
    if mode == "ignored" or state is None or state.direction is None:
        return NO_GAZE
    direction = state.fixated if state.saccade and saccade_display == "hold" else state.direction
    if direction is None:
        direction = state.direction
    dx, dy = field_offset_px(direction, focal_px)
    rotation = gaze_rotation_optical(direction) if mode == "contingent" else None
    if rotation is not None and angle_between_deg(direction, (1.0, 0.0, 0.0)) < 1e-6:
        rotation = None
    return GazeDisplay((int(round(dx)), int(round(dy))), rotation,
                       blank=state.saccade and saccade_display == "blank", saccade=state.saccade)
