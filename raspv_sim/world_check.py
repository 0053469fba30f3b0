"""Check a world before a graph starts: everything the `sim` node will do with it, without rendering.

:func:`check_world` reads and validates the YAML (:func:`~raspv_sim.world_spec.load_world`),
then builds the world in a throwaway headless PyBullet client exactly as the simulator does —
every mesh, URDF and SDF it names is loaded by PyBullet, people are created, the avatar is
placed at the spawn point — so a file the launch would fail on fails here, with the same
one-line :class:`~raspv_sim.world_spec.WorldFileError`. OBJ meshes must also be text with
finite vertices and faces that name existing vertices (PyBullet silently loads a binary or
empty file as nothing, and a NaN vertex or a face index past the vertex count without a
word). No rclpy.
"""
from __future__ import annotations

import math
from pathlib import Path

from raspv_common.text_files import read_text_file
from raspv_sim.world_spec import WorldFileError, WorldSpec, display_path



def check_world(world: str) -> WorldSpec:
    """The validated world ``world`` (shipped name or YAML path); raises :class:`WorldFileError`
    with one line naming the file and the entry when the simulator could not load it."""
    from raspv_sim.world_spec import load_world

    spec = load_world(world)
    src = display_path(spec.source) if spec.source else spec.name
    for m in spec.models:
        if m.kind == "obj":
            _check_obj_text(m.file, f"{src}: {m.where}: ")
    from raspv_sim.native_output import captured_native_output

    try:
        with captured_native_output():    # PyBullet's banner and loader chatter
            from raspv_sim.simulator import SimConfig, Simulation

            with Simulation(spec, SimConfig(width=16, height=12, renderer="tiny")):
                pass
    except WorldFileError:
        raise
    except (ValueError, RuntimeError) as exc:
        raise WorldFileError(f"{src}: the simulator cannot build this world ({str(exc).splitlines()[0]})") from None
    return spec


def _check_obj_text(path: Path, where: str) -> None:
    """A Wavefront OBJ is text with vertices and faces; PyBullet loads a binary or empty file
    as an empty mesh without a word, and a NaN vertex or a face naming a vertex that does not
    exist without a warning either, so such files are refused here (the first fault, with its
    line). Face indices are 1-based, negative ones count back from the last vertex so far."""
    text = read_text_file(path, "Wavefront OBJ mesh", lambda message: WorldFileError(where + message))
    shown = f"{where}{display_path(path)}"
    vertices = faces = 0
    highest = (0, 0)                       # (largest positive face index, its line)
    for number, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if not parts or parts[0] not in ("v", "f"):
            continue
        if parts[0] == "v":
            try:
                xyz = [float(x) for x in parts[1:4]]
            except ValueError:
                raise WorldFileError(f"{shown}: line {number}: vertex '{line.strip()[:60]}' is not three numbers") from None
            if len(xyz) < 3:
                raise WorldFileError(f"{shown}: line {number}: vertex '{line.strip()[:60]}' has fewer than three coordinates")
            if not all(math.isfinite(x) for x in xyz):
                raise WorldFileError(f"{shown}: line {number}: vertex {vertices + 1} is not finite ({' '.join(parts[1:4])})")
            vertices += 1
            continue
        if len(parts) < 4:
            raise WorldFileError(f"{shown}: line {number}: a face needs at least three vertices, got '{line.strip()[:60]}'")
        for ref in parts[1:]:
            try:
                index = int(ref.split("/")[0])
            except ValueError:
                raise WorldFileError(f"{shown}: line {number}: face vertex '{ref}' is not an index") from None
            if index == 0 or -index > vertices:
                raise WorldFileError(f"{shown}: line {number}: face index {index} names no vertex "
                                     f"({vertices} vertices before it; indices start at 1)")
            if index > highest[0]:
                highest = (index, number)
        faces += 1
    if not vertices or not faces:
        raise WorldFileError(f"{shown}: not a Wavefront OBJ mesh (no 'v' vertex and 'f' face lines)")
    if highest[0] > vertices:
        raise WorldFileError(f"{shown}: line {highest[1]}: face index {highest[0]} is past the vertex count ({vertices})")
