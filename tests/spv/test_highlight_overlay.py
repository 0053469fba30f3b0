"""The highlight overlay (paper §IV-D): classes by name over any mode, dimming, one instance
(largest / nearest), labels matched to their frame by stamp, and the temporal trails of Fig. 15."""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

from raspv_common.intrinsics import CameraIntrinsics
from raspv_perception.class_table import ClassTable
from raspv_spv.config import spv_config
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.simulator import PhospheneSimulator

WORLD = Path(__file__).resolve().parents[1] / "data" / "worlds" / "desk_and_person.yaml"
CAMERA = CameraIntrinsics.from_hfov(320, 240, 60.0)
TABLE = ClassTable.from_entries(["none", "floor", "person", "laptop", "ashcan"])


def simulator(mode="grey", temporal=False, **highlight) -> PhospheneSimulator:
    settings = {f"highlight.{k}": v for k, v in highlight.items()}
    return PhospheneSimulator(spv_config("optimist", mode=mode, overlays=["highlight"], temporal=temporal, width=400,
                                         mode_settings=settings))


@pytest.fixture(scope="module")
def office_view():
    from raspv_sim.simulator import SimConfig, Simulation
    with Simulation(WORLD, SimConfig()) as sim:
        frames = []
        for t in (4.0, 8.0):
            sim.step(t - sim.t)
            frames.append(sim.render())
        return frames, ClassTable.for_world(sim.classes)


@pytest.mark.parametrize("mode", ["grey", "depth"])
def test_asking_for_the_laptop_lights_the_laptop_and_nothing_else(office_view, mode):
    (frame, _), table = office_view
    sim = simulator(mode, classes=["laptop"])
    plain = PhospheneSimulator(spv_config("optimist", mode=mode, temporal=False, width=400))
    inputs = FrameInputs(color=frame.rgb, depth=frame.depth, camera=frame.intrinsics,
                         extras={"segmentation": frame.labels, "segmentation_classes": table})
    levels, base = sim.levels(inputs), plain.levels(inputs)
    s = sim.sampling(frame.intrinsics)
    on_laptop = s.inside & (s.sample(frame.labels) == table.id_of("laptop"))
    assert on_laptop.sum() >= 3
    assert np.array_equal(levels == 7, on_laptop | (on_laptop & (base == 7)))
    assert np.array_equal(levels[~on_laptop], np.ceil(base[~on_laptop] * 0.5).astype(np.uint8))


def test_asking_for_a_person_follows_the_walking_person(office_view):
    frames, table = office_view
    sim = simulator(classes=["people"])                 # a synonym of the world's "person"
    columns = []
    for frame in frames:
        inputs = FrameInputs(color=frame.rgb, camera=frame.intrinsics,
                             extras={"segmentation": frame.labels, "segmentation_classes": table})
        lit = sim.levels(inputs) == 7
        s = sim.sampling(frame.intrinsics)
        person = s.inside & (s.sample(frame.labels) == table.id_of("person"))
        assert lit.sum() > 5 and np.array_equal(lit & person, person) and not (lit & ~person & (s.sample(frame.labels) > 0)).any()
        columns.append(s.centres[lit, 0].mean())
    assert columns[1] > columns[0] + 40        # the walker goes from left to right across the view


def two_people_labels() -> tuple[np.ndarray, np.ndarray]:
    labels = np.zeros((240, 320), np.uint8)
    labels[60:200, 40:100] = 2          # a big person, far
    labels[120:200, 220:250] = 2        # a small person, near
    depth = np.full((240, 320), 5.0, np.float32)
    depth[60:200, 40:100] = 4.0
    depth[120:200, 220:250] = 1.5
    return labels, depth


