"""Trials in the simulator core (start pose, people restart, trial goals, collision count) and lockstep stepping."""
from __future__ import annotations

import math

import pytest

from raspv_sim.lockstep import Lockstep
from raspv_sim.simulator import SimConfig, Simulation
from raspv_sim.world_spec import GoalSpec


def test_start_trial_resets_the_avatar_people_goals_and_collisions(tmp_path):
    with Simulation("office", SimConfig(width=16, height=12, renderer="tiny")) as sim:
        for _ in range(20):
            sim.step(0.1, 1.0, 0.3)
        person = sim.world.people[0]
        start_pose = person.loop.pose_at(0.0)
        sim.start_trial(10.0, 6.0, math.pi / 2, (GoalSpec("task:ahead", (10.0, 7.0), 0.5),))
        a = sim.avatar
        assert (a.x, a.y, a.yaw, a.path_length, a.head) == (10.0, 6.0, math.pi / 2, 0.0, (0.0, 0.0, 0.0, 1.0))
        assert sim.t == pytest.approx(2.0)                      # time never goes back
        assert sim.world.client.getBasePositionAndOrientation(person.uid)[0][:2] == pytest.approx(start_pose[:2], abs=1e-6)
        log = sim.start_log(tmp_path, run_name="trial-1")
        assert log.dir == tmp_path / "trial-1"
        reports = [sim.step(0.1, 1.0, 0.0) for _ in range(10)]
        assert any(r.goals_reached == ["task:ahead"] for r in reports)
        summary, _ = sim.finish_log(plot=False)
        assert "task:ahead" in summary["goals_reached"]
        with pytest.raises(ValueError, match="overlaps"):
            sim.start_trial(19.6, 11.6, 0.0)                     # inside the bin
        assert (sim.avatar.x, sim.avatar.y) != (19.6, 11.6)
        sim.start_trial(1.0, 6.0, 0.0)
        assert sim.monitor.count == 0 and sim.trial_goals == () and sim.goals_reached == {}


def test_lockstep_steps_when_the_last_frame_is_answered():
    ls = Lockstep(timeout_s=2.0)
    assert ls.poll(0.0) and ls.take() == (0.0, 0.0)            # the first frame goes out at once
    ls.published(0.1, wall=10.0)
    assert not ls.poll(10.5)
    assert not ls.answer(0.05, 1.0, 0.0)                       # an answer to an older frame does not count
    assert not ls.poll(10.6)
    assert ls.answer(0.1 - 1e-8, 0.5, -0.2)                    # stamps round-trip through nanoseconds
    assert ls.poll(10.7) and ls.take() == (0.5, -0.2)
    ls.published(0.2, wall=11.0)
    assert not ls.poll(12.9) and ls.poll(13.0) and ls.timeouts == 1   # no answer: step anyway, counted
    assert ls.take() == (0.5, -0.2)                             # with the last command
    with pytest.raises(ValueError):
        Lockstep(timeout_s=0.0)


def test_lockstep_participants_hold_and_restart():
    ls = Lockstep(timeout_s=2.0, participants=frozenset({"planner"}))
    assert ls.poll(0.0) and ls.take() == (0.0, 0.0)
    ls.published(0.1, wall=1.0)
    assert not ls.answer(0.1, 0.4, 0.1)                        # the subject answered; the planner not yet
    assert not ls.poll(1.5)
    assert ls.answer(0.1, 0.0, 0.0, who="planner")             # now both: the step goes with the subject's command
    assert ls.poll(1.6) and ls.take() == (0.4, 0.1)
    ls.published(0.2, wall=2.0)
    ls.answer(0.2, 0.0, 0.0, who="planner")
    assert ls.answer(0.2, 0.3, 0.0)                            # in either order
    ls.hold = True
    assert not ls.poll(100.0) and ls.timeouts == 0              # held: no step, no timeout
    ls.hold = False
    ls.restart()                                                # a new trial: at once, standing still
    assert not ls.answer(0.2, 1.0, 1.0)                         # an answer to a frame before it does not count
    assert ls.poll(100.0) and ls.take() == (0.0, 0.0)


def test_strict_lockstep_waits_for_every_answer_however_late():
    """A scripted session (lockstep_hold) never steps on a timeout: at load 10-16 a frame's answer
    took over 2 s and the world stepped with the previous command, so a repetition parted."""
    ls = Lockstep(timeout_s=2.0, participants=frozenset({"planner"}), strict=True)
    assert ls.poll(0.0) and ls.take() == (0.0, 0.0)
    ls.published(0.1, wall=10.0)
    ls.answer(0.1, 0.0, 0.0, who="planner")
    assert not ls.poll(13.0) and not ls.poll(60.0)              # late: waits, counted once, no timeout
    assert (ls.late, ls.timeouts, ls.missing()) == (1, 0, ["controller"])
    assert ls.answer(0.1, 0.7, 0.1) and ls.poll(61.0) and ls.take() == (0.7, 0.1)
