"""A tree of stamped transforms, looked up between any two frames at a time (no rclpy).

tf2 is not on PyPI; this is the part of its buffer the graph needs: each frame has one parent,
an edge is either static (``/tf_static``: a mounting, a fixed offset) or a history of stamped
samples (``/tf``), kept in a :class:`~raspv_common.pose_buffer.PoseBuffer` and interpolated at
the asked time (linear translation, slerp rotation). :meth:`TransformTree.lookup` composes the
edges from ``source`` up to the nearest common ancestor and down to ``target``. The tf tests use
it to check that every frame a graph's topics name reaches ``map``; the slam node to put its
camera pose into ``base_link`` (through a head that may turn).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from raspv_common.pose_buffer import PoseBuffer, PoseLookupError


class TransformLookupError(LookupError):
    """No transform between two frames at the asked time (not connected, or no sample near it)."""


@dataclass
class _Edge:
    parent: str
    static: np.ndarray | None          # parent ← child, for a static edge
    samples: PoseBuffer | None          # parent ← child over time, for a dynamic edge


class TransformTree:
    """Frames linked child → parent by static or stamped transforms (4×4, parent ← child)."""

    def __init__(self, max_age_s: float = 10.0, max_extrapolation_s: float = 0.1) -> None:
        self.max_age_s = max_age_s
        self.max_extrapolation_s = max_extrapolation_s
        self._edges: dict[str, _Edge] = {}            # child → edge to its parent

    # -- filling -----------------------------------------------------------------------------
    def set(self, parent: str, child: str, matrix: np.ndarray, stamp: float | None = None,
            static: bool = False) -> None:
        """Add parent ← child: static (``stamp`` ignored) or a sample at ``stamp`` [s]. A child
        given a new parent, or switching between static and dynamic, starts afresh (as tf2 does)."""
        if not parent or not child or parent == child:
            raise ValueError(f"a transform needs two different, non-empty frame names, got {parent!r} ← {child!r}")
        T = np.asarray(matrix, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"transform {parent} ← {child} must be a finite 4x4 matrix")
        if self._would_loop(parent, child):
            raise ValueError(f"{parent} ← {child} would close a loop in the tree")
        edge = self._edges.get(child)
        if static:
            self._edges[child] = _Edge(parent, T.copy(), None)
            return
        if stamp is None:
            raise ValueError(f"a dynamic transform {parent} ← {child} needs a stamp")
        if edge is None or edge.parent != parent or edge.samples is None:
            edge = _Edge(parent, None, PoseBuffer(self.max_age_s, self.max_extrapolation_s))
            self._edges[child] = edge
        edge.samples.add(stamp, T)

    def _would_loop(self, parent: str, child: str) -> bool:
        frame, seen = parent, set()
        while frame in self._edges and frame not in seen:
            if frame == child:
                return True
            seen.add(frame)
            frame = self._edges[frame].parent
        return frame == child

    # -- the tree ----------------------------------------------------------------------------
    def frames(self) -> set[str]:
        return set(self._edges) | {e.parent for e in self._edges.values()}

    def edges(self) -> list[tuple[str, str, bool]]:
        """(parent, child, static) of every edge, sorted by child."""
        return [(e.parent, c, e.static is not None) for c, e in sorted(self._edges.items())]

    def parent_of(self, frame: str) -> str | None:
        edge = self._edges.get(frame)
        return None if edge is None else edge.parent

    def chain(self, frame: str) -> list[str]:
        """``frame`` and its ancestors, up to the root."""
        out = [frame]
        while out[-1] in self._edges:
            out.append(self._edges[out[-1]].parent)
        return out

    def connected(self, a: str, b: str) -> bool:
        return a == b or self.chain(a)[-1] == self.chain(b)[-1]

    # -- lookups -----------------------------------------------------------------------------
    def _up(self, chain: list[str], stamp: float | None) -> list[np.ndarray]:
        """For each frame of ``chain`` (but the last), root-ward edge parent ← frame at ``stamp``."""
        out = []
        for child in chain[:-1]:
            edge = self._edges[child]
            if edge.static is not None:
                out.append(edge.static)
                continue
            try:
                out.append(edge.samples.latest().matrix if stamp is None else edge.samples.lookup(stamp))
            except PoseLookupError as exc:
                raise TransformLookupError(f"{edge.parent} ← {child}: {exc}") from None
        return out

    def lookup(self, target: str, source: str, stamp: float | None = None) -> np.ndarray:
        """4×4 target ← source at ``stamp`` [s] (None: the newest sample of each dynamic edge)."""
        if target == source:
            return np.eye(4)
        up_source, up_target = self.chain(source), self.chain(target)
        common = next((f for f in up_source if f in set(up_target)), None)
        if common is None:
            raise TransformLookupError(f"{target} and {source} are not connected "
                                       f"({source} → {' → '.join(up_source[1:]) or 'no parent'}; "
                                       f"{target} → {' → '.join(up_target[1:]) or 'no parent'})")
        common_from_source = np.eye(4)
        for T in self._up(up_source[:up_source.index(common) + 1], stamp):
            common_from_source = T @ common_from_source
        common_from_target = np.eye(4)
        for T in self._up(up_target[:up_target.index(common) + 1], stamp):
            common_from_target = T @ common_from_target
        return np.linalg.inv(common_from_target) @ common_from_source

    def lookup_or_none(self, target: str, source: str, stamp: float | None = None) -> np.ndarray | None:
        try:
            return self.lookup(target, source, stamp)
        except TransformLookupError:
            return None
