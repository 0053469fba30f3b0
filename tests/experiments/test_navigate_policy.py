"""The default virtual patient (navigate) and every policy's ability: reaction time, perceptual
threshold and noise, seeded populations — from phosphene brightness alone; and whole trials in the
cores (quick_trial): the representation decides whether it walks past the crate."""
from __future__ import annotations

import math

import numpy as np
import pytest

from raspv_experiments.navigate_policy import Navigate, row_bands
from raspv_experiments.policies import PhospheneLayout, PolicyConfig, make_policy
from raspv_experiments.subject_ability import ABILITY, subject_ability

STILL = dict(noise=0.0, perception_noise=0.0, reaction_time_s=0.0)


def grid_layout(n: int = 20, size: int = 400, fov_deg: float = 40.0) -> PhospheneLayout:
    c = (np.arange(n) + 0.5) * size / n
    x, y = np.meshgrid(c, c)
    return PhospheneLayout(x.ravel(), y.ravel(), size, size, size / (2 * math.tan(math.radians(fov_deg) / 2)))


def floor_frame(layout: PhospheneLayout) -> np.ndarray:
    """Depth-mode floor: one brightness per image row, brighter toward the bottom (nearer)."""
    return 0.2 + 0.4 * layout.y / layout.height


def test_abilities_are_seeded_spread_and_bounded():
    a, b = subject_ability(3), subject_ability(3)
    assert a == b and a != subject_ability(4)
    assert subject_ability(0) == {k: v[0] for k, v in ABILITY.items()}          # the median subject
    assert subject_ability(5, spread=0.0) == subject_ability(0)
    population = [subject_ability(n) for n in range(1, 41)]
    for name, (median, _, lo, hi) in ABILITY.items():
        values = [p[name] for p in population]
        assert lo <= min(values) and max(values) <= hi and len(set(values)) > 30
        assert np.median(values) == pytest.approx(median, rel=0.25)
    with pytest.raises(ValueError):
        subject_ability(-1)


def test_reaction_time_threshold_and_noise():
    layout = grid_layout()
    p = make_policy("wander_avoid", layout, PolicyConfig(**{**STILL, "reaction_time_s": 0.3}))
    free = np.zeros(len(layout.x))
    cmds = [p.act(free, 0.1 * k) for k in range(5)]
    assert [c.linear for c in cmds[:3]] == [0.0, 0.0, 0.0]                # standing until it reacts
    assert cmds[3].linear == pytest.approx(p.config.max_linear)          # 0.3 s after the first frame
    # below the perceptual threshold nothing is seen: a dim obstacle ahead does not turn it
    q = make_policy("wander_avoid", layout, PolicyConfig(**STILL, min_brightness=0.5))
    dim = np.zeros(len(layout.x))
    dim[(layout.y > 200)] = 0.45
    assert q.act(dim).angular == 0.0
    noisy = [make_policy("navigate", layout, PolicyConfig(seed=7, perception_noise=0.05, reaction_time_s=0.0),
                         goal=(5.0, 0.0)).act(floor_frame(layout), 0.0) for _ in range(2)]
    assert noisy[0] == noisy[1]                                          # seeded


def test_rows_of_phosphenes_look_at_one_floor_distance():
    layout = grid_layout(10)
    bands = row_bands(layout)
    assert len(np.unique(bands)) == 10
    assert all(len(np.unique(layout.y[bands == b])) == 1 for b in np.unique(bands))


def test_navigate_walks_to_the_goal_and_around_what_stands_out():
    layout = grid_layout()
    p = Navigate(layout, PolicyConfig(**STILL), goal=(6.0, 0.0))
    clear = [p.act(floor_frame(layout), 0.1 * k) for k in range(3)]
    assert clear[-1].linear == pytest.approx(p.config.max_linear) and abs(clear[-1].angular) < 0.05
    # something nearer than the floor (brighter than its rows) ahead, a little to the left
    p = Navigate(layout, PolicyConfig(**STILL), goal=(6.0, 0.0))
    frame = floor_frame(layout)
    u = layout.x - layout.width / 2
    frame[(layout.y > 230) & (layout.y < 330) & (u > -60) & (u < 20)] = 0.95
    cmds = [p.act(frame, 0.1 * k) for k in range(3)]
    assert cmds[0].angular == pytest.approx(0.0, abs=0.05)              # one frame is not enough (noise)
    assert cmds[-1].angular < -0.1                                       # then it steers right, around it
    # the goal off to the left: it turns toward it
    q = Navigate(layout, PolicyConfig(**STILL), goal=(2.0, 2.0))
    assert q.act(floor_frame(layout), 0.0).angular > 0.3


def test_a_trail_is_followed_only_with_the_path_overlay():
    layout = grid_layout()
    p = Navigate(layout, PolicyConfig(**STILL), goal=(6.0, 0.0))
    frame = np.full(len(layout.x), 0.4)
    on = np.isfinite(p.ground_distance) & (np.abs(p.ground[:, 1] + 0.5) < 0.12)   # a trail 0.5 m to the right
    frame[on] = 1.0
    assert p.act(frame, 0.0).angular == pytest.approx(0.0, abs=0.05)      # no overlay: not a trail
    p.show("grey", ("path",))
    assert p.act(frame, 0.1).angular < -0.1                              # the trail: toward it
    lost = p.act(np.full(len(layout.x), 0.4), 0.2)
    assert lost.angular < 0                                              # out of view: back where it was


