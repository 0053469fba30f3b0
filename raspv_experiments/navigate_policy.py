"""``navigate``: the default virtual patient — walks to a goal seeing only the phosphenes (no rclpy).

What it knows besides the phosphene image (``/spv/frame``, ``/spv/map``) is what a person in
the experiment knows: which representation it is shown (the mode and overlays named in each
frame, as a subject is told the condition: a trail is looked for only when the ``path`` overlay
is on), its eye height and the head pitch it holds, where the goal is relative to
where it started (the instructions: "the far end of the hallway", "the bin in the meeting room",
as ``goal`` [m] in the start frame: x ahead, y left), and how it moved since — by path
integration of the commands its body carried out (motor noise is not felt, so the estimate
drifts as a person's does). It does not see the world, the camera or the map.

Each frame:

1. **A trail** (only with the navigation path overlay, which lights the path at full level and
   halves everything else): phosphenes clearly above half (``TRAIL_LEVEL``, and 75 % of the
   brightest seen lately) are a trail on the floor; it is followed by pure pursuit on the point about ``lookahead`` m ahead,
   and its direction remembered: when it leaves the view the subject turns back toward it.
2. **Obstacles**: phosphenes in the same image row look at the same floor distance (a level
   head), so the floor of a row has one brightness; whatever is brighter than that row's floor
   by ``contrast_threshold`` stands out — nearer than the floor in depth modes, walls and
   obstacles in Wall-Obstacles, bright objects in downsampling (dark ones do not stand out:
   that is the representation's weakness, not the subject's). The row's floor is the lower of
   its median now and its median over the last seconds (so a wall that fills a row still
   stands out while it comes nearer). Only what stands out in two frames running counts (one
   frame's perceptual noise is not an obstacle), and only what spans ``MIN_EXTENT_DEG`` of the
   view: one phosphene when they are that far apart, else it and a neighbour — a rule in visual
   angle, not in phosphenes, so the false alarms of perceptual noise do not grow with their
   number. An obstacle is placed where it meets the floor, as a person judges distance by where
   an object stands on the ground: in each image column, the lowest phosphene of a run that
   stands out, through its ray's floor point and the head pose (the phosphenes above it are the
   same obstacle's face, whose rays reach the floor far behind it: placing them there filled the
   free space behind every box with phantom obstacles, densely at high counts, sparsely at low
   ones). It is remembered for a few seconds in the path-integrated frame, so an obstacle that
   left the view is still walked around — as 5 cm floor cells, each with its latest sighting
   (a memory of the last 600 points, as before, forgot within a frame at 2500 phosphenes). What
   it remembers of a base is the floor patch where the base may be (:func:`footprints`): between
   that phosphene's ray and the ray of the one below it (which showed floor), half a spacing
   either side — a point with fine phosphenes, a patch half a metre deep with 4×4 — so a coarse
   view costs room, as blur does to a person, instead of a falsely exact position.
3. **Touch**: a bump (a collision the body feels: ``touch()``) is remembered as an obstacle just
   ahead, and it steps back for ``BACK_S`` and turns away from the side where it last saw more
   obstacles. (The other policies' "no optic flow" cue does not work here: on a featureless
   floor the view does not change while walking freely either.)
4. **Steering**: a route around everything it remembers, toward the goal (or back along a trail
   seen lately), planned on its own map (:func:`~raspv_experiments.perceived_map.plan_route`:
   the unseen is assumed open, obstacles kept at ``COMFORT`` where there is room and at the body's
   radius where there is not, the side of an obstacle once taken kept unless the other way is
   clearly shorter); it steers to the route point ``LOOKAHEAD`` m on, turning on the spot first
   when that is more than 45° away, at a speed that keeps ``COMMIT_S`` s to contact along the
   heading. (It used to take the free heading nearest the goal's direction, greedily: in the
   obstacle course's slalom that turned it on the spot in 25–60 % of its frames, most at high
   phosphene counts, where walls and boxes were seen best.)

Frames as in :mod:`raspv_experiments.policies`; the start frame: x ahead at the start, y left.
"""
from __future__ import annotations

import math

import numpy as np

