"""The message types bags are read and written with (no ROS imports).

One rosbags typestore for record, play, info, render and from-frames: ROS 2 Jazzy's standard
messages plus ``raspv_msgs`` registered from its ``.msg`` files, plus whatever other types a
bag brings along (their definitions are stored in the bag).
"""
from __future__ import annotations

import os
import sys
from functools import lru_cache
from pathlib import Path
from typing import Any

from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

REPO_MSG_DIR = Path(__file__).resolve().parents[1] / "raspv_msgs" / "msg"
INSTALLED_MSG_DIR = Path(sys.prefix) / "share" / "raspv_msgs" / "msg"


def share_dirs() -> list[Path]:
    """Where installed ROS packages keep ``<pkg>/msg/*.msg``: this interpreter's prefix, then every
    prefix of ``AMENT_PREFIX_PATH`` (a colcon install, a system ROS 2 in /opt/ros)."""
    prefixes = [sys.prefix, *(p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p)]
    return [Path(p) / "share" for p in dict.fromkeys(prefixes)]


def raspv_msg_dir() -> Path:
    """Where the ``raspv_msgs`` ``.msg`` files are: the source tree, else an installed share."""
    for d in (REPO_MSG_DIR, INSTALLED_MSG_DIR, *(share / "raspv_msgs" / "msg" for share in share_dirs())):
        if d.is_dir() and any(d.glob("*.msg")):
            return d
    raise FileNotFoundError(f"raspv_msgs .msg files not found in {REPO_MSG_DIR} or an installed share "
                            f"({', '.join(str(s) for s in share_dirs())})")


@lru_cache(maxsize=1)
def typestore() -> Typestore:
    """ROS 2 Jazzy types plus ``raspv_msgs`` (built once per process)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    types: dict[str, Any] = {}
    for path in sorted(raspv_msg_dir().glob("*.msg")):
        types.update(get_types_from_msg(path.read_text(), f"raspv_msgs/msg/{path.stem}"))
    store.register(types)
    return store


def normalise_type(name: str) -> str:
    """``sensor_msgs/Image`` or ``sensor_msgs/msg/Image`` → ``sensor_msgs/msg/Image``."""
    parts = name.split("/")
    return f"{parts[0]}/msg/{parts[1]}" if len(parts) == 2 else name


def is_known(msgtype: str) -> bool:
    return normalise_type(msgtype) in typestore().fielddefs


_PRIMITIVES = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32",
               "uint32", "int64", "uint64", "string", "wstring", "time", "duration"}


def ensure_type(msgtype: str, _seen: set[str] | None = None) -> bool:
    """Make ``msgtype`` known: already in the store, or registered (with its dependencies)
    from the ``.msg`` files installed under ``<prefix>/share/<pkg>/msg``. False if not found."""
    name = normalise_type(msgtype)
    store = typestore()
    if name in store.fielddefs:
        return True
    seen = _seen if _seen is not None else set()
    if name in seen:
        return False
    seen.add(name)
    pkg, _, short = name.partition("/msg/")
    path = next((p for p in (share / pkg / "msg" / f"{short}.msg" for share in share_dirs()) if p.is_file()), None)
    if path is None:
        return False
    text = path.read_text()
    for dep in _dependencies(text, pkg):
        if not ensure_type(dep, seen):
            return False
    try:
        store.register(get_types_from_msg(text, name))
    except Exception:  # a definition rosbags cannot parse
        return False
    return name in store.fielddefs


def _dependencies(msg_text: str, pkg: str) -> list[str]:
    """The message types a .msg definition refers to (``pkg/msg/Name``)."""
    deps = []
    for line in msg_text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line or "=" in line.split()[0]:
            continue
        token = line.split()[0]
        base = token.split("[", 1)[0].split("<=", 1)[0]
        if base in _PRIMITIVES or "=" in line.split(None, 1)[-1][:1]:
            continue
        if base == "Header":
            dep = "std_msgs/msg/Header"
        elif "/" in base:
            dep = normalise_type(base)
        else:
            dep = f"{pkg}/msg/{base}"
        if dep not in deps:
            deps.append(dep)
    return deps


def register_definition(msgtype: str, encoding: str, text: str) -> bool:
    """Make ``msgtype`` known from a definition stored in a bag (``encoding`` ``ros2msg``: the
    type's .msg text followed by its dependencies; ``ros2idl``: IDL), else from the installed
    ``.msg`` files. Returns whether the type is known afterwards."""
    store = typestore()
    msgtype = normalise_type(msgtype)
    if msgtype in store.fielddefs:
        return True
    try:
        if encoding == "ros2msg" and text:
            store.register(_types_from_concatenated_msg(text, msgtype))
        elif encoding == "ros2idl" and text:
            store.register(get_types_from_idl(text))
    except Exception:  # a definition rosbags cannot parse: try the installed files
        pass
    return msgtype in store.fielddefs or ensure_type(msgtype)


def _types_from_concatenated_msg(text: str, name: str) -> dict[str, Any]:
    """A rosbag2 message definition: the type's .msg text, then ``====`` separators each
    followed by ``MSG: pkg/Name`` and that dependency's text."""
    sep = "=" * 80
    blocks = text.split(sep)
    types: dict[str, Any] = dict(get_types_from_msg(blocks[0], name))
    for block in blocks[1:]:
        block = block.strip("\n")
        if not block.startswith("MSG: "):
            continue
        header, _, body = block.partition("\n")
        dep = normalise_type(header[5:].strip())
        types.update(get_types_from_msg(body, dep))
    return types
