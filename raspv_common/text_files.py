"""Reading the text and YAML files users name (worlds, devices, maps, graphs), with one-line errors.

Every way a named file can be wrong gets one line naming the file, in the caller's own
exception type (``WorldFileError``, ``DeviceError``, …), never a traceback:

    <file>: no such <what>                      <file>: is a directory, not a <what>
    <file>: cannot read (Permission denied)     <file>: not a text file (binary data at byte 17)
    <file>: line 3, column 5: invalid YAML (mapping values are not allowed here)

No ROS imports.
"""
from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import yaml

# Bytes that never appear in a UTF-8 text file a person wrote (NUL and most C0 controls).
_BINARY_BYTE = re.compile(rb"[\x00-\x08\x0e-\x1f]")


def display_path(path: str | os.PathLike) -> str:
    """``path`` relative to the working directory when that is shorter, for messages."""
    try:
        rel = os.path.relpath(path)
    except ValueError:
        return str(path)
    return rel if not rel.startswith("../..") else str(path)


def read_text_file(path: str | os.PathLike, what: str = "file", error: type[Exception] = ValueError,
                   label: str | None = None) -> str:
    """The UTF-8 text of ``path``; any failure raises ``error`` with one line naming the file.

    ``what`` names the kind of file in messages ("world file", "device file"); ``label`` is how
    the file is shown (default: :func:`display_path`).
    """
    p = Path(path)
    src = label or display_path(p)
    if p.is_dir():
        raise error(f"{src}: is a directory, not a {what}")
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise error(f"{src}: no such {what}") from None
    except OSError as exc:
        raise error(f"{src}: cannot read ({exc.strerror or exc})") from None
    bad = _BINARY_BYTE.search(data, 0, 1 << 20)
    if bad is not None:
        raise error(f"{src}: not a text file (binary data at byte {bad.start()}); expected a {what}")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{src}: not a UTF-8 text file (byte {exc.start}); expected a {what}") from None


def yaml_error_line(src: str, exc: yaml.YAMLError) -> str:
    """One line for a YAML syntax error: ``<src>: line L, column C: invalid YAML (problem)``."""
    mark = getattr(exc, "problem_mark", None)
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    return f"{src}: {where}invalid YAML ({problem})"


def read_yaml_file(path: str | os.PathLike, what: str = "YAML file", error: type[Exception] = ValueError,
                   label: str | None = None) -> Any:
    """The parsed YAML document of ``path`` (``yaml.safe_load``); failures as in
    :func:`read_text_file`, plus YAML syntax errors with their line and column."""
    src = label or display_path(Path(path))
    text = read_text_file(path, what, error, src)
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise error(yaml_error_line(src, exc)) from None
    except RecursionError:          # absurdly nested flow collections
        raise error(f"{src}: invalid YAML (nested too deeply)") from None
