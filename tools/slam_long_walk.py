"""A walk of ten minutes and more that keeps going through new places, for SLAM's memory (issue 32).

The shipped worlds are at most 20 m × 14 m: a ten-minute walk in them repeats its route, and a
map that sees the same places again reuses its keyframes instead of growing. This tool writes a
building of ``rows`` × ``columns`` rooms (``room`` metres each, every room another wall colour,
its own furniture against its north and south walls, surface textures and notices as every
world) with a corridor along its west side, and a walk through it: room after room along each
row (a door in every shared wall, the rows joined by a door at the row's end, serpentine), then
out of the last room into the corridor and back along it to the start — one loop, closed at the
very end. Every room is entered once. Writes ``OUT/building.yaml`` (a world file, docs/sim.md)
and ``OUT/walk.yaml`` (a walk, ``raspv sim walk OUT/walk.yaml -o SEQ`` renders it).

    python tools/slam_long_walk.py walks/long_building          # 8 × 7 rooms of 10 m × 5 m, 10 Hz
    raspv sim walk walks/long_building/walk.yaml -o walks/long_walk

World frame W: x east, y north, metres; the corridor is x ∈ [0, 2], the rooms start at x = 2.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import yaml

CORRIDOR = 2.0              # [m] wide, along the west side
DOOR = 0.9                  # [m] door openings (no leaves: nothing swings into the walk)
LOW, HIGH = 1.3, 3.7        # door offsets from a room's south wall [m] (the walk crosses the room diagonally)
PALETTE = [(0.92, 0.91, 0.88), (0.86, 0.83, 0.74), (0.78, 0.84, 0.88), (0.88, 0.8, 0.78), (0.8, 0.86, 0.78),
           (0.9, 0.86, 0.7), (0.75, 0.75, 0.8), (0.93, 0.84, 0.84), (0.82, 0.78, 0.72), (0.7, 0.8, 0.76)]
# furniture against a wall: (type, size along the wall, depth from it, height, class)
PIECES = [("table", 1.6, 0.8, 0.74, None), ("shelf", 1.0, 0.35, 1.8, None), ("sofa", 2.0, 0.9, 0.85, None),
          ("bed", 2.0, 1.4, 0.55, None), ("box", 1.2, 0.5, 0.9, "cabinet"), ("cylinder", 0.5, 0.5, 0.45, "plant"),
          ("bin", 0.4, 0.4, 0.6, None), ("box", 0.8, 0.6, 1.1, "printer"), ("shelf", 2.0, 0.4, 2.0, None)]


def building(rows: int, columns: int, room: tuple[float, float], seed: int, rate: float, speed: float) -> tuple[dict, dict]:
    """(world, walk) as YAML-ready mappings. ``rows`` must be even (the walk ends beside the corridor)."""
    if rows < 2 or rows % 2 or columns < 2:
        raise ValueError(f"need an even number of rows >= 2 and >= 2 columns, got {rows} x {columns}")
    w, h = room
    if w < 6 or h < 5:
        raise ValueError(f"rooms of at least 6 m x 5 m, got {w:g} x {h:g}")
    rng = np.random.default_rng(seed)
    x0 = lambda i: CORRIDOR + i * w          # noqa: E731 - a room's south-west corner
    y0 = lambda j: j * h                     # noqa: E731
    rooms, furniture, people, waypoints = [], [], [], []
    # door offsets: in the east wall of room (i, j) towards (i + 1, j), alternating so the walk zigzags
    east_door = {(i, j): (HIGH if (i + j) % 2 == 0 else LOW) for i in range(columns - 1) for j in range(rows)}
    north_door = {j: (w - 2.0 if j % 2 == 0 else 2.0) for j in range(rows - 1)}        # at the row's end
    entry = LOW                                   # room (0, 0)'s west door, the start's side
    exit_west = LOW if (rows - 1) % 2 == 0 else HIGH
    for j in range(rows):
        for i in range(columns):
            doors = []
            if i < columns - 1:
                doors.append({"wall": "east", "at": east_door[(i, j)], "width": DOOR})
            end = columns - 1 if j % 2 == 0 else 0
            if j < rows - 1 and i == end:
                doors.append({"wall": "north", "at": north_door[j], "width": DOOR})
            if i == 0 and j == 0:
                doors.append({"wall": "west", "at": entry, "width": DOOR})
            if i == 0 and j == rows - 1:
                doors.append({"wall": "west", "at": exit_west, "width": DOOR})
            open_sides = (["west"] if i > 0 else []) + (["south"] if j > 0 else [])
            color = PALETTE[int(rng.integers(len(PALETTE)))]
            entry_room = {"name": f"room_{j}_{i}", "from": [x0(i), y0(j)], "to": [x0(i) + w, y0(j) + h],
                          "color": [round(c, 3) for c in color], "doors": doors}
            if open_sides:
                entry_room["open"] = open_sides
            rooms.append(entry_room)
            # keep a north or south door's approach free (1.5 m either side of it)
            keep_free = {"north": [north_door[j]] if j < rows - 1 and i == (columns - 1 if j % 2 == 0 else 0) else [],
                         "south": [north_door[j - 1]] if j > 0 and i == (columns - 1 if (j - 1) % 2 == 0 else 0) else []}
            furniture += _furnish(rng, f"r{j}_{i}", x0(i), y0(j), w, h, keep_free)
    # a few people walking in the rooms' north bands, where nothing stands (kept free of furniture below)
    for n, (j, i) in enumerate([(0, columns // 2), (rows // 2, 1), (rows - 1, columns - 2)]):
        yy = y0(j) + h - 0.45
        furniture = [f for f in furniture if not (x0(i) <= f["position"][0] <= x0(i) + w and f["position"][1] > y0(j) + h - 1.5)]
        people.append({"name": f"walker_{n}", "model": "humanoid" if n % 2 == 0 else "capsule",
                       "waypoints": [[x0(i) + 1.0, yy], [x0(i) + w - 1.0, yy]], "speed": 0.7, "phase": float(n)})
    # the walk: room by room along each row, up at the row's end, then the corridor back to the start
    for j in range(rows):
        order = range(columns) if j % 2 == 0 else range(columns - 1, -1, -1)
        for i in order:
            going_east = j % 2 == 0
            came_from_south = j > 0 and i == (columns - 1 if (j - 1) % 2 == 0 else 0)
            if came_from_south:
                nx = north_door[j - 1]
                waypoints.append((x0(i) + nx, y0(j) + 1.0))
            elif going_east:
                waypoints.append((x0(i) + 1.0, y0(j) + (entry if i == 0 else east_door[(i - 1, j)])))
            else:
                waypoints.append((x0(i) + w - 1.0, y0(j) + east_door[(i, j)]))
            leaving_north = j < rows - 1 and i == (columns - 1 if going_east else 0)
            if leaving_north:
                waypoints.append((x0(i) + north_door[j], y0(j) + h - 1.0))
            elif going_east:
                waypoints.append((x0(i) + w - 1.0, y0(j) + east_door[(i, j)]))
            elif i > 0:
                waypoints.append((x0(i) + 1.0, y0(j) + east_door[(i - 1, j)]))
            else:
                waypoints.append((x0(i) + 1.0, y0(j) + exit_west))
    waypoints += [(CORRIDOR / 2, y0(rows - 1) + exit_west), (CORRIDOR / 2, y0(0) + entry)]
    length_x, length_y = CORRIDOR + columns * w, rows * h
    world = {"name": "long_building",
             "description": f"{rows} x {columns} rooms of {w:g} m x {h:g} m with a corridor along the west side "
                            "(tools/slam_long_walk.py)",
             "floor": {"from": [0, 0], "to": [length_x, length_y], "color": [0.55, 0.57, 0.6]},
             "defaults": {"wall_height": 2.7, "wall_thickness": 0.12, "wall_color": [0.92, 0.91, 0.88]},
             "rooms": rooms,
             "walls": [{"name": "corridor_west", "from": [0, 0], "to": [0, length_y]},
                       {"name": "corridor_south", "from": [0, 0], "to": [CORRIDOR, 0]},
                       {"name": "corridor_north", "from": [0, length_y], "to": [CORRIDOR, length_y]}],
             "furniture": furniture, "people": people,
             "spawn": {"position": [float(waypoints[0][0]), float(waypoints[0][1])], "yaw": 0}}
    walk = {"world": "", "waypoints": [[round(float(x), 3), round(float(y), 3)] for x, y in waypoints],
            "loops": 1, "speed": speed, "rate": rate}
    return world, walk


def _furnish(rng, tag: str, x0: float, y0: float, w: float, h: float, keep_free: dict) -> list[dict]:
    """Pieces against the south and north walls of a room, clear of the walk's band (y0 + LOW − 0.5
    … y0 + HIGH + 0.5) and of the approaches to a north/south door."""
    out = []
    for side in ("south", "north"):
        x = x0 + 0.4
        while True:
            kind, along, depth, height, cls = PIECES[int(rng.integers(len(PIECES)))]
            depth = min(depth, 0.8)                           # never into the walk's band
            if x + along > x0 + w - 0.4:
                break
            cx = x + along / 2
            if all(abs(cx - (x0 + d)) > 1.5 + along / 2 for d in keep_free[side]):
                cy = y0 + 0.06 + depth / 2 + 0.02 if side == "south" else y0 + h - 0.06 - depth / 2 - 0.02
                # the piece's own x runs across the wall (its front faces the room)
                piece = {"type": kind, "name": f"{tag}_{side}_{len(out)}", "position": [round(cx, 3), round(cy, 3)],
                         "yaw": 90 if side == "south" else -90, "size": [depth, along, height]}
                if kind in ("cylinder",):
                    piece["size"] = [depth, depth, height]
                if cls:
                    piece["class"] = cls
                piece["color"] = [round(float(c), 3) for c in rng.uniform(0.15, 0.85, 3)]
                out.append(piece)
            x += along + float(rng.uniform(0.3, 1.2))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("output", type=Path, help="folder for building.yaml and walk.yaml")
    parser.add_argument("--rows", type=int, default=8)
    parser.add_argument("--columns", type=int, default=7)
    parser.add_argument("--room", type=float, nargs=2, default=(10.0, 5.0), metavar=("W", "H"))
    parser.add_argument("--rate", type=float, default=10.0, help="frames per second (default 10: the slam node's max_rate)")
    parser.add_argument("--speed", type=float, default=1.0, help="m/s (default 1.0, as the office walks)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    try:
        world, walk = building(args.rows, args.columns, tuple(args.room), args.seed, args.rate, args.speed)
    except ValueError as exc:
        print(f"slam_long_walk: {exc}", file=sys.stderr)
        return 2
    from raspv_sim.walks import load_walk, plan_walk

    args.output.mkdir(parents=True, exist_ok=True)
    world_path = (args.output / "building.yaml").resolve()
    world_path.write_text(yaml.safe_dump(world, sort_keys=False))
    walk["world"] = str(world_path)
    (args.output / "walk.yaml").write_text(yaml.safe_dump(walk, sort_keys=False))
    plan = plan_walk(load_walk(args.output / "walk.yaml"))
    print(f"{args.output}: {args.rows} x {args.columns} rooms, {len(world['furniture'])} pieces of furniture; "
          f"walk {plan.length_m:.0f} m, {plan.poses[-1].t:.0f} s, {len(plan.poses)} frames at {args.rate:g} Hz")
    return 0


if __name__ == "__main__":
    sys.exit(main())
