"""The levels stream's core (no ROS): the sprite atlas reproduces the server's renderer for every
sprite model, messages round-trip, bad messages are refused, an atlas too large says so."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from raspv_hmd import protocol as P
from raspv_hmd.levels_stream import (WEIGHT_SCALE, pack_levels_payload, parse_sprites_message, sprites_message,
                                     unpack_levels_payload)
from raspv_spv.config import spv_config
from raspv_spv.simulator import PhospheneSimulator
from raspv_spv.sprite_atlas import AtlasTooLarge, SpriteAtlas, atlas_of_renderer, frame_weights
from raspv_spv.sprites_msg import atlas_from_msg, sprites_to_msg
from std_msgs.msg import Header

# device presets covering the sprite models: Gaussian (hexagonal, rectangular), axon map (coarse
# grid + fine sprites), biphasic axon map and dynaphos (one sprite per level), scoreboard on an implant
DEVICES = ["optimist", "argus_iii", "argus_ii_axon", "argus_ii_biphasic", "orion_dynaphos", "alpha_ims_implant"]


def atlas_of(sim: PhospheneSimulator, **kw) -> SpriteAtlas:
    return atlas_of_renderer(sim.renderer, sim.num_levels, **kw)


@pytest.mark.parametrize("device", DEVICES)
def test_the_atlas_draws_what_the_server_draws(device):
    """Client arithmetic (patches × weights summed, upsampled, saturated) = the renderer's, within
    one grey level: the atlas travels as half floats (2^-11 relative) and weights as uint16."""
    sim = PhospheneSimulator(spv_config(device, width=400, temporal=True))
    built = atlas_of(sim, map_id=7)
    ring = np.zeros(sim.count, bool)
    ring[::7] = True
    atlas, ring_back = parse_sprites_message(sprites_message(built, ring))   # as the browser gets it
    np.testing.assert_array_equal(ring_back, ring)
    via_ros = atlas_from_msg(sprites_to_msg(built, Header(), 7))       # as the bridge gets it
    np.testing.assert_array_equal(via_ros.atlas, atlas.atlas)
    np.testing.assert_array_equal(via_ros.patches, atlas.patches)
    assert atlas.map_id == 7 and (atlas.width, atlas.height) == (400, sim.config.height)
    rng = np.random.default_rng(1)
    for step in range(3):                                     # temporal state: brightness between levels
        levels = rng.integers(0, sim.num_levels, sim.count).astype(np.uint8)
        brightness = sim.brightness(levels)
        server = sim.render(brightness)
        sprite_levels = sim.sprite_levels if sim.renderer.levels > 1 else None
        payload = pack_levels_payload(7, frame_weights(brightness, sprite_levels, atlas.levels, sim.num_levels),
                                      sprite_levels, atlas.levels)
        map_id, weights, got_levels, flags = unpack_levels_payload(payload)
        client = atlas.render(weights, got_levels)
        diff = np.abs(server.astype(int) - client)
        assert map_id == 7 and flags == 0 and diff.max() <= 1, (device, step, diff.max())
        assert server.any()


def test_a_frame_is_two_bytes_per_phosphene_and_the_atlas_is_sent_once():
    sim = PhospheneSimulator(spv_config("optimist", width=800, temporal=False))
    payload = pack_levels_payload(1, np.full(sim.count, 0.5, np.float32), None, 1)
    assert len(payload) == 12 + 2 * sim.count                # ~2 kB for 1033 phosphenes
    assert 1.0e6 < len(sprites_message(atlas_of(sim))) < 2.5e6     # half floats, once per map


def test_weights_round_trip_within_their_quantum_and_saturate_at_four():
    w = np.array([0.0, 1e-5, 0.5, 1.0, 3.9999, 7.0, np.nan], np.float32)
    _, got, _, _ = unpack_levels_payload(pack_levels_payload(3, w, None, 1))
    np.testing.assert_allclose(got[:5], w[:5], atol=0.5 / WEIGHT_SCALE)
    assert got[5] == pytest.approx(65535 / WEIGHT_SCALE) and got[6] == 0.0


def test_levelled_weights_are_the_gain_on_each_levels_sprite():
    b = np.array([0.0, 0.5, 0.5, 1.0], np.float32)
    lv = np.array([0, 7, 3, 7], np.uint8)
    np.testing.assert_allclose(frame_weights(b, lv, levels=7, num_levels=8), [0.0, 0.5, 0.5 / (3 / 7), 1.0], rtol=1e-6)
    np.testing.assert_array_equal(frame_weights(b, None, levels=1, num_levels=8), b)


def test_bad_messages_are_refused_and_an_atlas_too_large_says_so():
    sim = PhospheneSimulator(spv_config("optimist", width=800, temporal=False))
    msg = sprites_message(atlas_of(sim))
    for bad in (msg[:20], msg[:-2], b"XXXX" + msg[4:]):
        with pytest.raises(P.ProtocolError):
            parse_sprites_message(bad)
    with pytest.raises(P.ProtocolError):
        unpack_levels_payload(pack_levels_payload(1, np.ones(10), None, 1)[:-1])
    with pytest.raises(AtlasTooLarge, match="atlas"):
        atlas_of(sim, max_side=256)
    with pytest.raises(ValueError, match="too big"):
        atlas_from_msg(sprites_to_msg(None, Header(), 3, unavailable="too big"))
    big = sp.csc_matrix((np.ones(1), ([0], [0])), shape=(100 * 100, 1))
    assert SpriteAtlas.from_matrices(big, None, 100, 100, 1, 1, 8).atlas.shape == (1, 1)
