"""The floor: a slab with its top at z = 0 over the world's floor rectangle, with holes cut where
descending staircases sink into it (all rectangles axis-aligned in W, metres)."""
from __future__ import annotations

from raspv_sim.primitives import Part, SolidObject
from raspv_sim.world_spec import FloorSpec

THICKNESS = 0.1  # m


def floor_rectangles(floor: FloorSpec, holes: list[tuple[float, float, float, float]]) -> list[tuple[float, float, float, float]]:
    """Rectangles (x0, y0, x1, y1) covering the floor minus the ``holes``: the grid of all hole
    edges, kept cells merged into strips along x."""
    xs = sorted({floor.lo[0], floor.hi[0], *(min(max(v, floor.lo[0]), floor.hi[0]) for h in holes for v in (h[0], h[2]))})
    ys = sorted({floor.lo[1], floor.hi[1], *(min(max(v, floor.lo[1]), floor.hi[1]) for h in holes for v in (h[1], h[3]))})

    def in_hole(cx: float, cy: float) -> bool:
        return any(h[0] < cx < h[2] and h[1] < cy < h[3] for h in holes)

    out = []
    for y0, y1 in zip(ys, ys[1:]):
        if y1 - y0 < 1e-9:
            continue
        start = None
        for x0, x1 in zip(xs, xs[1:]):
            keep = x1 - x0 > 1e-9 and not in_hole((x0 + x1) / 2, (y0 + y1) / 2)
            if keep and start is None:
                start = x0
            if not keep and start is not None:
                out.append((start, y0, x0, y1))
                start = None
        if start is not None:
            out.append((start, y0, xs[-1], y1))
    return out


def floor_solid(floor: FloorSpec, holes: list[tuple[float, float, float, float]]) -> SolidObject:
    parts = tuple(Part("box", (x1 - x0, y1 - y0, THICKNESS), ((x0 + x1) / 2, (y0 + y1) / 2, -THICKNESS / 2), floor.color)
                  for x0, y0, x1, y1 in floor_rectangles(floor, holes))
    return SolidObject("floor", "floor", parts)