@pytest.mark.parametrize("pick, side", [("largest", "left"), ("nearest", "right"), ("all", "both")])
def test_pick_one_instance(pick, side):
    labels, depth = two_people_labels()
    sim = simulator(classes=["person"], pick=pick)
    rgb = np.full((240, 320, 3), 100, np.uint8)
    lit = sim.levels(FrameInputs(color=rgb, depth=depth, camera=CAMERA,
                                 extras={"segmentation": labels, "segmentation_classes": TABLE})) == 7
    u = sim.sampling(CAMERA).uv[lit, 0]
    assert lit.any()
    if side == "left":
        assert (u < 160).all()
    elif side == "right":
        assert (u > 160).all()
    else:
        assert (u < 160).any() and (u > 160).any()


def test_dim_factor_and_nothing_highlighted_leaves_the_mode_alone():
    labels, _ = two_people_labels()
    rgb = np.full((240, 320, 3), 255, np.uint8)
    inputs = FrameInputs(color=rgb, camera=CAMERA, extras={"segmentation": labels, "segmentation_classes": TABLE})
    levels = simulator(classes=["person"], dim=0.25).levels(inputs)
    assert set(np.unique(levels)) <= {0, 2, 7} and (levels == 2).sum() > 100      # ⌈7 × 0.25⌉ = 2
    untouched = simulator(classes=["laptop"]).levels(inputs)                       # no laptop in view
    assert (untouched[untouched > 0] == 7).all()


def test_labels_are_used_only_with_the_frame_they_belong_to():
    labels, _ = two_people_labels()
    other = np.zeros_like(labels)
    other[:, 180:200] = 2
    rgb = np.zeros((240, 320, 3), np.uint8)
    sim = simulator(classes=["person"], max_age=0.05)
    history = ((10.0, labels), (10.1, other))

    def lit(stamp):
        inputs = FrameInputs(color=rgb, camera=CAMERA, stamp=stamp,
                             extras={"segmentation": history, "segmentation_classes": TABLE})
        return sim.sampling(CAMERA).uv[sim.levels(inputs) == 7, 0]

    assert lit(10.0).size and not ((lit(10.0) > 170) & (lit(10.0) < 210)).any()
    assert lit(10.09).size and ((lit(10.09) > 170) & (lit(10.09) < 210)).all()
    assert lit(10.3).size == 0                 # nothing within 50 ms: no highlight rather than a stale one


def test_unknown_class_highlights_nothing_and_says_so_once(caplog):
    labels, _ = two_people_labels()
    sim = simulator(classes=["lapptop"])
    inputs = FrameInputs(color=np.zeros((240, 320, 3), np.uint8), camera=CAMERA,
                         extras={"segmentation": labels, "segmentation_classes": TABLE})
    with caplog.at_level(logging.WARNING, logger="raspv.highlight"):
        for _ in range(3):
            assert not (sim.levels(inputs) == 7).any()
    assert len([r for r in caplog.records if "no class 'lapptop'" in r.getMessage()]) == 1


def test_temporal_model_leaves_trails_behind_a_moving_person():
    """Fig. 15: with the temporal model a highlighted person's phosphenes fade over several frames
    after the person moved on (and take frames to light up); without it they switch at once."""
    rgb = np.zeros((240, 320, 3), np.uint8)
    results = {}
    for temporal in (False, True):
        sim = simulator(temporal=temporal, classes=["person"])
        s = sim.sampling(CAMERA)
        history, frames = [], []
        for k in range(8):
            labels = np.zeros((240, 320), np.uint8)
            x = 60 + 25 * k                                     # walks right 25 px per frame
            labels[60:200, x:x + 40] = 2
            frames.append(s.sample(labels) == 2)
            inputs = FrameInputs(color=rgb, camera=CAMERA, extras={"segmentation": labels, "segmentation_classes": TABLE})
            history.append(sim.step(inputs).brightness)
        first = frames[0] & ~frames[1] & ~frames[2]                   # on the person in frame 0 only
        results[temporal] = [float(b[first].mean()) for b in history]
    assert results[False][0] == pytest.approx(1.0) and results[False][2] == 0.0
    assert results[True][0] < 1.0                                  # takes time to light up
    assert min(results[True][1:5]) > 0.05                          # lit on after it left: a trail
    assert results[True][7] < max(results[True])                   # that fades
