"""Furniture composed of primitives: tables, chairs, sofas, beds, shelves, bins, doors, boxes,
cylinders, rugs and laptops. Each builder works in the object's local frame (front towards +x, y left,
z up, origin at the centre of its footprint on its base) with ``size`` = (length x, width y,
height z) in metres."""
from __future__ import annotations

import math

from raspv_sim.primitives import LocalFrame, Part, SolidObject, shade
from raspv_sim.world_spec import FurnitureSpec

BOOK_COLORS = ((0.7, 0.15, 0.1), (0.15, 0.3, 0.6), (0.85, 0.75, 0.3), (0.2, 0.5, 0.3), (0.9, 0.9, 0.85),
               (0.4, 0.2, 0.45))


def furniture_solid(spec: FurnitureSpec) -> SolidObject:
    frame = LocalFrame(spec.position, math.radians(spec.yaw))
    parts = _BUILDERS[spec.type](frame, spec)
    return SolidObject(spec.name, spec.cls, tuple(parts), spec.specular, spec.where)


def _legs(f: LocalFrame, L: float, W: float, height: float, thick: float, color, inset: float) -> list[Part]:
    hx, hy = L / 2 - inset - thick / 2, W / 2 - inset - thick / 2
    return [f.box((sx * hx, sy * hy, height / 2), (thick, thick, height), color)
            for sx in (-1, 1) for sy in (-1, 1)]


def _table(f: LocalFrame, s: FurnitureSpec) -> list[Part]:
    L, W, H = s.size
    top = min(0.04, H / 4)
    return [f.box((0, 0, H - top / 2), (L, W, top), s.color)] + _legs(f, L, W, H - top, min(0.06, L / 6, W / 6),
                                                                        shade(s.color, 0.7), min(0.04, L / 10))


def _chair(f: LocalFrame, s: FurnitureSpec) -> list[Part]:
    L, W, H = s.size
    seat_h, seat_t, back_t = min(0.46, 0.55 * H), 0.05, min(0.05, L / 5)
    parts = [f.box((0, 0, seat_h - seat_t / 2), (L, W, seat_t), s.color),
             f.box((-L / 2 + back_t / 2, 0, (seat_h + H) / 2), (back_t, W, H - seat_h), shade(s.color, 0.9))]
    return parts + _legs(f, L, W, seat_h - seat_t, min(0.04, L / 8), shade(s.color, 0.7), 0.02)


def _sofa(f: LocalFrame, s: FurnitureSpec) -> list[Part]:
    L, W, H = s.size
    plinth, seat_h = 0.1, min(0.42, 0.5 * H)
    back, arm = min(0.22, L / 3), min(0.2, W / 6)
    arm_h = min(0.62, 0.75 * H)
    cushion = shade(s.color, 1.15)
    return [f.box((0, 0, plinth / 2), (L, W, plinth), (0.15, 0.12, 0.1)),
            f.box((back / 2, 0, (plinth + seat_h) / 2), (L - back, W - 2 * arm, seat_h - plinth), cushion),
            f.box((-L / 2 + back / 2, 0, (plinth + H) / 2), (back, W, H - plinth), s.color),
            f.box((0, W / 2 - arm / 2, (plinth + arm_h) / 2), (L, arm, arm_h - plinth), s.color),
            f.box((0, -W / 2 + arm / 2, (plinth + arm_h) / 2), (L, arm, arm_h - plinth), s.color)]


def _bed(f: LocalFrame, s: FurnitureSpec) -> list[Part]:
    L, W, H = s.size
    frame_h = min(0.3, 0.55 * H)
    head_t, head_h = 0.06, max(H + 0.4, 0.95)
    blanket = (0.3, 0.45, 0.6)
    return [f.box((0, 0, frame_h / 2), (L, W, frame_h), s.color),
            f.box((0, 0, (frame_h + H) / 2), (L - 0.04, W - 0.04, H - frame_h), (0.92, 0.92, 0.9)),
            f.box((L * 0.15, 0, H + 0.01), (L * 0.7, W - 0.02, 0.04), blanket),   # sunk 1 cm: no coplanar faces
            f.box((-L / 2 + 0.3, 0, H + 0.05), (0.35, W * 0.8, 0.1), (0.97, 0.97, 0.97)),
            f.box((-L / 2 - head_t / 2, 0, head_h / 2), (head_t, W, head_h), shade(s.color, 0.85))]


