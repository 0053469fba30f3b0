"""Turns a :class:`WorldSpec` into PyBullet bodies in a given client, and moves its people.

Every body knows its name, class label and class id; :attr:`BuiltWorld.class_lut` maps
PyBullet's segmentation buffer (body id, −1 for nothing) to class ids in one ``np.take``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pybullet
import pybullet_data

from raspv_sim.floor import floor_solid
from raspv_sim.furniture import furniture_solid
from raspv_sim.humanoid_walker import BASE_SCALE, LINK_PARTS, MODEL_HEIGHT, URDF, WalkClip, z_up_orientation
from raspv_sim.native_output import captured_native_output
from raspv_sim.people import SKIN, TROUSERS, WaypointLoop, capsule_person_parts
from raspv_sim.primitives import Part, SolidObject
from raspv_sim.staircase import floor_hole, staircase_solid
from raspv_sim.surface_textures import kind_of, part_seed, textured_box_obj
from raspv_sim.walls import wall_solids
from raspv_sim.world_spec import ModelSpec, PersonSpec, WorldFileError, WorldSpec, display_path

STRUCTURE_CLASSES = frozenset({"floor", "wall", "door", "stairs"})


@dataclass(frozen=True)
class BodyInfo:
    """What a PyBullet body is in the world file."""

    name: str
    cls: str
    class_id: int
    kind: str            # "static", "model" or "person"
    collide: bool = True
    specular: bool = False


@dataclass
class PersonBody:
    uid: int
    spec: PersonSpec
    loop: WaypointLoop
    clip: WalkClip | None = None
    scale: float = 1.0


@dataclass
class BuiltWorld:
    """The bodies of a world in one PyBullet client."""

    client: object
    spec: WorldSpec
    bodies: dict[int, BodyInfo] = field(default_factory=dict)
    people: list[PersonBody] = field(default_factory=list)
    holes: list[tuple[float, float, float, float]] = field(default_factory=list)
    class_lut: np.ndarray = field(default_factory=lambda: np.zeros(1, np.uint8))
    specular_lut: np.ndarray = field(default_factory=lambda: np.zeros(1, bool))

    def finish(self, extra_uids: tuple[int, ...] = ()) -> None:
        """(Re)build the look-up tables after bodies were added (``extra_uids`` map to class 0)."""
        top = max([*self.bodies, *extra_uids, 0])
        self.class_lut = np.zeros(top + 2, np.uint8)
        self.specular_lut = np.zeros(top + 2, bool)
        for uid, info in self.bodies.items():
            self.class_lut[uid + 1] = info.class_id
            self.specular_lut[uid + 1] = info.specular

    def info(self, uid: int) -> BodyInfo | None:
        return self.bodies.get(uid)

    def static_uids(self, structure_only: bool = False) -> list[int]:
        """Bodies that never move (and collide); with ``structure_only`` only floor, walls, doors, stairs."""
        return [uid for uid, b in self.bodies.items() if b.kind != "person" and b.collide
                and (not structure_only or b.cls in STRUCTURE_CLASSES)]

    def update_people(self, t: float) -> None:
        """Place every person where its loop is at time ``t`` [s]."""
        c = self.client
        for person in self.people:
            x, y, heading = person.loop.pose_at(t)
            if person.clip is None:
                c.resetBasePositionAndOrientation(person.uid, (x, y, 0.0), (0.0, 0.0, math.sin(heading / 2), math.cos(heading / 2)))
                continue
            pose = person.clip.pose(person.loop.distance_at(t), person.scale)
            c.resetBasePositionAndOrientation(person.uid, (x, y, pose.root_height), z_up_orientation(heading, pose.root_quat))
            c.resetJointStatesMultiDof(person.uid, list(pose.joints), targetValues=list(pose.joints.values()))


class _ShapeCache:
    """Collision and visual shapes shared by parts of equal size (and colour); with ``textures``
    static boxes are drawn with their class's surface texture (:mod:`raspv_sim.surface_textures`)."""

    def __init__(self, client, textures: bool = False):
        self.c = client
        self.textures = textures
        self.collision: dict = {}
        self.visual: dict = {}

    def _args(self, part: Part) -> tuple[int, dict]:
        sx, sy, sz = part.size
        if part.shape == "box":
            return pybullet.GEOM_BOX, {"halfExtents": [sx / 2, sy / 2, sz / 2]}
        if part.shape == "sphere":
            return pybullet.GEOM_SPHERE, {"radius": sx / 2}
        if part.shape == "cylinder":
            return pybullet.GEOM_CYLINDER, {"radius": sx / 2, "height": sz}
        if part.shape == "capsule":
            return pybullet.GEOM_CAPSULE, {"radius": sx / 2, "height": sz}
        raise ValueError(f"unknown primitive {part.shape!r}")

    def collision_shape(self, part: Part) -> int:
        if not part.collide:
            return -1
        key = (part.shape, part.size)
        if key not in self.collision:
            geom, kw = self._args(part)
            self.collision[key] = self.c.createCollisionShape(geom, **kw)
        return self.collision[key]

    def visual_shape(self, part: Part, cls: str = "") -> int:
        if not part.visible:
            return -1
        if self.textures and part.shape == "box":
            kind = kind_of(cls)           # walls: one texture each; floor and furniture: a few shared ones
            seed = 0 if kind == "floor" else part_seed(part.position, part.size) % (4 if kind == "other" else 2**32)
            key = ("textured", part.size, part.color, kind, seed)
            if key not in self.visual:
                obj = textured_box_obj(part.size, cls, part.color, seed)
                self.visual[key] = self.c.createVisualShape(pybullet.GEOM_MESH, fileName=str(obj),
                                                            specularColor=[0.0, 0.0, 0.0])
            return self.visual[key]
        key = (part.shape, part.size, part.color)
        if key not in self.visual:
            geom, kw = self._args(part)
            if part.shape in ("cylinder", "capsule"):
                kw = {"radius": kw["radius"], "length": kw["height"]}
            self.visual[key] = self.c.createVisualShape(geom, rgbaColor=[*part.color, 1.0], specularColor=[0.0, 0.0, 0.0], **kw)
        return self.visual[key]


