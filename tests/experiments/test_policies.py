"""Scripted subjects: what they do from phosphene brightness alone."""
from __future__ import annotations

import math

import numpy as np
import pytest

from raspv_experiments.policies import FollowPath, PhospheneLayout, PolicyConfig, WanderAvoid, make_policy


def grid_layout(n: int = 30, size: int = 600, fov_deg: float = 45.0) -> PhospheneLayout:
    c = (np.arange(n) + 0.5) * size / n
    x, y = np.meshgrid(c, c)
    return PhospheneLayout(x.ravel(), y.ravel(), size, size, size / (2 * math.tan(math.radians(fov_deg) / 2)))


def trail(layout: PhospheneLayout, policy, lateral: float, level: float = 1.0, rest: float = 0.4) -> np.ndarray:
    """Brightness with a straight trail on the floor at ``lateral`` m to the left (rest dimmed)."""
    b = np.full(len(layout.x), rest)
    on = np.isfinite(policy.ground_distance) & (np.abs(policy.ground[:, 1] - lateral) < 0.15)
    b[on] = level
    return b


def test_floor_projection_matches_the_head_pose():
    layout = grid_layout()
    p = FollowPath(layout, PolicyConfig(head_pitch_deg=30.0, eye_height=1.6, noise=0.0))
    centre = int(np.argmin((layout.x - 300) ** 2 + (layout.y - 300) ** 2))
    # the image centre looks 30 deg down: the floor 1.6 / tan(30 deg) m ahead
    assert p.ground[centre, 0] == pytest.approx(1.6 / math.tan(math.radians(30)), rel=0.05)
    assert abs(p.ground[centre, 1]) < 0.1


@pytest.mark.parametrize("lateral, sign", [(0.6, 1.0), (-0.6, -1.0)])
def test_follow_path_steers_toward_the_bright_trail(lateral, sign):
    layout = grid_layout()
    p = FollowPath(layout, PolicyConfig(noise=0.0))
    cmd = p.act(trail(layout, p, lateral))
    assert cmd.linear > 0.1 and sign * cmd.angular > 0.1
    straight = p.act(trail(layout, p, 0.0))
    assert straight.linear == pytest.approx(p.config.max_linear, rel=0.05) and abs(straight.angular) < 0.1


def test_follow_path_searches_where_it_last_saw_the_trail():
    layout = grid_layout()
    p = FollowPath(layout, PolicyConfig(noise=0.0))
    p.act(trail(layout, p, -0.8))
    lost = p.act(np.zeros(len(layout.x)))
    assert lost.linear == 0.0 and lost.angular < 0                      # turns right, where it was
    # without an overlay every lit phosphene is alike: nothing stands out as a trail to follow
    uniform = p.act(np.full(len(layout.x), 0.05))
    assert uniform.linear == 0.0


def test_wander_avoid_turns_away_from_bright_near_things():
    layout = grid_layout()
    w = WanderAvoid(layout, PolicyConfig(noise=0.0))
    free = w.act(np.zeros(len(layout.x)))
    assert free.linear == pytest.approx(w.config.max_linear) and free.angular == 0.0
    b = np.zeros(len(layout.x))
    b[(layout.y > 300) & (layout.x > 250)] = 1.0                         # something near, ahead and to the right
    cmd = w.act(b)
    assert cmd.angular > 0 and cmd.linear < 0.1                          # turns left, nearly stops


def test_seeded_noise_and_validation():
    layout = grid_layout(10)
    a = [make_policy("wander_avoid", layout, PolicyConfig(seed=3, noise=0.2)).act(np.zeros(100)).angular for _ in range(2)]
    assert a[0] == a[1] != 0.0
    with pytest.raises(ValueError, match="unknown scripted-subject policy"):
        make_policy("teleport", layout)
    with pytest.raises(ValueError, match="brightness values for 100 phosphenes"):
        make_policy("follow_path", layout).act(np.zeros(5))


def test_a_blocked_subject_steps_back():
    """Walking while the view does not change (no optic flow): the subject steps back and turns."""
    layout = grid_layout()
    p = FollowPath(layout, PolicyConfig(noise=0.0))
    frame = trail(layout, p, 0.0)
    cmds = [p.act(frame) for _ in range(p.STILL_FRAMES + 2)]
    assert cmds[0].linear > 0.1
    assert cmds[-1].linear < 0 and cmds[-1].angular != 0.0
    later = [p.act(frame) for _ in range(p.BACK_FRAMES + 2)]
    assert later[-1].linear > 0.1                                        # then walks on
