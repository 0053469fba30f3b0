"""Kinds of files a graph names, and how each is checked before any process starts (no rclpy).

A node parameter that names a file says so in its schema —
``Param("world", "apartment", "...", file_kind="world")`` — and the launcher (``raspv launch``,
``--check`` included) runs that kind's check on the parameter's value before it starts
anything, so a file the node would fail on is one line naming the graph, the parameter and the
file:

    demo.yaml: sim.ros__parameters.world: worlds/x.yaml: line 3, column 5: invalid YAML (...)

A check is the loader the node itself uses (or a function that runs it without side effects):
it takes the parameter's value and raises ``ValueError`` (every RASPV loader error is one) or
``OSError`` with one line naming the file. An empty value means "not set" and is not checked.
New kinds (segmentation models, protocols, …) are one entry in :data:`FILE_KINDS`, or a
:func:`register_file_kind` call from the package that owns them. Checks are given as
``"module:function"`` so validating a graph imports only what its files need.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any, Callable, Iterable

from raspv_common.params import Param

Check = Callable[[str], Any]


@dataclass(frozen=True)
class FileKind:
    """``check``: ``"module:function"`` or a callable taking the parameter's value (a path or,
    for kinds with shipped entries, a name) and raising ValueError/OSError with one line.
    ``with_params``: the check also takes the node's parameter values (a dict) — for files
    whose meaning depends on another parameter (a model file and the backend that runs it)."""

    name: str
    check: str | Check
    description: str
    with_params: bool = False

    def checker(self) -> Check:
        if callable(self.check):
            return self.check
        module, attr = self.check.split(":")
        return getattr(importlib.import_module(module), attr)


def _check_bag(value: str) -> None:
    from raspv_bags.reader import BagReader

    BagReader(value).close()


def _check_segmentation_model(value: str, params: dict) -> None:
    """The segmentation node's ``model`` (and ``labels``) loaded as its backend loads them."""
    from raspv_perception.segmentation_models import load_model

    backend = params.get("backend", "person")
    if backend == "sim":
        return                              # ground truth from the world: no model file is read
    load_model(backend, value, params.get("labels", ""), params.get("threshold", 0.5), 1)


def _check_output_dir(value: str) -> None:
    """A directory the node will create (with its parents) and write into: a file is created
    and removed in it (or in its nearest existing parent), so a directory that exists but
    cannot be written — permissions, a read-only mount, an immutable directory, even for
    root — is refused, not only one whose mode bits say so."""
    import os
    import tempfile
    from pathlib import Path

    p = Path(value).expanduser()
    if p.exists() and not p.is_dir():
        raise ValueError(f"{value}: exists and is not a directory")
    existing = next(q for q in (p, *p.parents) if q.exists())
    if not existing.is_dir():
        raise ValueError(f"{value}: cannot create or write in it ({existing} is not writable: not a directory)")
    try:
        fd, probe = tempfile.mkstemp(prefix=".raspv-write-check-", dir=existing)
    except OSError as exc:
        raise ValueError(f"{value}: cannot create or write in it ({existing} is not writable: "
                         f"{exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(probe)


def _check_pem(value: str) -> str:
    from raspv_common.text_files import read_text_file

    text = read_text_file(value, "PEM file")
    if "-----BEGIN " not in text:
        raise ValueError(f"{value}: not a PEM file (no '-----BEGIN' line)")
    return text


def _check_tls_certificate(value: str, params: dict) -> None:
    """The bridge's ``tls_cert`` (PEM), loaded with its ``tls_key`` as the server loads them:
    a key that does not belong to the certificate is refused here, not when the node starts."""
    import ssl

    _check_pem(value)
    key = str(params.get("tls_key") or "").strip()
    if not key or check_file("pem", key) is not None:
        return                                  # no key, or one its own check reports
    try:
        ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER).load_cert_chain(value, key)
    except ssl.SSLError as exc:
        if "KEY_VALUES_MISMATCH" in str(exc):
            raise ValueError(f"{value}: the certificate does not match the private key {key} (tls_key)") from None
        raise ValueError(f"{value}: TLS cannot load this certificate with the key {key} "
                         f"({exc.reason or _one_line(exc)})") from None


def _check_layout(value: str) -> None:
    """An implant layout (name or YAML file) loaded as the spv node loads it; a file that is
    not text is one line naming it (the loader would only say which byte is not UTF-8)."""
    from raspv_spv.implant_layout import load_layout

    _layout_file_is_text(value)
    load_layout(value)


def _layout_file_is_text(value: str) -> None:
    from pathlib import Path

    from raspv_common.text_files import read_text_file

    text = str(value).strip()
    if text.endswith((".yaml", ".yml")) or "/" in text:        # a path, as load_layout decides
        path = Path(text).expanduser()
        if path.is_file():
            read_text_file(path, "layout YAML file")


