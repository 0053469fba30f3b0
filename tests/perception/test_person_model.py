"""The shipped person model: the ONNX conversion against the original MediaPipe .tflite run with
LiteRT, masks on real photographs with and without people, and the depth fusion on real RGB-D
frames and on a rendered person."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from raspv_perception import scene_labels as L
from raspv_perception.person_fusion import FusionConfig, fuse_person
from raspv_perception.scene_perception import ScenePerception
from raspv_perception.segmentation import Segmenter
from raspv_perception.segmentation_models import PersonModel
from raspv_bringup.testing import dev_requirement

TFLITE = Path(__file__).resolve().parents[1] / "data" / "models" / "selfie_segmentation.tflite"
WORLD = Path(__file__).resolve().parents[1] / "data" / "worlds" / "desk_and_person.yaml"


@pytest.fixture(scope="module")
def model():
    return PersonModel()


def photographs():
    from skimage import data
    return {"astronaut": data.astronaut(), "camera": np.dstack([data.camera()] * 3)}


def test_onnx_model_matches_the_original_tflite(model, tum_frame):
    """Same 256x256 input tensor through both runtimes. Tolerance 1e-4 of a probability: the
    runtimes sum convolutions in different orders (float32), which moves outputs by ~1e-7; the
    conversion replaced one custom layer, and an error there would show as ~1e-1."""
    litert = dev_requirement("ai_edge_litert.interpreter", "ai-edge-litert")
    interp = litert.Interpreter(model_path=str(TFLITE), num_threads=1)
    interp.allocate_tensors()
    inp, out = interp.get_input_details()[0], interp.get_output_details()[0]
    images = [*photographs().values(), tum_frame[0], np.random.default_rng(1).integers(0, 256, (300, 400, 3), np.uint8)]
    for rgb in images:
        x = (cv2.resize(rgb, (256, 256), interpolation=cv2.INTER_AREA).astype(np.float32) / 255.0)[None]
        interp.set_tensor(inp["index"], x)
        interp.invoke()
        ref = interp.get_tensor(out["index"]).reshape(256, 256)
        got = model.session.run(None, {model.session.get_inputs()[0].name: x})[0].reshape(256, 256)
        assert np.abs(got - ref).max() < 1e-4
        assert ((got >= 0.5) == (ref >= 0.5)).mean() > 0.9999


def test_photographs_with_people_are_covered(model):
    """Coverage of the person in two photographs shipped with scikit-image (≈ 55 % and ≈ 32 % of
    the image in the reference-facts measurement), and little outside the person."""
    shots = photographs()
    seg = Segmenter(model)
    astro = seg.segment(shots["astronaut"]).labels.astype(bool)
    assert 0.45 < astro.mean() < 0.65
    assert astro[:120, 380:].mean() < 0.05          # the flag and the wall beside her head
    camera = seg.segment(shots["camera"]).labels.astype(bool)
    assert 0.22 < camera.mean() < 0.42
    assert camera[300:, 420:].mean() < 0.05         # the field right of the man and his tripod


def test_real_frames_without_people_stay_nearly_empty(model, tum_frame, nyu_frame, kinect_frames):
    """TUM desk, NYU basement, three PCL Kinect frames: the raw network marks at most ~0.5 %
    (a blob where the Kinect frames have no depth at their border); with the depth fusion
    nothing, for any cluster support in [0.15, 0.4] and piece size in [0.001, 0.005]."""
    for rgb, depth, camera in [tum_frame, nyu_frame, *kinect_frames]:
        p = model.probability(rgb)
        assert (p >= 0.5).mean() < 0.006
        scene = ScenePerception().process(depth, camera)
        for support in (0.15, 0.25, 0.4):
            for min_area in (0.001, 0.002, 0.005):
                fused = fuse_person(p, scene.labels, depth, FusionConfig(cluster_support=support, min_area=min_area))
                assert fused.mask.mean() < 0.001


def test_depth_fusion_completes_a_partial_mask_and_drops_surfaces():
    h, w = 120, 160
    labels = np.full((h, w), L.WALL, np.uint8)
    labels[80:] = L.FLOOR
    depth = np.full((h, w), 4.0, np.float32)
    labels[30:100, 40:70] = L.OBSTACLE           # a person 2 m away
    depth[30:100, 40:70] = 2.0
    labels[60:100, 100:130] = L.OBSTACLE         # a box 3 m away
    depth[60:100, 100:130] = 3.0
    prob = np.zeros((h, w), np.float32)
    prob[30:55, 40:70] = 0.9                      # the network saw only the head and shoulders
    prob[10:25, 90:150] = 0.95                    # and fired on the wall
    prob[85:95, 100:112] = 0.8                    # and on a corner of the box
    fused = fuse_person(prob, labels, depth)
    person = np.zeros((h, w), bool)
    person[30:100, 40:70] = True
    assert np.array_equal(fused.mask, person)
    assert (fused.clusters, fused.accepted) == (2, 1)
    raw = fuse_person(prob)                       # without depth: what the network said
    assert raw.mask[10:25, 90:150].all() and not raw.mask[60:100, 40:70].any()


def test_depth_clusters_split_at_depth_steps():
    from raspv_perception.person_fusion import depth_clusters
    cand = np.ones((20, 40), bool)
    depth = np.full((20, 40), 2.0, np.float32)
    depth[:, 20:] = 2.5                           # 25 % step: two objects side by side
    count, ids = depth_clusters(cand, depth, 0.05)
    assert count - 1 == 2 and ids[5, 5] != ids[5, 30]
    count, _ = depth_clusters(cand, depth, 0.3)   # a larger tolerance joins them
    assert count - 1 == 1


def test_a_rendered_walking_person_is_found_and_the_desk_is_not(model):
    from raspv_sim.simulator import SimConfig, Simulation
    with Simulation(WORLD, SimConfig()) as sim:
        sim.step(4.0)
        frame = sim.render()
        person = frame.labels == sim.classes.index("person")
        furniture = np.isin(frame.labels, [sim.classes.index(c) for c in ("table", "laptop", "bin")])
        scene = ScenePerception().process(frame.depth, frame.intrinsics, frame.world_from_camera)
    result = Segmenter(model).segment(frame.rgb, scene.labels, frame.depth)
    mask = result.labels.astype(bool)
    iou = (mask & person).sum() / (mask | person).sum()
    assert result.fusion.fused and iou > 0.5
    assert (mask & furniture).sum() < 0.05 * mask.sum()