from raspv_experiments.perceived_map import plan_route
from raspv_experiments.policies import PhospheneLayout, Policy, PolicyConfig, floor_points

BODY_RADIUS = 0.25                 # m, the avatar's body
AVOID_RANGE = 2.2                  # m: obstacles this near are remembered (+ 1 m) and looked at for speed
COMMIT_S = 2.0                     # s: time to contact kept along the heading taken (speed ≤ free distance / this)
COMFORT = 0.7                      # m from an obstacle's base where the route stops costing more (room permitting)
LOOKAHEAD = 0.8                    # m along the planned route: the point steered to
MEMORY_S = 4.0                     # s an obstacle out of view is remembered
MEMORY_CELL = 0.05                 # m: remembered obstacles are floor cells of this size (latest sighting each), so
                                   # what is remembered does not depend on how many phosphenes showed it
FLOOR_TAU_S = 1.5                  # s: time constant of a row's floor brightness over time
TRAIL_MEMORY_S = 6.0               # s: turns back toward a trail seen this recently
BACK_S = 0.8                       # s stepping back after a bump
MIN_EXTENT_DEG = 3.0               # what stands out must span this much of the view (10 cm at 2 m): one phosphene
                                   # when they are this far apart, else it and a neighbour (so the false alarms of
                                   # perceptual noise do not grow with the number of phosphenes)
TRAIL_LEVEL = 0.78                 # the path overlay lights the path at full level (1) and halves the rest (≤ 4/7 with
                                   # 8 levels): a trail is brighter than midway, with room for perceptual noise


def _wrap(a: float | np.ndarray):
    return (np.asarray(a) + math.pi) % (2 * math.pi) - math.pi


def _spacing(layout: PhospheneLayout) -> float:
    """Median distance from a phosphene to its nearest neighbour [px]."""
    pts = np.column_stack([layout.x, layout.y])
    n = len(pts)
    if n < 2:
        return 1.0
    sample = pts if n <= 1500 else pts[np.linspace(0, n - 1, 1500).astype(int)]
    d = np.hypot(*(sample[:, None, :] - pts[None, :, :]).transpose(2, 0, 1))
    d[d == 0] = np.inf
    return max(float(np.median(d.min(axis=1))), 1e-6)


def free_distance(rel: np.ndarray, headings: np.ndarray, radius: float, reach: float) -> np.ndarray:
    """(H,) how far the body (a disc of ``radius`` [m]) can walk along each heading [rad, body
    frame] before it touches one of the obstacle points ``rel`` (M, 2) [m, body frame: x ahead,
    y left]; ``reach`` where nothing is in the way (0 where the body already touches one)."""
    if len(rel) == 0:
        return np.full(len(headings), float(reach))
    ch, sh = np.cos(headings), np.sin(headings)
    along = rel[:, :1] * ch + rel[:, 1:] * sh                # (M, H)
    across = -rel[:, :1] * sh + rel[:, 1:] * ch
    inside = np.abs(across) < radius
    touch = along - np.sqrt(np.maximum(radius ** 2 - across ** 2, 0.0))
    touch = np.where(inside & (along > -radius), touch, np.inf)
    return np.clip(touch.min(axis=0), 0.0, float(reach))


def row_bands(layout: PhospheneLayout) -> np.ndarray:
    """(N,) band index of each phosphene: phosphenes in one image row (±0.35 of the spacing)."""
    if len(layout.x) < 2:
        return np.zeros(len(layout.x), int)
    return np.round((layout.y - layout.y.min()) / (0.7 * _spacing(layout))).astype(int)


def neighbours(layout: PhospheneLayout, radius_spacings: float = 1.5):
    """(N, N) sparse 0/1 matrix: phosphenes within ``radius_spacings`` of the spacing of each other
    (a grid's 8 neighbours), not itself."""
    from scipy.sparse import coo_matrix
    from scipy.spatial import cKDTree

    n = len(layout.x)
    pairs = (cKDTree(np.column_stack([layout.x, layout.y])).query_pairs(radius_spacings * _spacing(layout),
                                                                       output_type="ndarray")
             if n > 1 else np.empty((0, 2), int))
    i = np.concatenate([pairs[:, 0], pairs[:, 1]])
    j = np.concatenate([pairs[:, 1], pairs[:, 0]])
    return coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n)).tocsr()