def _shelf(f: LocalFrame, s: FurnitureSpec) -> list[Part]:
    L, W, H = s.size
    t = 0.02
    parts = [f.box((0, sy * (W / 2 - t / 2), H / 2), (L, t, H), s.color) for sy in (-1, 1)]
    parts.append(f.box((-L / 2 + t / 2, 0, H / 2), (t, W - 2 * t, H), shade(s.color, 0.8)))
    levels = [t / 2 + i * (H - t) / s.shelves for i in range(s.shelves + 1)]
    for i, z in enumerate(levels):
        parts.append(f.box((t / 2, 0, z), (L - t, W - 2 * t, t), s.color))
        if i < len(levels) - 1:   # a row of books on every board but the top
            gap = levels[i + 1] - z - t
            span, y = W - 2 * t - 0.04, -(W / 2) + t + 0.02
            k = 0
            while y < -W / 2 + t + 0.02 + span * 0.8:
                bw = 0.03 + 0.02 * ((i * 7 + k * 3) % 4)
                bh = gap * (0.6 + 0.08 * ((i + k) % 4))
                color = BOOK_COLORS[(i * 5 + k) % len(BOOK_COLORS)]
                parts.append(f.box((0.02, y + bw / 2, z + t / 2 + bh / 2), (L * 0.7, bw, bh), color))
                y += bw + 0.005
                k += 1
    return parts


def _bin(f: LocalFrame, s: FurnitureSpec) -> list[Part]:
    L, W, H = s.size
    d = min(L, W)
    rim = min(0.04, H / 8)
    return [f.cylinder((0, 0, (H - rim) / 2), d * 0.96, H - rim, s.color),
            f.cylinder((0, 0, H - rim / 2), d, rim, shade(s.color, 0.55))]


def _door(f: LocalFrame, s: FurnitureSpec) -> list[Part]:
    """A free-standing door leaf hinged at the local origin, ``size`` = (width, thickness, height),
    turned by ``open`` degrees about the hinge."""
    W, T, H = s.size
    a = math.radians(s.open)
    c, sn = math.cos(a), math.sin(a)
    leaf = f.box((c * W / 2, sn * W / 2, H / 2), (W, T, H), s.color, yaw=a)
    hx, hy = c * (W - 0.08), sn * (W - 0.08)
    handles = [f.box((hx - sn * side * (T / 2 + 0.02), hy + c * side * (T / 2 + 0.02), 1.0), (0.12, 0.02, 0.02),
                     (0.75, 0.75, 0.72), yaw=a) for side in (-1, 1)]
    return [leaf, *handles]


def _box(f: LocalFrame, s: FurnitureSpec) -> list[Part]:
    L, W, H = s.size
    return [f.box((0, 0, H / 2), (L, W, H), s.color)]


def _laptop(f: LocalFrame, s: FurnitureSpec) -> list[Part]:
    """An open laptop: ``size`` = (depth of the base, width, height of the open lid); the display
    faces +x, the hinge is at the back (−x)."""
    L, W, H = s.size
    base_t, lid_t = min(0.02, H / 6), min(0.012, L / 10)
    display = (0.08, 0.1, 0.16)
    return [f.box((0, 0, base_t / 2), (L, W, base_t), s.color),
            f.box((L * 0.05, 0, base_t + 0.002), (L * 0.5, W * 0.85, 0.004), shade(s.color, 0.45)),   # keyboard
            f.box((-L / 2 + lid_t / 2, 0, base_t + (H - base_t) / 2), (lid_t, W, H - base_t), s.color),
            f.box((-L / 2 + lid_t + 0.002, 0, base_t + (H - base_t) / 2), (0.004, W * 0.9, (H - base_t) * 0.85),
                  display)]


def _rug(f: LocalFrame, s: FurnitureSpec) -> list[Part]:
    """Sunk 5 mm into what it lies on, so its bottom never shares a plane with the floor."""
    L, W, H = s.size
    return [f.box((0, 0, (H - 0.005) / 2), (L, W, H + 0.005), s.color)]


def _cylinder(f: LocalFrame, s: FurnitureSpec) -> list[Part]:
    L, W, H = s.size
    return [f.cylinder((0, 0, H / 2), min(L, W), H, s.color)]


_BUILDERS = {"table": _table, "chair": _chair, "sofa": _sofa, "bed": _bed, "shelf": _shelf, "bin": _bin,
             "door": _door, "box": _box, "cylinder": _cylinder, "rug": _rug, "laptop": _laptop}
