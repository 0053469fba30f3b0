"""The BlindBot avatar: kinematic drive, blocked by walls (never through them), collision events,
slides, stairs up, no walking off edges, people walking into it."""
from __future__ import annotations

import math

import pytest

from raspv_sim.avatar import AvatarConfig
from raspv_sim.simulator import SimConfig, Simulation
from raspv_sim.world_spec import parse_world

# A 10 × 6 m room split by a wall at x = 5 (12 cm thick) with a 1 m opening centred at y = 3;
# an ascending staircase in the east half; a person walking north–south at x = 2.
WORLD = {
    "floor": {"from": [0, 0], "to": [10, 6]},
    "rooms": [{"name": "room", "from": [0, 0], "to": [10, 6]}],
    "walls": [{"name": "partition", "from": [5, 0], "to": [5, 6], "doors": [{"at": 3.0, "width": 1.0}]}],
    "stairs": [{"name": "steps", "direction": "up", "position": [6.5, 4.6], "yaw": 0, "steps": 4, "riser": 0.15,
                "tread": 0.3, "width": 1.4, "landing": 1.5}],
    "people": [{"name": "walker", "waypoints": [[2.0, 0.8], [2.0, 5.2]], "speed": 1.0, "phase": 0.0}],
    "goals": [{"name": "east", "position": [8.5, 1.5], "radius": 0.5}],
    "spawn": {"position": [1.0, 1.0], "yaw": 0},
}
WALL_FACE = 5.0 - 0.06      # west face of the partition [m]
RADIUS = AvatarConfig().body_radius


@pytest.fixture
def sim():
    spec = parse_world({**WORLD, "people": []}, "test-world")
    s = Simulation(spec, SimConfig(width=16, height=12, renderer="tiny"))
    yield s
    s.close()


def drive(sim: Simulation, v: float, w: float, seconds: float, dt: float = 0.05) -> list:
    events = []
    for _ in range(int(round(seconds / dt))):
        events += sim.step(dt, v, w).collisions
    return events


def test_moves_exactly_as_commanded(sim):
    sim.avatar.teleport(1.0, 1.0, 0.0)
    assert drive(sim, 1.0, 0.0, 1.0) == []
    assert (sim.avatar.x, sim.avatar.y) == pytest.approx((2.0, 1.0), abs=1e-9)
    drive(sim, 0.0, 1.2, 1.0)
    assert sim.avatar.yaw == pytest.approx(1.2)
    assert (sim.avatar.x, sim.avatar.y) == pytest.approx((2.0, 1.0), abs=1e-9)
    # an arc: v = 0.5 m/s, ω = 0.5 rad/s for π s is a quarter circle of radius 1 m
    sim.avatar.teleport(3.0, 1.5, 0.0)
    drive(sim, 0.5, 0.5, math.pi, dt=0.01)
    assert (sim.avatar.x, sim.avatar.y) == pytest.approx((4.0, 2.5), abs=0.01)
    assert sim.avatar.path_length == pytest.approx(1.0 + math.pi / 2, abs=0.01)


def test_speeds_are_limited(sim):
    sim.avatar.teleport(1.0, 1.0, 0.0)
    drive(sim, 10.0, 0.0, 1.0)
    assert sim.avatar.x == pytest.approx(1.0 + AvatarConfig().max_linear)
    assert sim.linear == AvatarConfig().max_linear


def test_driving_into_a_wall_stops_the_avatar_and_reports_one_collision(sim):
    sim.avatar.teleport(3.5, 1.0, 0.0)
    events = drive(sim, 1.0, 0.0, 3.0)
    assert WALL_FACE - RADIUS - 0.02 < sim.avatar.x <= WALL_FACE - RADIUS + 1e-6
    assert sim.avatar.y == pytest.approx(1.0)
    assert len(events) == 1
    e = events[0]
    assert (e.name, e.cls, e.count, e.speed) == ("partition", "wall", 1, 1.0)
    assert e.normal == pytest.approx((-1.0, 0.0, 0.0), abs=1e-6)         # from the wall to the avatar
    assert e.position[0] == pytest.approx(WALL_FACE, abs=0.02)           # the avatar's front
    x = sim.avatar.x
    assert drive(sim, 1.0, 0.0, 2.0) == [] and sim.avatar.x == x      # pushing on: no new event
    drive(sim, -0.5, 0.0, 1.0)                                          # back off, come again
    again = drive(sim, 1.0, 0.0, 2.0)
    assert [(e.name, e.count) for e in again] == [("partition", 2)]


def test_no_step_is_long_enough_to_pass_through_the_wall(sim):
    sim.avatar.teleport(4.3, 1.0, 0.0)
    for _ in range(5):
        sim.step(0.2, 1.5, 0.0)     # 30 cm per step, more than the wall is thick
        assert sim.avatar.x < WALL_FACE - RADIUS + 1e-6


