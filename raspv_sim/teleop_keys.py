"""Keyboard teleoperation logic (no terminal, no rclpy): keys → base velocity and head orientation.

The movement keys and speed keys are those of ROS's ``teleop_twist_keyboard``; the arrow keys
turn the head (the headset's job in a real session)::

    Move the body:            Turn the head:            Speeds (x 1.1 / x 0.9):
       u    i    o               arrows: yaw / pitch       q/z  all
       j    k    l               [ / ]: roll               w/x  linear only
       m    ,    .               h: look straight ahead    e/c  angular only
    k or space: stop; any other key stops too.

A motion key keeps the avatar moving for ``key_timeout`` seconds (longer than the keyboard's
auto-repeat delay, so holding a key walks smoothly); ``key_timeout`` = 0 keeps it moving until
another key is pressed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

HELP = __doc__.split("::", 1)[1].split("\nA motion key", 1)[0].strip("\n")

MOVES: dict[str, tuple[int, int]] = {   # key → (forward sign, left-turn sign)
    "i": (1, 0), "o": (1, -1), "j": (0, 1), "l": (0, -1), "u": (1, 1),
    ",": (-1, 0), ".": (-1, 1), "m": (-1, -1), "k": (0, 0), " ": (0, 0),
}
SPEEDS: dict[str, tuple[float, float]] = {   # key → (linear factor, angular factor)
    "q": (1.1, 1.1), "z": (0.9, 0.9), "w": (1.1, 1.0), "x": (0.9, 1.0), "e": (1.0, 1.1), "c": (1.0, 0.9),
}
HEAD: dict[str, tuple[int, int, int]] = {    # key → (roll, pitch, yaw) step signs; pitch > 0 looks down
    "up": (0, -1, 0), "down": (0, 1, 0), "left": (0, 0, 1), "right": (0, 0, -1), "[": (-1, 0, 0), "]": (1, 0, 0),
}
_ESCAPES = {"[A": "up", "[B": "down", "[C": "right", "[D": "left", "OA": "up", "OB": "down", "OC": "right", "OD": "left"}


class KeyDecoder:
    """Turns raw terminal bytes into key names: printable characters as themselves, arrow
    escape sequences as "up", "down", "left", "right", Ctrl-C as "ctrl-c", a lone ESC as "esc"."""

    def __init__(self) -> None:
        self._pending = ""

    def feed(self, data: bytes) -> list[str]:
        text = self._pending + data.decode("utf-8", errors="ignore")
        self._pending = ""
        keys: list[str] = []
        i = 0
        while i < len(text):
            ch = text[i]
            if ch == "\x1b":
                seq = text[i + 1:i + 3]
                if len(seq) < 2 and i + 1 + len(seq) == len(text) and (seq in ("", "[", "O")):
                    self._pending = text[i:]        # wait for the rest of the sequence
                    break
                if seq in _ESCAPES:
                    keys.append(_ESCAPES[seq])
                    i += 3
                    continue
                keys.append("esc")
            elif ch == "\x03":
                keys.append("ctrl-c")
            else:
                keys.append(ch)
            i += 1
        return keys

    def flush(self) -> list[str]:
        """Keys still pending (a lone ESC once no more bytes came)."""
        keys = ["esc"] if self._pending.startswith("\x1b") else []
        self._pending = ""
        return keys


@dataclass
class TeleopConfig:
    linear_speed: float = 0.5        # m/s
    angular_speed: float = 1.0       # rad/s
    key_timeout: float = 0.7         # s, 0 = latch
    head_step_deg: float = 5.0
    max_head_yaw_deg: float = 90.0
    max_head_pitch_deg: float = 70.0
    max_head_roll_deg: float = 40.0


class TeleopKeys:
    """State machine of the keyboard: feed it keys with their time, read velocity and head."""

    def __init__(self, config: TeleopConfig | None = None):
        self.config = config or TeleopConfig()
        self.linear_speed = self.config.linear_speed
        self.angular_speed = self.config.angular_speed
        self.motion = (0, 0)
        self.last_motion_t = -math.inf
        self.head_deg = [0.0, 0.0, 0.0]   # roll, pitch, yaw relative to the base
        self.quit = False

    def handle(self, key: str, now: float) -> str:
        """Apply one key pressed at time ``now`` [s]; returns a short status text."""
        c = self.config
        if key in ("ctrl-c",):
            self.quit = True
            self.motion = (0, 0)
            return "quit"
        if key in MOVES:
            self.motion = MOVES[key]
            self.last_motion_t = now
        elif key in SPEEDS:
            fl, fa = SPEEDS[key]
            self.linear_speed *= fl
            self.angular_speed *= fa
        elif key in HEAD:
            step = c.head_step_deg
            limits = (c.max_head_roll_deg, c.max_head_pitch_deg, c.max_head_yaw_deg)
            for i, sign in enumerate(HEAD[key]):
                self.head_deg[i] = max(-limits[i], min(limits[i], self.head_deg[i] + sign * step))
        elif key == "h":
            self.head_deg = [0.0, 0.0, 0.0]
        else:
            self.motion = (0, 0)
        return self.status(now)

    def velocity(self, now: float) -> tuple[float, float]:
        """(linear m/s, angular rad/s) to command at time ``now``."""
        timeout = self.config.key_timeout
        if timeout > 0 and now - self.last_motion_t > timeout:
            self.motion = (0, 0)
        return self.motion[0] * self.linear_speed, self.motion[1] * self.angular_speed

    def head_angles(self) -> tuple[float, float, float]:
        """(roll, pitch, yaw) of the head relative to the base [rad]."""
        return tuple(math.radians(v) for v in self.head_deg)  # type: ignore[return-value]

    def status(self, now: float) -> str:
        v, w = self.velocity(now)
        r, p, y = self.head_deg
        return (f"speed {self.linear_speed:.2f} m/s, turn {self.angular_speed:.2f} rad/s | moving v={v:+.2f} "
                f"w={w:+.2f} | head roll {r:+.0f}° pitch {p:+.0f}° yaw {y:+.0f}°")