def _solid_body(c, shapes: _ShapeCache, obj: SolidObject, origin=(0.0, 0.0, 0.0)) -> int:
    """One multibody: a shapeless base at ``origin`` and one fixed link per part."""
    inv_pos = [-v for v in origin]
    n = len(obj.parts)
    return c.createMultiBody(
        baseMass=0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1, basePosition=list(origin),
        linkMasses=[0.0] * n,
        linkCollisionShapeIndices=[shapes.collision_shape(p) for p in obj.parts],
        linkVisualShapeIndices=[shapes.visual_shape(p, obj.cls) for p in obj.parts],
        linkPositions=[[p.position[0] + inv_pos[0], p.position[1] + inv_pos[1], p.position[2] + inv_pos[2]] for p in obj.parts],
        linkOrientations=[list(p.quaternion) for p in obj.parts],
        linkInertialFramePositions=[[0.0, 0.0, 0.0]] * n, linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * n,
        linkParentIndices=[0] * n, linkJointTypes=[pybullet.JOINT_FIXED] * n, linkJointAxis=[[0.0, 0.0, 1.0]] * n)


def static_solids(spec: WorldSpec) -> list[SolidObject]:
    """Floor, walls (+ door leaves), furniture and staircases as primitive solids."""
    holes = [h for h in (floor_hole(s) for s in spec.stairs) if h is not None]
    solids = [floor_solid(spec.floor, holes)]
    for wall in spec.walls:
        solids += wall_solids(wall)
    solids += [furniture_solid(f) for f in spec.furniture]
    solids += [staircase_solid(s) for s in spec.stairs]
    return solids


