"""The continuous temporal models against pulse2percept's implementation of the same models.

Tolerance: 1e-4 of the response peak. pulse2percept integrates in float32 and compares
float32 times i*dt with the stimulus breakpoints; with dt = 1/256 ms every i*dt is exact and
breakpoints half a step away from the grid cannot be rounded to another step, so both codes
integrate the very same stimulus and agree to float32 precision. With pulse2percept's default
dt = 0.005 ms (not exact in binary) a phase edge can move by one 5 µs step; a 0.45 ms phase is
then ~1 % longer or shorter, which β = 3.43 turns into a few % of brightness: checked at 3 %.
"""
import numpy as np
import pytest

from raspv_bringup.testing import dev_requirement

dev_requirement("pulse2percept")
from pulse2percept.models.retina import Horsager2009Temporal, Nanduri2012Temporal  # noqa: E402
from pulse2percept.stimuli import BiphasicPulseTrain, Stimulus  # noqa: E402

from raspv_spv.temporal import (BiphasicPulse, Horsager2009, Nanduri2012, current_on_grid,  # noqa: E402
                                pulse_train_breakpoints, temporal_model)

DT = 1.0 / 256.0
T_MS = 300.0

STIMULI = {
    "single pulse": ([5.0], BiphasicPulse(30.0, 0.4525)),
    "50 Hz train": (np.arange(0.0, 200.0, 20.0), BiphasicPulse(30.0, 0.4525)),
    "irregular, with gap": ([0.0, 20.0, 40.0, 100.0, 230.0], BiphasicPulse(50.0, 1.0025, 0.1)),
    "anodic first, 25 Hz": (np.arange(10.0, 250.0, 40.0), BiphasicPulse(20.0, 0.4525, 0.0, cathodic_first=False)),
}
MODELS = [(Horsager2009, Horsager2009Temporal), (Nanduri2012, Nanduri2012Temporal)]


def p2p_and_ours(ours, theirs, times, values, dt, t_out):
    n = int(round(T_MS / dt))
    mine = ours.response(current_on_grid(times, values, dt, n))[np.round(t_out / dt).astype(int)]
    stim = Stimulus(values[None].astype(np.float32), time=times.astype(np.float32))
    ref = theirs.predict_percept(stim, t_percept=t_out).data.ravel()
    return mine, ref


@pytest.mark.parametrize("ours_cls, theirs_cls", MODELS, ids=["horsager2009", "nanduri2012"])
@pytest.mark.parametrize("stimulus", list(STIMULI), ids=list(STIMULI))
def test_model_matches_pulse2percept(ours_cls, theirs_cls, stimulus):
    onsets, pulse = STIMULI[stimulus]
    times, values = pulse_train_breakpoints(np.asarray(onsets) + DT / 2, pulse)
    # pulse2percept holds the first breakpoint's value from t = 0: start with a 0 at t = 0
    times, values = np.r_[0.0, times, T_MS], np.r_[0.0, values, 0.0]
    t_out = np.arange(0.0, T_MS, 0.5)
    mine, ref = p2p_and_ours(ours_cls(dt=DT), theirs_cls(dt=DT, verbose=False).build(), times, values, DT, t_out)
    assert ref.max() > 0
    assert np.abs(mine - ref).max() <= 1e-4 * ref.max()


@pytest.mark.parametrize("ours_cls, theirs_cls", MODELS, ids=["horsager2009", "nanduri2012"])
def test_pulse2percept_pulse_train_at_its_default_step(ours_cls, theirs_cls):
    train = BiphasicPulseTrain(20, 30, 0.45, interphase_dur=0.1, stim_dur=T_MS)
    t_out = np.arange(0.0, T_MS, 1.0)
    mine, ref = p2p_and_ours(ours_cls(dt=0.005), theirs_cls(dt=0.005, verbose=False).build(),
                             train.time, train.data[0], 0.005, t_out)
    assert np.abs(mine - ref).max() <= 0.03 * ref.max()


def test_single_pulse_rises_fast_and_decays_slowly():
    dt = 1 / 64
    times, values = pulse_train_breakpoints([0.0], BiphasicPulse())
    r = Horsager2009(dt=dt).response(current_on_grid(times, values, dt, int(400 / dt)))
    t = np.arange(r.size) * dt
    peak = t[np.argmax(r)]
    half_before = t[(t < peak) & (r > r.max() / 2)][0]
    half_after = t[(t > peak) & (r < r.max() / 2)][0]
    tenth_after = t[(t > peak) & (r < r.max() / 10)][0]
    assert 30 < peak < 90
    assert half_after - peak > 1.5 * (peak - half_before)          # decays slower than it rises
    assert 150 < tenth_after < 250                                  # a response of about 200 ms


def test_bad_stimuli_and_parameters_are_refused():
    with pytest.raises(ValueError, match="pulses overlap"):
        pulse_train_breakpoints([0.0, 0.5], BiphasicPulse(phase_ms=0.45))
    with pytest.raises(ValueError, match="must be smaller than tau1"):
        Horsager2009(dt=1.0)
    with pytest.raises(ValueError, match="amplitude must be a positive"):
        BiphasicPulse(amplitude_ua=-5)
    with pytest.raises(ValueError, match="unknown temporal model 'wilson'"):
        temporal_model("wilson")
