"""BlindBot: the kinematic avatar of the subject in the virtual world.

Base frame B: x forward, y left, z up, origin on the ground between the feet. The base is a
differential drive (linear v along x, angular ω about z) that goes exactly where commanded
unless its human-sized collision body (a vertical cylinder from just above the
highest walkable step to the top of the head) would enter an object: every move is cut into short
sub-steps, each checked with PyBullet distance queries against the bodies nearby, so it cannot
pass through walls; when blocked it slides along the obstacle (optional) or stops in contact.
It follows the ground up and down steps no higher than ``max_step`` (stairs) and refuses to
walk off higher edges. The head turns relative to the base (roll, pitch, yaw about a neck pivot);
the camera sits at ``eye_height`` above the feet when the head is level.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pybullet

from raspv_common.frames import LINK_FROM_OPTICAL
from raspv_common.rotations import head_angles, head_quaternion  # noqa: F401  (re-exported)
from raspv_sim.world_builder import BuiltWorld

SUBSTEP = 0.05            # m, longest straight move checked at once
GROUND_PROBE_GAP = 0.01   # m, between the top of the ground probe and the bottom of the body
MAX_PEOPLE_UNDERFOOT = 8  # person surfaces the ground probe looks through before giving up
# optical frame (x right, y down, z forward) expressed in the head frame (x forward, y left, z up)
HEAD_FROM_OPTICAL = LINK_FROM_OPTICAL[:3, :3]


@dataclass(frozen=True)
class AvatarConfig:
    """Body and limits. Lengths in m, speeds in m/s and rad/s."""

    body_radius: float = 0.25
    body_height: float = 1.8          # top of the collision body above the feet
    eye_height: float = 1.6
    neck_to_eye: tuple[float, float, float] = (0.08, 0.0, 0.10)   # eye from the neck pivot, head frame
    max_linear: float = 1.5
    max_angular: float = 1.5
    max_step: float = 0.2             # highest step up or down it walks over
    contact_margin: float = 0.02      # closer than this to an object counts as touching it
    slide: bool = True                # slide along obstacles instead of stopping dead

    def __post_init__(self) -> None:
        if self.body_radius <= 0 or self.max_linear < 0 or self.max_angular < 0 or self.max_step < 0:
            raise ValueError("body radius must be positive and limits non-negative")
        if self.body_height <= self.max_step + GROUND_PROBE_GAP + 0.5:
            raise ValueError(f"body height {self.body_height} m is too short above a {self.max_step} m step")
        if not 0 < self.eye_height - self.neck_to_eye[2] < self.body_height + 0.5:
            raise ValueError(f"eye height {self.eye_height} m does not fit the body")


@dataclass(frozen=True)
class Contact:
    """The avatar touching (or blocked by) body ``uid``: closest point on the avatar and the
    normal from the object to the avatar, both in W; ``distance`` < 0 means overlap [m]."""

    uid: int
    position: tuple[float, float, float]
    normal: tuple[float, float, float]
    distance: float


@dataclass
class MoveResult:
    distance: float                         # m travelled by the base in this step
    blocked_by: Contact | None = None       # the object that stopped (part of) the move
    drop: bool = False                      # stopped at an edge higher than max_step
    contacts: list[Contact] = field(default_factory=list)


def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def quaternion_matrix(q) -> np.ndarray:
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


class Avatar:
    """The avatar's body in a built world (one cylinder body in the same PyBullet client)."""

    def __init__(self, world: BuiltWorld, config: AvatarConfig, x: float, y: float, yaw: float):
        self.world, self._config = world, config
        self.c = world.client
        c = config
        self._bottom = c.max_step + GROUND_PROBE_GAP          # body bottom above the feet
        self._centre = (self._bottom + c.body_height) / 2
        # a vertical cylinder: a flat bottom (feet) meets a step edge at once, unlike a capsule's round end
        shape = self.c.createCollisionShape(pybullet.GEOM_CYLINDER, radius=c.body_radius,
                                            height=c.body_height - self._bottom)
        self.uid = self.c.createMultiBody(0, shape, -1, basePosition=[x, y, self._centre])
        self.c.setCollisionFilterGroupMask(self.uid, -1, 0, 0)   # invisible to rays and the world
        world.finish(extra_uids=(self.uid,))
        self.x, self.y, self.yaw = float(x), float(y), float(yaw)
        self.z = 0.0
        ground = self._ground(self.x, self.y, 0.5)
        self.z = ground if ground is not None else 0.0
        self.head = (0.0, 0.0, 0.0, 1.0)
        self.path_length = 0.0
        self._place(self.x, self.y, self.z)

    @property
    def config(self) -> AvatarConfig:
        return self._config

    @config.setter
    def config(self, new: AvatarConfig) -> None:
        """Limits, eye height and sliding may change; the body's shape is fixed at creation."""
        old = self._config
        if (new.body_radius, new.body_height, new.max_step) != (old.body_radius, old.body_height, old.max_step):
            raise ValueError("body_radius, body_height and max_step are fixed once the avatar exists")
        self._config = new

    # -- poses ----------------------------------------------------------------------------------
    def world_from_base(self) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = quaternion_matrix(yaw_quaternion(self.yaw))
        T[:3, 3] = (self.x, self.y, self.z)
        return T

    def base_from_head(self) -> np.ndarray:
        """The head frame (neck pivot, turned by the head orientation) in B: the tf ``base_link → head``."""
        c = self.config
        T = np.eye(4)
        T[:3, :3] = quaternion_matrix(self.head)
        T[:3, 3] = (0.0, 0.0, c.eye_height - c.neck_to_eye[2])
        return T

    def head_from_camera_link(self) -> np.ndarray:
        """The camera body (eye, x forward, z up) in the head frame: the fixed tf ``head → camera_link``."""
        T = np.eye(4)
        T[:3, 3] = self.config.neck_to_eye
        return T

    def base_from_camera(self) -> np.ndarray:
        """Camera optical frame in B (neck pivot, head rotation, eye offset)."""
        T = self.base_from_head() @ self.head_from_camera_link()
        T[:3, :3] = T[:3, :3] @ HEAD_FROM_OPTICAL
        return T

    def world_from_camera(self) -> np.ndarray:
        return self.world_from_base() @ self.base_from_camera()

    def set_head(self, q) -> None:
        """Head orientation relative to the base, quaternion (x, y, z, w); identity looks ahead."""
        q = np.asarray(q, dtype=float)
        n = float(np.linalg.norm(q))
        if q.shape != (4,) or not math.isfinite(n) or n < 1e-9:
            raise ValueError(f"head orientation must be a non-zero quaternion (x, y, z, w), got {q.tolist()}")
        self.head = tuple(float(v) for v in q / n)

    def teleport(self, x: float, y: float, yaw: float) -> None:
        """Put the base at (x, y) on the ground below, facing ``yaw`` [rad] (no collision check)."""
        ground = self._ground(x, y, 2.0)
        self.x, self.y, self.yaw, self.z = float(x), float(y), float(yaw), ground if ground is not None else 0.0
        self._place(self.x, self.y, self.z)

    def placement_problem(self) -> str | None:
        """Why the avatar cannot stand where it is (no floor below, overlapping an object), or None."""
        if self._ground(self.x, self.y, self.config.max_step) is None:
            return "has no floor under it (within the step height of z = 0)"
        overlaps = [k for k in self._closest(self.x, self.y, self.z, 0.0) if k.distance < -0.005]
        self._place(self.x, self.y, self.z)
        if overlaps:
            info = self.world.bodies[min(overlaps, key=lambda k: k.distance).uid]
            return f"overlaps {info.cls} '{info.name}' (its body is a {self.config.body_radius} m radius cylinder)"
        return None

    # -- motion ---------------------------------------------------------------------------------
    def move(self, linear: float, angular: float, dt: float) -> MoveResult:
        """Integrate (v [m/s], ω [rad/s]) for ``dt`` s within the limits; returns what happened."""
        c = self.config
        v = max(-c.max_linear, min(c.max_linear, float(linear)))
        w = max(-c.max_angular, min(c.max_angular, float(angular)))
        total = abs(v) * dt
        n = max(1, math.ceil(total / SUBSTEP), math.ceil(abs(w) * dt / 0.1))
        result = MoveResult(0.0)
        for _ in range(n):
            self.yaw = (self.yaw + w * dt / n + math.pi) % (2 * math.pi) - math.pi
            if total == 0.0 or result.blocked_by is not None or result.drop:
                continue
            step = v * dt / n
            moved = self._translate(step * math.cos(self.yaw), step * math.sin(self.yaw), result)
            result.distance += moved
        self.path_length += result.distance
        self._place(self.x, self.y, self.z)
        result.contacts = self.contacts()
        if result.blocked_by is not None and all(k.uid != result.blocked_by.uid for k in result.contacts):
            result.contacts.append(result.blocked_by)
        return result

    def _translate(self, dx: float, dy: float, result: MoveResult) -> float:
        """Move by (dx, dy) as far as free; slides once along a blocking object. Returns metres moved."""
        ok, z, blocker = self._try(self.x + dx, self.y + dy)
        if ok:
            return self._commit(self.x + dx, self.y + dy, z)
        if blocker is None:
            result.drop = True
            return self._approach(dx, dy)
        result.blocked_by = blocker
        if self.config.slide:
            n = np.array(blocker.normal[:2])
            norm = float(np.linalg.norm(n))
            if norm > 1e-6:
                n /= norm
                m = np.array([dx, dy])
                into = float(m @ n)
                if into < 0:
                    sx, sy = m - into * n
                    if math.hypot(sx, sy) > 1e-6:
                        ok, z, _ = self._try(self.x + sx, self.y + sy)
                        if ok:
                            return self._commit(self.x + sx, self.y + sy, z)
        return self._approach(dx, dy)

    def _approach(self, dx: float, dy: float) -> float:
        """Go the largest free fraction of (dx, dy) (bisection), ending close to the obstacle."""
        lo, hi, best_z = 0.0, 1.0, None
        for _ in range(6):
            mid = (lo + hi) / 2
            ok, z, _ = self._try(self.x + dx * mid, self.y + dy * mid)
            if ok:
                lo, best_z = mid, z
            else:
                hi = mid
        if lo == 0.0 or best_z is None:
            self._place(self.x, self.y, self.z)
            return 0.0
        return self._commit(self.x + dx * lo, self.y + dy * lo, best_z)

    def _commit(self, x: float, y: float, z: float) -> float:
        d = math.sqrt((x - self.x) ** 2 + (y - self.y) ** 2 + (z - self.z) ** 2)
        self.x, self.y, self.z = x, y, z
        return d

    def _try(self, x: float, y: float) -> tuple[bool, float, Contact | None]:
        """Whether the base can stand at (x, y): (free, ground z, the worst blocking contact).
        A move into an object is refused unless it does not deepen an existing overlap (so
        the avatar can always back away from a person who walked into it)."""
        z = self._ground(x, y, self.config.max_step)
        if z is None:
            return False, self.z, None
        before = {k.uid: k.distance for k in self._closest(self.x, self.y, self.z, margin=0.0)}
        worst = None
        for k in self._closest(x, y, z, margin=0.0):
            if k.distance < -1e-4 and k.distance < before.get(k.uid, 0.0) - 1e-6:
                if worst is None or k.distance < worst.distance:
                    worst = k
        self._place(self.x, self.y, self.z)
        return worst is None, z, worst

    def _ground(self, x: float, y: float, reach: float) -> float | None:
        """Height of the walkable surface under (x, y) within ±``reach`` m of the feet, or None.
        People are not ground: the probe looks through a person's feet (a walk teleported onto
        a walker stood on its shoes, 0.15-0.4 m up)."""
        top = self.z + self.config.max_step + GROUND_PROBE_GAP / 2
        bottom = self.z - reach - 1e-3
        for _ in range(MAX_PEOPLE_UNDERFOOT):
            hit = self.c.rayTest([x, y, top], [x, y, bottom])[0]
            if hit[0] < 0 or hit[0] == getattr(self, "uid", None):
                return None
            info = self.world.bodies.get(hit[0])
            if info is None or info.kind != "person":
                return float(hit[3][2])
            top = float(hit[3][2]) - 1e-3           # inside the person: a ray leaving a body reports no hit
        return None

    def _place(self, x: float, y: float, z: float) -> None:
        self.c.resetBasePositionAndOrientation(self.uid, [x, y, z + self._centre], [0.0, 0.0, 0.0, 1.0])

    def _closest(self, x: float, y: float, z: float, margin: float) -> list[Contact]:
        """Nearest point of every body within ``margin`` m of the body standing at (x, y, z)."""
        self._place(x, y, z)
        r = self.config.body_radius + margin
        lo = [x - r, y - r, z + self._bottom - margin]
        hi = [x + r, y + r, z + self.config.body_height + margin]
        nearby = {uid for uid, _ in (self.c.getOverlappingObjects(lo, hi) or ()) if uid != self.uid}
        out = []
        for uid in nearby:
            if uid not in self.world.bodies or not self.world.bodies[uid].collide:
                continue
            points = self.c.getClosestPoints(self.uid, uid, margin)
            if points:
                p = min(points, key=lambda q: q[8])
                out.append(Contact(uid, tuple(p[5]), tuple(p[7]), float(p[8])))
        return out

    def contacts(self) -> list[Contact]:
        """Objects within ``contact_margin`` of the body where it stands now."""
        return self._closest(self.x, self.y, self.z, self.config.contact_margin)
