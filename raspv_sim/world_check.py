"""Check a world before a graph starts: everything the `sim` node will do with it, without rendering.

:func:`check_world` reads and validates the YAML (:func:`~raspv_sim.world_spec.load_world`),
then builds the world in a throwaway headless PyBullet client exactly as the simulator does —
every mesh, URDF and SDF it names is loaded by PyBullet, people are created, the avatar is
placed at the spawn point — so a file the launch would fail on fails here, with the same
one-line :class:`~raspv_sim.world_spec.WorldFileError`. OBJ meshes must also be text with
vertices and faces (PyBullet silently loads a binary or empty file as nothing). No rclpy.
"""
from __future__ import annotations

from pathlib import Path

from raspv_common.text_files import read_text_file
from raspv_sim.world_spec import WorldFileError, WorldSpec, display_path

_OBJ_VERTEX = ("v ", "v\t")
_OBJ_FACE = ("f ", "f\t")


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
    as an empty mesh without a word, so such a file is refused here."""
    text = read_text_file(path, "Wavefront OBJ mesh", lambda message: WorldFileError(where + message))
    lines = [line.lstrip() for line in text.splitlines()]
    if not any(line.startswith(_OBJ_VERTEX) for line in lines) or not any(line.startswith(_OBJ_FACE) for line in lines):
        raise WorldFileError(f"{where}{display_path(path)}: not a Wavefront OBJ mesh (no 'v' vertex and 'f' face lines)")