def _check_device(value: str, params: dict) -> None:
    """The spv node's ``device`` (preset name or YAML file), with the layout it names, and
    what the node will build from it: a lattice device (no layout, no ``num_phosphenes``
    override) must fit the phosphene map's limit."""
    from pathlib import Path

    from raspv_common.text_files import read_yaml_file
    from raspv_spv.device import load_device
    from raspv_spv.phosphene_map import MAX_PHOSPHENES

    path = Path(str(value).strip()).expanduser()
    if path.suffix in (".yaml", ".yml") and path.is_file():
        data = read_yaml_file(path, "device YAML file")
        if isinstance(data, dict) and isinstance(data.get("layout"), str):
            try:
                _layout_file_is_text(data["layout"])
            except ValueError as exc:
                raise ValueError(f"{value}: layout {exc}") from None
    device = load_device(value)
    if device.layout or params.get("layout") or params.get("num_phosphenes"):
        return
    if device.num_phosphenes > MAX_PHOSPHENES:
        raise ValueError(f"{value}: num_phosphenes {device.num_phosphenes} is above the limit of {MAX_PHOSPHENES} "
                         "phosphenes (use fewer, or set the spv node's num_phosphenes)")


FILE_KINDS: dict[str, FileKind] = {
    "world": FileKind("world", "raspv_sim.world_check:check_world",
                      "simulator world: shipped name or YAML file, with every mesh/URDF/SDF it names"),
    "device": FileKind("device", _check_device, "prosthesis: preset name or device YAML file", with_params=True),
    "map": FileKind("map", "raspv_common.occupancy:load_map", "map_server YAML and the image it names"),
    "bag": FileKind("bag", _check_bag, "ROS 2 bag: directory, .mcap or .db3 file"),
    "output_dir": FileKind("output_dir", _check_output_dir, "directory the node creates and writes into"),
    "pem": FileKind("pem", _check_pem, "PEM certificate or key"),
    "tls_certificate": FileKind("tls_certificate", _check_tls_certificate,
                                "PEM certificate, loaded with the node's tls_key", with_params=True),
    "layout": FileKind("layout", _check_layout, "implant electrode layout: name or YAML file"),
    "segmentation_model": FileKind("segmentation_model", _check_segmentation_model,
                                   "segmentation model (ONNX or TorchScript) with its YAML", with_params=True),
    "learned_model": FileKind("learned_model", "raspv_spv.modes.learned:check_model",
                              "learned encoder (ONNX with RASPV metadata, from raspv learn)"),
    "gaze_trace": FileKind("gaze_trace", "raspv_experiments.scripted_gaze:load_trace",
                           "gaze trace CSV: t,x,y,z,valid or t,yaw_deg,pitch_deg,valid"),
    "camera_recording": FileKind("camera_recording", "raspv_camera.drivers:check_recording",
                                 "RGB-D camera SDK recording", with_params=True),
    "slam_map": FileKind("slam_map", "raspv_slam.map_store:check_map",
                         "saved SLAM map: a name in the maps directory ($RASPV_MAPS_DIR) or a map folder"),
    "aligned_slam_map": FileKind("aligned_slam_map", "raspv_common.slam_map_files:check_aligned_map",
                                 "saved SLAM map placed on a building map by raspv slam align "
                                 "(its building_alignment.yaml is read)"),
}


def register_file_kind(name: str, check: str | Check, description: str, with_params: bool = False) -> FileKind:
    """Declare a new kind of file (e.g. from the package that loads it); returns it."""
    kind = FileKind(name, check, description, with_params)
    FILE_KINDS[name] = kind
    return kind


def check_file(kind: str, value: str, params: dict[str, Any] | None = None) -> str | None:
    """None when ``value`` is a usable file of ``kind``, else one line saying why — or one
    line per mistake, joined by newlines, when the check's exception lists them in ``errors``
    (a world with several broken entries). ``params``: the node's parameter values, for kinds
    whose check needs them."""
    spec = FILE_KINDS.get(kind)
    if spec is None:
        return f"declares an unknown file kind {kind!r} (known: {', '.join(sorted(FILE_KINDS))})"
    try:
        if spec.with_params:
            spec.checker()(value, dict(params or {}))
        else:
            spec.checker()(value)
    except (ValueError, OSError) as exc:
        errors = getattr(exc, "errors", None)
        if isinstance(errors, list) and errors and all(isinstance(e, str) for e in errors):
            return "\n".join(line for e in errors if (line := _one_line(ValueError(e))))
        return _one_line(exc) or f"{value}: not a usable {spec.description}"
    except Exception as exc:  # noqa: BLE001 - a loader's bug must still be one line, not a traceback
        return f"{value}: cannot be checked as a {kind} ({type(exc).__name__}: {_one_line(exc)})"
    return None


def check_files(params: Iterable[Param], values: dict[str, Any],
                cache: dict[tuple, str | None] | None = None) -> list[tuple[str, str]]:
    """Run the file checks of every parameter of ``params`` that declares a file kind and has a
    non-empty value in ``values``; returns (parameter, message) for each failure. ``cache``
    (kind, value) → result spares checking a file twice (two nodes naming one world)."""
    errors = []
    cache = {} if cache is None else cache
    for p in params:
        if not p.file_kind:
            continue
        value = values.get(p.name, p.default)
        for item in (value if isinstance(value, list) else [value]):
            if isinstance(item, str) and item.strip():
                kind = FILE_KINDS.get(p.file_kind)
                key = (p.file_kind, item) if kind is None or not kind.with_params else (p.file_kind, item, repr(values))
                if key not in cache:
                    cache[key] = check_file(p.file_kind, item, values)
                if cache[key]:
                    errors.extend((p.name, line) for line in cache[key].split("\n"))
    return errors


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        return f"{exc.filename}: {exc.strerror}" if exc.filename else exc.strerror
    text = str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)
    lines = [line.strip() for line in text.strip().splitlines() if line.strip()]
    return lines[0] if lines else ""
