"""Moving people: waypoint loops walked at constant speed (kinematic), and the capsule person's
body parts. No pybullet here; :mod:`raspv_sim.world_builder` creates and moves the bodies."""
from __future__ import annotations

import math

import numpy as np

from raspv_sim.primitives import LocalFrame, Part, shade
from raspv_sim.world_spec import PersonSpec

SKIN = (0.87, 0.7, 0.58)
TROUSERS = (0.18, 0.2, 0.3)
HAIR = (0.2, 0.14, 0.1)


class WaypointLoop:
    """A closed polyline (last point joins the first) walked at ``speed`` m/s from ``phase`` m."""

    def __init__(self, waypoints: tuple[tuple[float, float], ...], speed: float, phase: float = 0.0):
        pts = np.asarray(waypoints, dtype=float)
        nxt = np.roll(pts, -1, axis=0)
        seg = np.linalg.norm(nxt - pts, axis=1)
        keep = seg > 1e-9
        self.starts, self.ends, self.lengths = pts[keep], nxt[keep], seg[keep]
        self.cumulative = np.concatenate([[0.0], np.cumsum(self.lengths)])
        self.perimeter = float(self.cumulative[-1])
        self.speed, self.phase = float(speed), float(phase)

    def distance_at(self, t: float) -> float:
        """Distance walked [m] after ``t`` seconds (not wrapped)."""
        return self.phase + self.speed * t

    def pose_at(self, t: float) -> tuple[float, float, float]:
        """(x, y, heading [rad]) in W at time ``t`` [s]."""
        s = self.distance_at(t) % self.perimeter
        i = min(int(np.searchsorted(self.cumulative, s, side="right")) - 1, len(self.lengths) - 1)
        a = (s - self.cumulative[i]) / self.lengths[i]
        p = self.starts[i] + a * (self.ends[i] - self.starts[i])
        d = self.ends[i] - self.starts[i]
        return float(p[0]), float(p[1]), float(math.atan2(d[1], d[0]))


def capsule_person_parts(spec: PersonSpec) -> list[Part]:
    """A standing person of ``spec.height`` m facing +x, origin between the feet (local frame)."""
    f = LocalFrame((0.0, 0.0, 0.0), 0.0)
    H = spec.height
    leg = 0.47 * H
    head = 0.13 * H
    torso_top = H - head
    shirt = spec.color
    parts = [f.cylinder((0, sy * 0.09, leg / 2), 0.13, leg, TROUSERS) for sy in (-1, 1)]
    parts.append(f.capsule((0, 0, (leg + torso_top) / 2), 0.34, max(0.05, torso_top - leg - 0.34), shirt))
    arm = 0.36 * H
    parts += [f.capsule((0, sy * 0.24, torso_top - 0.06 - arm / 2), 0.09, arm - 0.09, shade(shirt, 0.9))
              for sy in (-1, 1)]
    parts.append(f.sphere((0, 0, H - head / 2), head, SKIN))
    parts.append(f.sphere((-0.015, 0, H - head * 0.4), head * 0.98, HAIR, collide=False))
    return parts
