"""The classes of a segmentation model: names, synonyms, display colours, and finding class ids
by name (no ROS).

    table = ClassTable.from_label_set("ade20k")
    ids, unknown = table.ids_for(["person", "bin"])     # bin → ADE20K "ashcan"

Name lookup, for each requested name (case and ``_``/space insensitive), first match wins:
1. classes whose own name is it; 2. classes listing it as a synonym; 3. classes in the same
ADE20K class as it (through ADE20K's synonym table and :data:`~raspv_perception.label_sets.ALIASES`),
so "bin" finds the world's ``bin``, ADE20K's ``ashcan`` and "trash can".
"""
from __future__ import annotations

import colorsys
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np

from raspv_perception.label_sets import ADE20K_150, ALIASES, LABEL_SETS

_BLACK_NAMES = {"none", "background", "unlabeled", "other", "void"}


def normalise(name: str) -> str:
    """Lower case, ``_`` → space, single spaces."""
    return " ".join(str(name).replace("_", " ").lower().split())


def _split(entry: str) -> tuple[str, tuple[str, ...]]:
    parts = [normalise(p) for p in str(entry).split(";") if p.strip()]
    if not parts:
        raise ValueError(f"empty class name {entry!r}")
    return parts[0], tuple(dict.fromkeys(p for p in parts[1:] if p != parts[0]))


_ADE_PRIMARY = {}
_ADE_SYNONYM: dict[str, str] = {}
for _entry in ADE20K_150:
    _p, _syn = _split(_entry)
    _ADE_PRIMARY[_p] = _p
    for _s in _syn:
        _ADE_SYNONYM.setdefault(_s, _p)


def canonical(name: str) -> str:
    """The ADE20K class name that covers ``name`` (itself when ADE20K has no such class)."""
    n = normalise(name)
    n = ALIASES.get(n, n)
    if n in _ADE_PRIMARY:
        return n
    return _ADE_SYNONYM.get(n, n)


def palette(names: Sequence[str]) -> np.ndarray:
    """(K, 3) uint8 RGB display colours: well-spread hues (golden-ratio steps), black for
    background-like names."""
    out = np.zeros((len(names), 3), np.uint8)
    for i, n in enumerate(names):
        if normalise(n) in _BLACK_NAMES:
            continue
        r, g, b = colorsys.hsv_to_rgb((0.11 + i * 0.618034) % 1.0, 0.65, 0.95)
        out[i] = (int(r * 255), int(g * 255), int(b * 255))
    return out


@dataclass(frozen=True)
class ClassTable:
    """``names[i]`` is class id i; ``synonyms[i]`` its other names; ``colors`` (K, 3) uint8 RGB.
    ``label_set``: where the names come from (``ade20k``, ``coco_stuff``, ``person``, ``sim``, a file)."""

    names: tuple[str, ...]
    synonyms: tuple[tuple[str, ...], ...]
    colors: np.ndarray = field(repr=False, compare=False)
    label_set: str = "custom"

    def __post_init__(self) -> None:
        if len(self.synonyms) != len(self.names) or self.colors.shape != (len(self.names), 3):
            raise ValueError("names, synonyms and colors must have one entry per class")
        if not self.names:
            raise ValueError("a class table needs at least one class")
        if len(self.names) > 65536:
            raise ValueError(f"{len(self.names)} classes do not fit a mono16 label image")

    # -- construction ---------------------------------------------------------------------------
    @classmethod
    def from_entries(cls, entries: Iterable[str], label_set: str = "custom",
                     colors: np.ndarray | None = None) -> "ClassTable":
        """From ``"name;synonym;…"`` strings, one per class id."""
        split = [_split(e) for e in entries]
        names = tuple(n for n, _ in split)
        cols = palette(names) if colors is None else np.asarray(colors, np.uint8).reshape(-1, 3)
        return cls(names, tuple(s for _, s in split), cols, label_set)

    @classmethod
    def from_label_set(cls, name: str) -> "ClassTable":
        """A built-in set (``ade20k``, ``coco_stuff``, ``person``); KeyError naming the known ones."""
        key = normalise(name).replace(" ", "_").replace("-", "_")
        if key not in LABEL_SETS:
            raise KeyError(f"unknown label set {name!r}; built in: {', '.join(sorted(LABEL_SETS))}")
        return cls.from_entries(LABEL_SETS[key], key)

    @classmethod
    def for_world(cls, classes: Sequence[str]) -> "ClassTable":
        """The virtual world's classes (``/sim/classes``), each with the synonyms of the ADE20K class
        that covers it (so "trash can" finds the world's ``bin``)."""
        names = [normalise(c) for c in classes]
        synonyms = []
        for n in names:
            c = canonical(n)
            group = [c] + [s for s, p in _ADE_SYNONYM.items() if p == c]
            synonyms.append(tuple(dict.fromkeys(g for g in group if g != n)) if c != n or group[1:] else ())
        return cls(tuple(names), tuple(synonyms), palette(names), "sim")

    # -- lookup ---------------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.names)

    def ids_for(self, requested: Iterable[str]) -> tuple[np.ndarray, list[str]]:
        """(sorted unique class ids matching any requested name, the names that matched nothing)."""
        found: set[int] = set()
        unknown: list[str] = []
        canon = [canonical(n) for n in self.names]
        for raw in requested:
            r = normalise(raw)
            ids = [i for i, n in enumerate(self.names) if n == r]
            if not ids:
                ids = [i for i, s in enumerate(self.synonyms) if r in s]
            if not ids:
                c = canonical(r)
                ids = [i for i, k in enumerate(canon) if k == c]
            if ids:
                found.update(ids)
            else:
                unknown.append(str(raw))
        return np.array(sorted(found), dtype=np.int64), unknown

    def id_of(self, name: str) -> int:
        """The single id of ``name``; KeyError listing the classes when there is none."""
        ids, unknown = self.ids_for([name])
        if unknown:
            raise KeyError(f"no class {name!r} in {self.label_set} ({self.describe()})")
        return int(ids[0])

    def describe(self, limit: int = 12) -> str:
        """"K classes: a, b, c, …" for messages."""
        shown = ", ".join(self.names[:limit])
        return f"{len(self.names)} classes: {shown}{', …' if len(self.names) > limit else ''}"

    def colorize(self, labels: np.ndarray) -> np.ndarray:
        """(H, W) class ids → (H, W, 3) uint8 RGB (ids beyond the table black)."""
        lut = np.zeros((max(256, len(self.names)), 3), np.uint8)
        lut[: len(self.names)] = self.colors
        return lut[np.asarray(labels).astype(np.intp).clip(0, len(lut) - 1)]