def build_world(client, spec: WorldSpec, textures: bool = False) -> BuiltWorld:
    """Create every body of ``spec`` in ``client`` (a connected PyBullet client); ``textures``
    draws static boxes with surface texture instead of flat colour."""
    world = BuiltWorld(client, spec)
    world.holes = [h for h in (floor_hole(s) for s in spec.stairs) if h is not None]
    shapes = _ShapeCache(client, textures)
    for obj in static_solids(spec):
        if not obj.parts:
            continue
        uid = _solid_body(client, shapes, obj)
        world.bodies[uid] = BodyInfo(obj.name, obj.cls, spec.class_id(obj.cls), "static", True, obj.specular)
    for model in spec.models:
        for uid in _load_model(client, model, spec.source):
            world.bodies[uid] = BodyInfo(model.name, model.cls, spec.class_id(model.cls), "model", model.collision, model.specular)
    data_dir = pybullet_data.getDataPath()
    clip = None
    for person in spec.people:
        loop = WaypointLoop(person.waypoints, person.speed, person.phase)
        if person.model == "capsule":
            obj = SolidObject(person.name, person.cls, tuple(capsule_person_parts(person)))
            uid = _solid_body(client, shapes, obj)
            body = PersonBody(uid, person, loop)
        else:
            clip = clip or WalkClip(data_dir)
            scale = person.height / MODEL_HEIGHT
            with captured_native_output():
                uid = client.loadURDF(f"{data_dir}/{URDF}", [0, 0, 0], useFixedBase=True, globalScaling=BASE_SCALE * scale,
                                      flags=pybullet.URDF_MAINTAIN_LINK_ORDER)
            _dress_humanoid(client, uid, person.color)
            body = PersonBody(uid, person, loop, clip, scale)
        world.people.append(body)
        world.bodies[uid] = BodyInfo(person.name, person.cls, spec.class_id(person.cls), "person", True)
    world.update_people(0.0)
    world.finish()
    return world


def _dress_humanoid(c, uid: int, shirt) -> None:
    colours = {"hips": TROUSERS, "leg": TROUSERS, "foot": (0.1, 0.1, 0.1), "torso": shirt, "arm": shirt,
               "head": SKIN, "hand": SKIN}
    for link, part in LINK_PARTS.items():
        c.changeVisualShape(uid, link, rgbaColor=[*colours[part], 1.0])


def _load_model(c, m: ModelSpec, spec_source=None) -> list[int]:
    yaw = math.radians(m.yaw)
    q_yaw = (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
    q = c.multiplyTransforms([0, 0, 0], q_yaw, [0, 0, 0], (math.sin(math.pi / 4), 0, 0, math.cos(math.pi / 4)))[1] \
        if m.up == "y" else q_yaw
    with captured_native_output() as out:
        try:
            if m.kind == "obj":
                kw = {"fileName": str(m.file), "meshScale": [m.scale] * 3}
                vis = c.createVisualShape(pybullet.GEOM_MESH, **kw, **({"rgbaColor": [*m.color, 1.0]} if m.color else {}))
                col = c.createCollisionShape(pybullet.GEOM_MESH, flags=pybullet.GEOM_FORCE_CONCAVE_TRIMESH, **kw) \
                    if m.collision else -1
                uids = [c.createMultiBody(0, col, vis, basePosition=list(m.position), baseOrientation=list(q))]
            elif m.kind == "urdf":
                uids = [c.loadURDF(str(m.file), list(m.position), list(q), useFixedBase=True, globalScaling=m.scale)]
            else:
                uids = list(c.loadSDF(str(m.file), globalScaling=m.scale))
                for uid in uids:
                    pos, orn = c.getBasePositionAndOrientation(uid)
                    pos, orn = c.multiplyTransforms(list(m.position), list(q), pos, orn)
                    c.resetBasePositionAndOrientation(uid, pos, orn)
        except pybullet.error as exc:
            failure = str(exc)
        else:
            failure = ""
    if failure or any(u < 0 for u in uids):
        detail = " ".join(line.strip() for line in out.text.splitlines() if line.strip())[-200:]
        src = display_path(spec_source) if spec_source else "<world>"
        raise WorldFileError(f"{src}: {m.where}: PyBullet could not load {m.file} ({failure or 'invalid model'}){': ' + detail if detail else ''}")
    for uid in uids:
        links = range(-1, c.getNumJoints(uid))
        if m.color is not None:
            for link in links:
                c.changeVisualShape(uid, link, rgbaColor=[*m.color, 1.0])
        if not m.collision:
            for link in links:
                c.setCollisionFilterGroupMask(uid, link, 0, 0)
    return uids