def phosphene_below(layout: PhospheneLayout) -> np.ndarray:
    """(N,) index of the nearest phosphene below each one in its image column (within ±0.35 of
    the spacing across, at most 2.5 spacings down), −1 where there is none (the lowest of the column)."""
    n = len(layout.x)
    below = np.full(n, -1)
    if n < 2:
        return below
    spacing = _spacing(layout)
    column = np.round((layout.x - layout.x.min()) / (0.7 * spacing)).astype(int)
    for c in np.unique(column):
        idx = np.flatnonzero(column == c)
        idx = idx[np.argsort(layout.y[idx])]                 # top to bottom (y down)
        gap = np.diff(layout.y[idx])
        ok = gap <= 2.5 * spacing
        below[idx[:-1][ok]] = idx[1:][ok]
    return below


def footprints(layout: PhospheneLayout, config: PolicyConfig) -> tuple[np.ndarray, np.ndarray]:
    """Where on the floor the base of an obstacle may be when phosphene i is the lowest of its
    column that stands out: anywhere between its own ray and the ray of the phosphene below
    (which showed floor), within half a spacing either side — sampled as (P, 2) floor points
    [m, body frame: x ahead, y left] with the (P,) phosphene each belongs to. A coarse grid
    leaves a large patch (4×4 phosphenes in 35°: about 0.35 m across and 0.5 m deep at 2 m), a
    fine one a point: the subject keeps away from everywhere the obstacle may be."""
    n = len(layout.x)
    spacing = _spacing(layout) if n > 1 else 1.0
    k = int(np.clip(np.ceil(spacing / 3.0), 1, 9))            # sub-rays per axis, ≈ 3 image px apart
    across = (np.linspace(-0.5, 0.5, k) if k > 1 else np.zeros(1)) * spacing
    down = (np.linspace(0.0, 1.0, k) if k > 1 else np.zeros(1)) * spacing
    dx, dy = (a.ravel() for a in np.meshgrid(across, down))
    sub = PhospheneLayout(np.repeat(layout.x, len(dx)) + np.tile(dx, n), np.repeat(layout.y, len(dy)) + np.tile(dy, n),
                          layout.width, layout.height, layout.focal_px)
    owner = np.repeat(np.arange(n), len(dx))
    _, ground = floor_points(sub, config)
    ok = np.isfinite(ground[:, 0])
    return ground[ok], owner[ok]


