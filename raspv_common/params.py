"""Node parameters declared as data (no ROS imports).

Every node kind publishes its parameters as a list of :class:`Param` in a light module (e.g.
``raspv_spv/spv_params.py``). The launcher validates a graph file against these schemas before
starting anything, and the node base declares them in rclpy with descriptors (type, range,
description) and checks every run-time change with the same code.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping, Sequence

_TYPE_NAMES = {bool: "bool", int: "int", float: "float", str: "string", list: "list"}


@dataclass(frozen=True)
class Param:
    """One node parameter.

    ``default`` fixes the type (bool, int, float, str, or a list of one of those). ``minimum`` and
    ``maximum`` bound numbers (inclusive); ``choices`` restricts values to a set. ``dynamic``
    says whether it may change while the node runs (``raspv param set``). ``file_kind`` says
    the value names a file of that kind (``raspv_bringup/file_kinds.py``: world, device, map,
    bag, …), checked before a graph starts.

    Parameters that only work together say so: ``needs`` names parameters that must be set too
    when this one is set (with ``needs_when``: only when its value is one of those), ``excludes``
    those that must not be set with it (declare it on one side). "Set" means not empty ("", [],
    False, 0, None). The
    launcher (and ``--check``) and the node refuse a graph breaking them in one line each.
    """

    name: str
    default: Any
    description: str
    minimum: float | None = None
    maximum: float | None = None
    choices: Sequence[Any] | None = None
    dynamic: bool = True
    unit: str = ""
    file_kind: str = ""
    needs: tuple[str, ...] = ()
    needs_when: tuple[Any, ...] = ()
    excludes: tuple[str, ...] = ()

    @property
    def kind(self) -> type:
        return list if isinstance(self.default, (list, tuple)) else type(self.default)

    @property
    def element_kind(self) -> type | None:
        if self.kind is not list:
            return None
        return type(self.default[0]) if self.default else str

    def type_name(self) -> str:
        if self.kind is list:
            return f"list of {_TYPE_NAMES.get(self.element_kind, '?')}"
        return _TYPE_NAMES.get(self.kind, self.kind.__name__)

    def allowed(self) -> str:
        """Human description of what values are allowed."""
        parts = [self.type_name()]
        if self.choices is not None:
            parts.append("one of " + ", ".join(repr(c) for c in self.choices))
        if self.minimum is not None and self.maximum is not None:
            parts.append(f"in [{self.minimum}, {self.maximum}]")
        elif self.minimum is not None:
            parts.append(f">= {self.minimum}")
        elif self.maximum is not None:
            parts.append(f"<= {self.maximum}")
        return " ".join(parts)

    def pairing(self) -> str:
        """What this parameter needs or excludes, for references ("" when nothing)."""
        parts = []
        if self.needs:
            when = f" when {' or '.join(repr(v) for v in self.needs_when)}" if self.needs_when else ""
            parts.append(f"needs {', '.join(self.needs)}{when}")
        if self.excludes:
            parts.append(f"not with {', '.join(self.excludes)}")
        return "; ".join(parts)

    def coerce(self, value: Any) -> Any:
        """Return ``value`` converted to this parameter's type, or raise ``ValueError`` saying
        what is allowed. Ints are accepted for floats; nothing else is converted silently."""
        kind = self.kind
        if kind is list:
            if not isinstance(value, (list, tuple)):
                raise ValueError(f"expected {self.allowed()}, got {type(value).__name__} {value!r}")
            elem = Param(self.name, self.default[0] if self.default else "", self.description,
                         self.minimum, self.maximum, self.choices)
            return [elem.coerce(v) for v in value]
        if kind is bool:
            if not isinstance(value, bool):
                raise ValueError(f"expected {self.allowed()}, got {type(value).__name__} {value!r}")
            out: Any = value
        elif kind is int:
            if isinstance(value, bool) or not isinstance(value, int):
                raise ValueError(f"expected {self.allowed()}, got {type(value).__name__} {value!r}")
            out = value
        elif kind is float:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"expected {self.allowed()}, got {type(value).__name__} {value!r}")
            out = float(value)
            if not math.isfinite(out):
                raise ValueError(f"expected a finite number ({self.allowed()}), got {value!r}")
        elif kind is str:
            if not isinstance(value, str):
                raise ValueError(f"expected {self.allowed()}, got {type(value).__name__} {value!r}")
            out = value
        else:  # pragma: no cover - schema error
            raise TypeError(f"parameter {self.name}: unsupported type {kind}")
        if self.choices is not None and out not in self.choices:
            raise ValueError(f"{out!r} is not allowed; expected {self.allowed()}")
        if self.minimum is not None and out < self.minimum:
            raise ValueError(f"{out!r} is out of range; expected {self.allowed()}")
        if self.maximum is not None and out > self.maximum:
            raise ValueError(f"{out!r} is out of range; expected {self.allowed()}")
        return out


@dataclass
class ParamSchema:
    """The parameters of one node kind, by name."""

    params: dict[str, Param] = field(default_factory=dict)

    @classmethod
    def of(cls, params: Iterable[Param]) -> "ParamSchema":
        out: dict[str, Param] = {}
        for p in params:
            if p.name in out:
                raise ValueError(f"parameter {p.name!r} declared twice")
            p.coerce(p.default)  # a schema whose default is invalid is a programming error
            out[p.name] = p
        for p in out.values():
            unknown = [o for o in p.needs + p.excludes if o not in out]
            if unknown:
                raise ValueError(f"parameter {p.name!r} needs or excludes unknown {', '.join(unknown)}")
        return cls(out)

    def __contains__(self, name: str) -> bool:
        return name in self.params

    def __getitem__(self, name: str) -> Param:
        return self.params[name]

    def __iter__(self):
        return iter(self.params.values())

    def defaults(self) -> dict[str, Any]:
        return {p.name: (list(p.default) if isinstance(p.default, tuple) else p.default) for p in self}

    def validate(self, values: Mapping[str, Any]) -> tuple[dict[str, Any], list[tuple[str, str]]]:
        """Check ``values`` against the schema. Returns (coerced values, errors) where each
        error is (key, message naming what is allowed)."""
        good: dict[str, Any] = {}
        errors: list[tuple[str, str]] = []
        for key, value in values.items():
            if key not in self.params:
                known = ", ".join(sorted(self.params)) or "(none)"
                errors.append((key, f"unknown parameter; this node has: {known}"))
                continue
            try:
                good[key] = self.params[key].coerce(value)
            except ValueError as exc:
                errors.append((key, str(exc)))
        return good, errors

    def check_together(self, values: Mapping[str, Any]) -> list[tuple[str, str]]:
        """Check the parameters that only work together (``Param.needs``, ``Param.excludes``) on
        ``values`` (names missing from it take their defaults). Returns (key, message) errors."""
        full = {**self.defaults(), **{k: v for k, v in values.items() if k in self.params}}
        errors: list[tuple[str, str]] = []
        for p in self:
            value = full[p.name]
            if not is_set(value):
                continue
            if p.needs and (not p.needs_when or value in p.needs_when):
                for other in p.needs:
                    if is_set(full[other]):
                        continue
                    if p.needs_when:
                        errors.append((p.name, f"{value!r} needs {other}, which is not set"))
                    elif p.name in self.params[other].needs:
                        errors.append((p.name, f"set without {other}: {p.name} and {other} only work together "
                                               f"(set both or neither)"))
                    else:
                        errors.append((p.name, f"needs {other}, which is not set"))
            for other in p.excludes:
                if is_set(full[other]):
                    errors.append((p.name, f"{p.name} and {other} are both set: give one of them"))
        return errors


def is_set(value: Any) -> bool:
    """Whether a parameter value counts as given: not "", [], False, 0 or None."""
    return value not in ("", None, False) and not (isinstance(value, (list, tuple)) and not value)
