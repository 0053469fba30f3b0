"""The differentiable twin against the live renderer and temporal model, and its gradients."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from raspv_learn.fidelity import SPRITE_CASES, TOLERANCE, agreement
from raspv_learn.temporal_twin import TemporalTwin
from raspv_learn.twin import PhospheneTwin
from raspv_spv.config import spv_config
from raspv_spv.simulator import PhospheneSimulator
from raspv_spv.temporal_lut import TemporalState


@pytest.mark.parametrize("what, device, width, defects", SPRITE_CASES, ids=[c[0] for c in SPRITE_CASES])
def test_twin_matches_the_live_renderer_for_every_sprite_model(what, device, width, defects):
    # 14 frames with the temporal model on: rising, held, fading phosphenes
    result = agreement(device, width, frames=14, **defects)
    twin = result.twin
    assert (twin.scale > 1) == ("coarse" in what) and ("fine" in twin._matrices) == ("fine" in what)
    assert twin.levelled == ("levelled" in what)
    assert result.max_error <= TOLERANCE, what
    # and the live node's uint8 image is the twin's, rounded (±1 only at a rounding boundary)
    assert result.max_rounded_diff <= 1 and result.rounded_share < 1e-3


def test_twin_from_the_node_parameters_is_the_nodes_configuration():
    from raspv_spv.spv_params import PARAMS

    params = {p.name: p.default for p in PARAMS}
    params.update(device="argus_iii", width=160, dropout=0.2, seed=3)
    twin = PhospheneTwin.from_node_params(params)
    sim = PhospheneSimulator(spv_config("argus_iii", width=160, dropout=0.2, seed=3))
    assert twin.count == sim.count == 240
    np.testing.assert_array_equal(twin.visible.numpy() == 0, sim.map.dropped)


@pytest.mark.parametrize("model", ["horsager2009", "nanduri2012"])
def test_temporal_twin_is_the_live_look_up_table_on_the_levels_the_node_shows(model):
    config = spv_config("argus_iii", width=160, temporal_model=model)
    twin = TemporalTwin.from_config(config)
    live = TemporalState(twin.table.numpy(), 240)
    rng = np.random.default_rng(2)
    levels = rng.integers(0, 8, (40, 240))
    levels[rng.random((40, 240)) < 0.5] = 0                          # pulses come and go: trails
    amp = levels.astype(np.float32) / 7
    ours, pulses, _ = twin(torch.from_numpy(amp)[None])
    for t in range(40):
        expected = live.step(amp[t])
        np.testing.assert_allclose(ours[0, t].numpy(), expected, atol=1e-6)
        np.testing.assert_allclose(pulses[0, t].numpy(), live.amplitude, atol=1e-7)


def test_temporal_twin_continues_a_sequence_from_its_state():
    twin = TemporalTwin.from_config(spv_config("argus_iii", width=160))
    amp = torch.from_numpy(np.random.default_rng(3).integers(0, 2, (2, 16, 30)).astype(np.float32))
    whole, _, _ = twin(amp)
    first, _, state = twin(amp[:, :7])
    second, _, _ = twin(amp[:, 7:], state)
    torch.testing.assert_close(torch.cat([first, second], 1), whole)


def test_gradcheck_on_a_small_configuration():
    torch.manual_seed(0)
    # the paper's sprites, a coarse-grid tissue model and a levelled model, in double precision
    for device, kw in (("default", {"width": 24, "num_phosphenes": 12}), ("bva44", {"width": 48}),
                       ("orion_dynaphos", {"width": 32})):
        twin = PhospheneTwin(PhospheneSimulator(spv_config(device, temporal=False, **kw)), torch.float64)
        n, top = twin.count, twin.num_levels - 1
        # inside a level step (the blend between two levels' sprites is linear there) and below saturation
        step = torch.randint(0, top, (2, n), dtype=torch.float64)
        amplitude = ((step + 0.2 + 0.6 * torch.rand(2, n, dtype=torch.float64)) / top).requires_grad_()
        brightness = (amplitude.detach() * 0.5).requires_grad_()
        assert torch.autograd.gradcheck(lambda b: twin(b), (brightness,))
        if twin.levelled:
            assert torch.autograd.gradcheck(lambda b, a: twin(b, a), (brightness, amplitude))
    temporal = TemporalTwin.from_config(spv_config("argus_iii", width=160), torch.float64)
    # pulse probabilities strictly between 0 and 1 (a below level 1) and at levels ≥ 1
    amp = torch.rand(1, 5, 6, dtype=torch.float64) * 0.12 + 0.01
    amp[:, :, :3] += 0.4
    assert torch.autograd.gradcheck(lambda a: temporal(a)[0], (amp.requires_grad_(),))


def test_twin_refuses_a_wrong_batch_shape():
    twin = PhospheneTwin(PhospheneSimulator(spv_config("argus_iii", width=160, temporal=False)))
    with pytest.raises(ValueError, match=r"expected brightness of shape \(batch, 240\)"):
        twin(torch.zeros(3, 17))
