"""Place recognition: the per-map bag of binary words finds the keyframe of a place seen before
(a revisit from a slightly different pose), k-majority training is deterministic, and the loop
closer turns a revisit into a verified loop edge."""
import numpy as np

from raspv_slam.config import SlamConfig
from raspv_slam.frame import FramePreparer
from raspv_slam.place_recognition import PlaceDatabase, Vocabulary

from .conftest import K, pose, render

# keyframes looking at different parts of the room (positions, headings)
PLACES = [(x, y, yaw) for x, y in ((-1.5, -1.0), (1.0, 1.0)) for yaw in (0.0, 60.0, 120.0, 180.0, 240.0, 300.0)]


def test_a_revisit_finds_the_keyframe_of_that_place():
    config = SlamConfig(vocabulary_first=8, vocabulary_words=300)
    prep = FramePreparer(K, config)
    db = PlaceDatabase(config)
    for i, p in enumerate(PLACES):
        db.add(i, prep.prepare(0.0, *render(pose(*p))).features.descriptors)
    assert db.vocabulary is not None and len(db.vocabulary) == 300
    hits = 0
    for i in (0, 3, 7, 10):
        x, y, yaw = PLACES[i]
        revisit = prep.prepare(0.0, *render(pose(x + 0.15, y - 0.1, yaw + 6.0)))   # 18 cm and 6° away
        best = db.query(revisit.features.descriptors, top=3)
        hits += best[0][0] == i
        assert i in [k for k, _ in best], (i, best)
    assert hits >= 3                     # top-1 for most, top-3 for all


def test_vocabulary_training_is_deterministic():
    rng = np.random.default_rng(1)
    d = rng.integers(0, 256, (3000, 32), dtype=np.uint8)
    a, b = Vocabulary.train(d, 50, seed=3), Vocabulary.train(d, 50, seed=3)
    np.testing.assert_array_equal(a.words, b.words)
    h = a.histogram(d[:100])
    assert h.sum() == 100 and len(h) == 50


def test_the_loop_closer_finds_a_revisit_despite_drift_and_corrects_the_map():
    from raspv_slam.frame_registration import FrameRegistrar
    from raspv_slam.keyframe import Keyframe, encode_images
    from raspv_slam.loop_closing import LoopCloser
    from raspv_slam.se3 import inverse
    from raspv_slam.slam_map import SlamMap

    from .conftest import motion_error

    config = SlamConfig(background=False, vocabulary_first=8, vocabulary_words=300)
    prep = FramePreparer(K, config)
    m = SlamMap(K, config)
    closer = LoopCloser(m, FrameRegistrar(K, prep.small_intrinsics, config, prep.registration), prep, config)
    # turning in place once around, then back at the start: the last keyframe revisits the first
    truth = [pose(0.3, -0.4, yaw) for yaw in range(0, 360, 30)] + [pose(0.35, -0.35, 8.0)]
    n = len(truth) - 1

    def drifted(i):            # what a drifting tracker would have believed: 2.5 m and 15° off at the end
        D = pose(2.5 * i / n, 0.0, 15.0 * i / n, z=0.0, pitch_down_deg=0.0) @ inverse(pose(0, 0, 0, z=0.0, pitch_down_deg=0.0))
        return inverse(truth[0]) @ D @ truth[i]

    for i, T in enumerate(truth):
        frame = prep.prepare(float(i), *render(T))
        kf = Keyframe(i, float(i), frame.features, *encode_images(frame.small_rgb, frame.small_depth))
        parent = None if i == 0 else i - 1
        m.add_keyframe(kf, drifted(i), parent, None if i == 0 else inverse(truth[i - 1]) @ T)
        closer.process(i)
    loops = [(e.a, e.b) for e in m.edges if e.kind == "loop"]
    assert any(b == n and a in (0, 1, 11) for a, b in loops), loops
    # after the correction the revisit sits where it is relative to the first keyframe
    dt, dr = motion_error(inverse(truth[0]) @ truth[n], inverse(m.pose(0)) @ m.pose(n))
    assert dt < 0.03 and dr < 1.0, (dt, dr)