def test_slides_along_a_wall_it_meets_at_an_angle(sim):
    sim.avatar.teleport(4.0, 0.6, math.radians(30))
    drive(sim, 1.0, 0.0, 2.0)
    assert sim.avatar.x < WALL_FACE - RADIUS + 1e-6
    assert sim.avatar.y > 1.5                       # slid north along the partition
    sim.avatar.config = AvatarConfig(slide=False)
    sim.avatar.teleport(4.0, 0.6, math.radians(30))
    drive(sim, 1.0, 0.0, 2.0)
    assert sim.avatar.y < 1.2                       # stopped dead


def test_walks_through_the_door_opening(sim):
    sim.avatar.teleport(4.0, 3.0, 0.0)
    events = drive(sim, 1.0, 0.0, 2.0)
    assert sim.avatar.x == pytest.approx(6.0) and events == []


def test_walks_up_the_stairs_and_will_not_step_off_the_landing(sim):
    sim.avatar.teleport(5.8, 4.6, 0.0)
    drive(sim, 0.5, 0.0, 5.0, dt=0.05)               # 2.5 m east: over 4 steps onto the landing
    assert sim.avatar.x == pytest.approx(8.3, abs=1e-6)
    assert sim.avatar.z == pytest.approx(0.6, abs=1e-4)
    assert sim.avatar.world_from_camera()[2, 3] == pytest.approx(0.6 + 1.6, abs=1e-4)
    # off the side of the landing is a 0.6 m drop: refused and reported
    sim.avatar.teleport(8.3, 4.6, math.pi / 2)
    events = drive(sim, 0.5, 0.0, 3.0)
    assert sim.avatar.y < 4.6 + 0.7 + 1e-6 and sim.avatar.z == pytest.approx(0.6, abs=1e-4)
    assert [(e.name, e.cls) for e in events] == [("edge", "drop")]


def test_a_step_too_high_blocks():
    spec = parse_world({**WORLD, "people": []}, "test-world")
    with Simulation(spec, SimConfig(width=16, height=12, renderer="tiny", avatar=AvatarConfig(max_step=0.1))) as s:
        s.avatar.teleport(5.8, 4.6, 0.0)
        events = drive(s, 0.5, 0.0, 2.0)
        assert s.avatar.x == pytest.approx(6.5 - RADIUS, abs=0.02) and s.avatar.z == pytest.approx(0.0, abs=1e-9)
        assert [(e.name, e.cls) for e in events] == [("steps", "stairs")]
        with pytest.raises(ValueError, match="fixed once the avatar exists"):
            s.avatar.config = AvatarConfig(max_step=0.2)


def test_goal_reached_once(sim):
    sim.avatar.teleport(7.5, 1.5, 0.0)
    reached = [r.goals_reached for r in (sim.step(0.05, 1.0, 0.0) for _ in range(20))]
    assert sum(len(g) for g in reached) == 1 and sim.goals_reached["east"] == pytest.approx(0.5, abs=0.06)


def test_a_person_walking_into_the_avatar_is_a_collision_and_it_can_step_away():
    spec = parse_world(WORLD, "test-world")
    with Simulation(spec, SimConfig(width=16, height=12, renderer="tiny")) as s:
        s.avatar.teleport(2.0, 3.0, 0.0)          # in the walker's path, 2.2 m ahead of it
        walker = s.world.people[0]
        p0 = s.client.getBasePositionAndOrientation(walker.uid)[0]
        events = drive(s, 0.0, 0.0, 3.0)
        p1 = s.client.getBasePositionAndOrientation(walker.uid)[0]
        assert p1[1] - p0[1] == pytest.approx(3.0, abs=1e-6)   # it walked 3 m north through the avatar
        assert [(e.name, e.cls) for e in events] == [("walker", "person")]
        s.avatar.teleport(2.0, 3.0, 0.0)
        s.world.update_people(2.2)                # now overlapping the avatar
        x = s.avatar.x
        s.step(0.0)
        drive(s, 0.5, 0.0, 1.0)                   # stepping out of the overlap is allowed
        assert s.avatar.x > x + 0.4


def test_put_where_a_person_stands_it_stays_on_the_floor():
    """A person is not ground: a walk's frame rendered where a walker is (people do not step
    aside) keeps the camera at eye height instead of standing on the walker's shoes."""
    people = [{**WORLD["people"][0], "model": "humanoid"}]
    spec = parse_world({**WORLD, "people": people}, "test-world")
    with Simulation(spec, SimConfig(width=16, height=12, renderer="tiny")) as s:
        s.world.update_people(2.2)                # the walker at (2.0, 3.0)
        for y in (2.9, 2.95, 3.0, 3.05, 3.1):
            s.avatar.teleport(2.0, y, 0.0)
            assert s.avatar.z == pytest.approx(0.0, abs=1e-6)