class Navigate(Policy):
    name = "navigate"
    BASES_ONLY = True            # remember only each obstacle's base (see the module docstring)
    FOOTPRINTS = True            # remember the whole floor patch where the base may be (see footprints())

    def __init__(self, layout: PhospheneLayout, config: PolicyConfig | None = None,
                 goal: tuple[float, float] | None = None, **_) -> None:
        super().__init__(layout, config)
        self.goal = None if goal is None else np.asarray(goal, float)      # start frame [m]
        self.bands = row_bands(layout)
        self.band_ids = np.unique(self.bands)
        self.floor_ref = np.full(self.band_ids.max() + 1, np.nan)
        self.bearing = np.arctan2(self.ground[:, 1], self.ground[:, 0])    # NaN above the horizon
        self._standing_out = np.zeros(len(layout.x), bool)     # stood out in the previous frame
        self._below = phosphene_below(layout)
        spacing_deg = math.degrees(_spacing(layout) / layout.focal_px) if len(layout.x) > 1 else 180.0
        self._support = 0 if spacing_deg >= MIN_EXTENT_DEG else 1     # neighbours that must stand out too
        self._neighbours = neighbours(layout) if self._support else None
        self._footprint, self._footprint_of = footprints(layout, self.config)
        self._aim: np.ndarray | None = None            # the route point steered to last frame (start frame)
        self.pose = np.zeros(3)                        # path-integrated x, y [m], heading [rad] (start frame)
        self.memory: list[tuple[float, float, float]] = []      # obstacles: (x, y, t) in the start frame
        self._cells: dict[tuple[int, int], float] = {}          # the same, by MEMORY_CELL cell: last seen [s]
        self.peak = 0.0
        self.trail_heading: float | None = None        # start-frame heading where the trail was last seen
        self.trail_t = -math.inf
        self._touched = False
        self._back_until = -math.inf
        self._back_turn = 0.0

    def touch(self) -> None:
        """The body bumped into something (felt, not seen)."""
        self._touched = True

    def unblock(self, b: np.ndarray) -> tuple[float, float] | None:
        t = self.t or 0.0
        if self._touched:
            self._touched = False
            if t >= self._back_until:
                x, y, h = self.pose
                cs, sn = math.cos(h), math.sin(h)
                felt = (x + (BODY_RADIUS + MEMORY_CELL) * cs, y + (BODY_RADIUS + MEMORY_CELL) * sn)
                self._cells[tuple(np.round(np.array(felt) / MEMORY_CELL).astype(int))] = t    # felt: remembered too
                left = sum(1 for mx, my, _ in self.memory if -sn * (mx - x) + cs * (my - y) > 0)
                right = len(self.memory) - left
                side = (-1.0 if left > right else 1.0) if left != right else float(self.rng.choice([-1.0, 1.0]))
                self._back_until, self._back_turn = t + BACK_S, side
        if t < self._back_until:
            return -0.4 * self.config.max_linear, 0.8 * self.config.max_angular * self._back_turn
        return None

    # -- perception ----------------------------------------------------------------------------
    def trail(self, b: np.ndarray) -> np.ndarray:
        """Indices of the trail on the floor (with the path overlay on: it lights the path at full
        level and halves everything else, so the trail is what is clearly above half)."""
        top = float(b.max()) if len(b) else 0.0
        self.peak = max(top, self.peak * 0.97)
        if top <= 0.0 or "path" not in self.overlays:
            return np.empty(0, int)
        bright = (b >= TRAIL_LEVEL) & (b >= 0.75 * self.peak)
        if bright.sum() < 2:
            return np.empty(0, int)
        return np.flatnonzero(bright & np.isfinite(self.ground_distance))

    def obstacles(self, b: np.ndarray, exclude: np.ndarray) -> np.ndarray:
        """Indices of phosphenes that stand out from their row's floor (see the module docstring)."""
        alpha = 1.0 - math.exp(-self.dt / FLOOR_TAU_S) if self.dt > 0 else 0.0
        ref = np.zeros(len(self.floor_ref))
        for band in self.band_ids:
            m = self.bands == band
            now = float(np.median(b[m]))
            old = self.floor_ref[band]
            self.floor_ref[band] = now if math.isnan(old) else old + alpha * (now - old)
            ref[band] = min(now, self.floor_ref[band])
        floor = np.maximum(ref[self.bands], self.config.min_brightness)     # at the threshold is not standing out
        out = (b > 0) & (b >= floor + self.config.contrast_threshold) & np.isfinite(self.ground_distance)
        out[exclude] = False
        seen, self._standing_out = out & self._standing_out, out
        if self._support:                    # smaller than MIN_EXTENT_DEG: one phosphene's noise, not an obstacle
            seen &= (self._neighbours @ seen.astype(float)) >= self._support
        if self.BASES_ONLY:                  # an obstacle is where it meets the floor: the lowest of each run
            has = self._below >= 0
            base = seen.copy()
            base[has] &= ~seen[self._below[has]]
            seen = base
        return np.flatnonzero(seen)

    # -- the decision ---------------------------------------------------------------------------
    def executed(self, v: float, w: float) -> None:
        x, y, h = self.pose
        h += w * self.dt
        self.pose = np.array([x + v * self.dt * math.cos(h), y + v * self.dt * math.sin(h), float(_wrap(h))])

    def _remember(self, idx: np.ndarray) -> None:
        t = self.t or 0.0
        x, y, h = self.pose
        c, s = math.cos(h), math.sin(h)
        near = idx[self.ground_distance[idx] < AVOID_RANGE + 1.0]
        g = self._footprint[np.isin(self._footprint_of, near)] if self.FOOTPRINTS else self.ground[near]
        cells = np.round(np.column_stack([x + c * g[:, 0] - s * g[:, 1], y + s * g[:, 0] + c * g[:, 1]])
                         / MEMORY_CELL).astype(int)
        for key in map(tuple, cells):
            self._cells[key] = t
        self._cells = {k: seen for k, seen in self._cells.items() if t - seen <= MEMORY_S}
        self.memory = [(i * MEMORY_CELL, j * MEMORY_CELL, seen) for (i, j), seen in self._cells.items()]

    def _desired(self) -> float:
        """Desired heading relative to the body [rad]: back to the trail, else to the goal, else ahead."""
        x, y, h = self.pose
        if self.trail_heading is not None and (self.t or 0.0) - self.trail_t <= TRAIL_MEMORY_S:
            return float(_wrap(self.trail_heading - h))
        if self.goal is not None:
            return float(_wrap(math.atan2(self.goal[1] - y, self.goal[0] - x) - h))
        return float(_wrap(-h))

    def _target(self) -> np.ndarray:
        """Where the route leads [m, start frame]: back along a trail seen lately, else the goal,
        else ahead as at the start."""
        x, y, h = self.pose
        if self.trail_heading is not None and (self.t or 0.0) - self.trail_t <= TRAIL_MEMORY_S:
            return np.array([x + 3.0 * math.cos(self.trail_heading), y + 3.0 * math.sin(self.trail_heading)])
        if self.goal is not None:
            return self.goal
        return np.array([x + 3.0, y])

    def decide(self, b: np.ndarray) -> tuple[float, float]:
        c = self.config
        x, y, h = self.pose
        idx = self.trail(b)
        obstacles = self.obstacles(b, idx)
        self._remember(obstacles)
        if len(idx):
            d = self.ground_distance[idx]
            near = np.abs(d - c.lookahead) <= 0.5
            pick = idx[near] if near.any() else idx[[int(np.argmin(np.abs(d - c.lookahead)))]]
            gx, gy = (self.ground[pick] * b[pick, None]).sum(axis=0) / b[pick].sum()
            bearing = math.atan2(gy, gx)
            self.trail_heading, self.trail_t = float(_wrap(h + bearing)), self.t or 0.0
            self._aim = None
            if abs(bearing) > math.radians(50):
                return 0.0, c.max_angular * math.copysign(1.0, bearing)
            v = c.max_linear * max(0.2, math.cos(bearing) ** 2)
            return v, 2.0 * v * math.sin(bearing) / max(math.hypot(gx, gy), 0.3)
        goal_dist = math.inf if self.goal is None else math.hypot(self.goal[0] - x, self.goal[1] - y)
        seen = np.array([(mx, my) for mx, my, _ in self.memory]) if self.memory else np.empty((0, 2))
        route = plan_route(self.pose[:2], self._target(), seen, BODY_RADIUS, COMFORT, keep=self._aim)
        cs, sn = math.cos(h), math.sin(h)
        rel = (seen - [x, y]) @ np.array([[cs, -sn], [sn, cs]])            # body frame: x ahead, y left
        self._aim = None
        if not route.reachable:                           # no way out of what it saw: turn toward the freer side
            side = -1.0 if (rel[:, 1] > 0).sum() > len(rel) / 2 else 1.0
            return 0.0, 0.8 * c.max_angular * side
        along = np.hypot(*np.diff(route.points, axis=0).T).cumsum() if len(route.points) > 1 else np.zeros(0)
        k = int(np.searchsorted(along, LOOKAHEAD)) + 1 if len(along) else 0
        self._aim = route.points[min(k, len(route.points) - 1)]
        px, py = self._aim - [x, y]
        heading = float(_wrap(math.atan2(py, px) - h)) if math.hypot(px, py) > 1e-6 else self._desired()
        if abs(heading) > math.radians(45):
            return 0.0, c.max_angular * math.copysign(1.0, heading)
        free = float(free_distance(rel, np.array([heading]), BODY_RADIUS, AVOID_RANGE)[0])
        v = min(c.max_linear, free / COMMIT_S) * max(0.3, math.cos(heading) ** 2)
        if goal_dist < 1.0:
            v = min(v, max(0.2, goal_dist) * c.max_linear)
        return v, float(np.clip(1.8 * heading, -c.max_angular, c.max_angular))
