"""Representation modes and overlays: the registry (imports nothing heavy).

A mode turns one frame's inputs into a level per phosphene; an overlay highlights some
phosphenes on top of any mode (full level) and dims the rest. To add one: write a file in this
package with a subclass of :class:`raspv_spv.modes.base.Mode` (or ``Overlay``) and add a line
below, ``"name": "raspv_spv.modes.<file>:<Class>"``. docs/spv.md has a worked example.
"""
from __future__ import annotations

import importlib

MODES: dict[str, str] = {
    "grey": "raspv_spv.modes.grey:GreyMode",
    "depth": "raspv_spv.modes.depth:DepthMode",
    "edges": "raspv_spv.modes.edges:EdgesMode",
    "edges_depth": "raspv_spv.modes.edges:DepthEdgesMode",
    "chess_floor": "raspv_spv.modes.chess_floor:ChessFloorMode",
    "wall_obstacles": "raspv_spv.modes.wall_obstacles:WallObstaclesMode",
    "chess_wall_obstacles": "raspv_spv.modes.chess_wall_obstacles:ChessWallObstaclesMode",
    "depth_no_floor": "raspv_spv.modes.depth_no_floor:DepthNoFloorMode",
    "learned": "raspv_spv.modes.learned:LearnedMode",
}

OVERLAYS: dict[str, str] = {
    "path": "raspv_spv.modes.path_overlay:PathOverlay",
    "stairs": "raspv_spv.modes.stairs_overlay:StairsOverlay",
    "highlight": "raspv_spv.modes.highlight_overlay:HighlightOverlay",
    "guidance": "raspv_spv.modes.guidance_overlay:GuidanceOverlay",
}


def _load(table: dict[str, str], kind: str, name: str):
    if name not in table:
        known = ", ".join(sorted(table)) or "none yet"
        raise KeyError(f"unknown {kind} {name!r}; known: {known}")
    module, attr = table[name].split(":")
    return getattr(importlib.import_module(module), attr)


def mode_class(name: str):
    """The :class:`~raspv_spv.modes.base.Mode` subclass registered as ``name``."""
    return _load(MODES, "mode", name)


def overlay_class(name: str):
    """The :class:`~raspv_spv.modes.base.Overlay` subclass registered as ``name``."""
    return _load(OVERLAYS, "overlay", name)