def test_a_bump_makes_it_step_back_and_turn():
    layout = grid_layout()
    p = Navigate(layout, PolicyConfig(**STILL), goal=(6.0, 0.0))
    p.act(floor_frame(layout), 0.0)
    p.touch()
    bumped_at = p.pose.copy()
    back = p.act(floor_frame(layout), 0.1)
    assert back.linear < 0 and back.angular != 0.0
    later, poses = [], []
    for k in range(2, 40):
        later.append(p.act(floor_frame(layout), 0.1 * k))
        poses.append(p.pose[:2].copy())
    assert later[-1].linear > 0.1                                        # walking again within 4 s
    felt = np.array([(x, y) for x, y, _ in p.memory])                   # what it bumped into is remembered,
    assert len(felt) == 1 and np.hypot(*(felt[0] - bumped_at[:2])) < 0.4     # just ahead of where it bumped,
    assert np.hypot(*(np.array(poses) - felt[0]).T).min() > 0.25        # and walked round it (body radius)
    assert poses[-1][0] > felt[0][0]                                     # to beyond it


@pytest.mark.slow
def test_the_representation_decides_whether_they_get_past_the_crate():
    """The documented example sweep's task (the crate in the straight line to the goal), virtual
    subjects 1-4 as the sweep runs them (its seeds): with depth (the crate nearer than the floor) all
    reach the goal without touching it; downsampled grey hardly shows it: fewer reach, or bump."""
    from raspv_experiments.quick_sweep import run_quick_sweep
    from raspv_experiments.sweep import load_sweep

    from tests.experiments.conftest import REPO

    sweep = load_sweep(REPO / "experiments" / "example_sweep.yaml")
    sweep.subjects = [1, 2, 3, 4]
    records = run_quick_sweep(sweep, progress=None, workers=2)          # the suite's second core
    depth = [r for r in records if r.condition == "depth"]
    grey = [r for r in records if r.condition == "downsampling"]
    assert len(depth) == len(grey) == 4
    assert all(r.success and r.collisions == 0 for r in depth), [(r.duration_s, r.collisions) for r in depth]
    assert sum(r.success for r in grey) < 4 or sum(r.collisions for r in grey) > 0


def test_one_phosphene_is_an_obstacle_only_when_phosphenes_are_far_apart():
    """What stands out must span MIN_EXTENT_DEG of the view: a single phosphene does when the grid
    is coarse (4x4 in 40 deg: 10 deg apart); in a fine grid (50x50: 0.8 deg) it needs a neighbour,
    so perceptual noise's false alarms do not grow with the number of phosphenes."""
    for n, single_counts in ((4, True), (50, False)):
        layout = grid_layout(n)
        p = Navigate(layout, PolicyConfig(**STILL), goal=(6.0, 0.0))
        frame = floor_frame(layout)
        lone = int(np.argmin(np.hypot(layout.x - 200, layout.y - 330)))
        frame[lone] = 1.0
        for k in range(2):
            p.act(frame, 0.1 * k)
        assert bool(p.memory) == single_counts, n
        blob = np.hypot(layout.x - 200, layout.y - 330) < 25          # 3.5 deg across: an obstacle in both
        frame[blob] = 1.0
        q = Navigate(layout, PolicyConfig(**STILL), goal=(6.0, 0.0))
        for k in range(2):
            q.act(frame, 0.1 * k)
        assert q.memory, n


def test_an_obstacle_is_remembered_where_it_meets_the_floor():
    """A box face lights a run of phosphenes up a column: their rays' floor points reach far behind
    it, but only the lowest (its base) is remembered, as the floor patch between its ray and the
    ray below — nearly the same nearest cells at 10x10 and 50x50 phosphenes."""
    nearest = {}
    for n in (10, 50):
        layout = grid_layout(n)
        p = Navigate(layout, PolicyConfig(**STILL), goal=(6.0, 0.0))
        frame = floor_frame(layout)
        face = (np.abs(layout.x - 200) < 60) & (layout.y > 160) & (layout.y < 320)
        frame[face] = 1.0
        for k in range(2):
            p.act(frame, 0.1 * k)
        cells = np.array([(x, y) for x, y, _ in p.memory])
        base = p.ground[face & (layout.y == layout.y[face].max()), 0].mean()          # the lowest row of the face
        floor = p.ground[layout.y == layout.y[layout.y > layout.y[face].max()].min(), 0].mean()  # the row below it
        # between the base's ray and the floor seen below it (the patch where the base may be:
        # 5 cm cells, a step walked), nothing behind it where the face's upper rays meet the floor
        assert floor - 0.15 < cells[:, 0].min() and cells[:, 0].max() < base + 0.15, n
        assert p.ground[face, 0].max() > base + 0.7, n                                # (those reach ≥ 0.7 m further)
        nearest[n] = cells[:, 0].min()
    assert abs(nearest[10] - nearest[50]) < 0.25
