"""Moving people: waypoint loops at constant speed; the capsule person and the animated humanoid."""
from __future__ import annotations

import math

import numpy as np
import pytest

from raspv_sim.people import WaypointLoop
from raspv_sim.simulator import SimConfig, Simulation
from raspv_sim.world_spec import parse_world


def test_waypoint_loop_walks_at_constant_speed_and_closes():
    loop = WaypointLoop(((0.0, 0.0), (4.0, 0.0), (4.0, 3.0)), speed=1.0)
    assert loop.perimeter == pytest.approx(12.0)
    assert loop.pose_at(0.0) == pytest.approx((0.0, 0.0, 0.0))
    assert loop.pose_at(2.0) == pytest.approx((2.0, 0.0, 0.0))
    assert loop.pose_at(5.5) == pytest.approx((4.0, 1.5, math.pi / 2))
    x, y, heading = loop.pose_at(9.5)          # on the way back along the hypotenuse
    assert (x, y) == pytest.approx((2.0, 1.5)) and heading == pytest.approx(math.atan2(-3, -4))
    assert loop.pose_at(12.0 + 2.0) == pytest.approx(loop.pose_at(2.0))
    assert WaypointLoop(((0.0, 0.0), (4.0, 0.0)), 0.5, phase=3.0).pose_at(2.0) == pytest.approx((4.0, 0.0, math.pi))


WORLD = {
    "floor": {"from": [0, 0], "to": [12, 6]},
    "people": [{"name": "bob", "model": "capsule", "waypoints": [[1, 2], [9, 2]], "speed": 1.2, "color": "blue"},
               {"name": "ann", "model": "humanoid", "waypoints": [[1, 4], [9, 4]], "speed": 0.9, "height": 1.7}],
    "spawn": {"position": [11, 3], "yaw": 180},
}


def test_people_walk_in_the_world_and_are_labelled_person():
    spec = parse_world(WORLD, "people-world")
    with Simulation(spec, SimConfig(width=96, height=72, renderer="tiny")) as sim:
        bob, ann = sim.world.people
        c = sim.client
        start = [np.array(c.getBasePositionAndOrientation(p.uid)[0]) for p in (bob, ann)]
        knee = c.getJointState(ann.uid, 4)[0]
        sim.step(2.5)
        moved = [np.array(c.getBasePositionAndOrientation(p.uid)[0]) - s for p, s in zip((bob, ann), start)]
        assert moved[0][:2] == pytest.approx([3.0, 0.0], abs=1e-6)
        assert moved[1][:2] == pytest.approx([2.25, 0.0], abs=1e-6)
        assert c.getJointState(ann.uid, 4)[0] != pytest.approx(knee, abs=1e-3)     # the legs swing
        frame = sim.render()
        person = sim.classes.index("person")
        assert (frame.labels == person).sum() > 60
        seen = set(np.unique(sim.camera.render(frame.world_from_camera).body).tolist())
        assert {bob.uid, ann.uid} <= seen
        # the humanoid stands about as tall as asked: its head is ~1.7 m above the floor
        top = max(c.getAABB(ann.uid, link)[1][2] for link in range(-1, c.getNumJoints(ann.uid)))
        assert 1.55 < top < 1.85
