"""The discretised temporal model (paper §III-D): 1024-entry table, disk cache, history registers."""
import numpy as np
import pytest

from raspv_spv import temporal_lut
from raspv_spv.temporal import Horsager2009, current_on_grid, pulse_train_breakpoints
from raspv_spv.temporal_lut import TABLE_SIZE, TemporalLUTConfig, TemporalState, build_table, load_table

FAST = TemporalLUTConfig(dt_ms=1 / 32)     # coarse step: same code path, 8x faster to build


@pytest.fixture(scope="module")
def table():
    return load_table(TemporalLUTConfig())


def test_table_is_normalised_and_indexed_by_the_pulse_history(table):
    assert table.shape == (TABLE_SIZE,) and table.dtype == np.float32
    assert table[0] == 0.0 and table.max() == pytest.approx(1.0) and table.min() >= 0.0
    single = [table[1 << k] for k in range(10)]                 # one pulse k frames ago
    peak = int(np.argmax(single))
    assert 1 <= peak <= 3                                        # fast rise (tens of ms) ...
    assert all(np.diff(single[peak:]) < 0) and single[-1] < 0.1 * single[peak]   # ... slow decay
    held = [table[(1 << (k + 1)) - 1] for k in range(10)]       # on for the last k+1 frames
    assert all(np.diff(held) > 0) and held[-1] == pytest.approx(1.0)


def test_table_entries_are_the_continuous_model_of_that_history():
    cfg = TemporalLUTConfig(sample="end", frame_ms=20.0, dt_ms=1 / 64)
    table = build_table(cfg)
    model = Horsager2009(dt=cfg.dt_ms)
    n = int(round(200.0 / cfg.dt_ms))

    def end_of_history(bits):
        onsets = [20.0 * k for k in range(10) if bits >> (9 - k) & 1]
        t, v = pulse_train_breakpoints(onsets, cfg.pulse)
        return model.response(current_on_grid(t, v, cfg.dt_ms, n))[-1]

    ref = end_of_history(0b1111111111)
    for bits in (0b1, 0b10, 0b1010101010, 0b1100000011):
        assert table[bits] == pytest.approx(end_of_history(bits) / ref, rel=1e-5)


def test_tables_are_cached_on_disk_by_their_parameters(monkeypatch):
    first = load_table(FAST)
    files = list(temporal_lut.cache_dir().glob(f"*{FAST.key()}.npy"))
    assert len(files) == 1

    def no_build(config):
        raise AssertionError("rebuilt a cached table")

    monkeypatch.setattr(temporal_lut, "build_table", no_build)
    assert np.array_equal(load_table(FAST), first)
    other = TemporalLUTConfig(dt_ms=1 / 32, pulse_amplitude_ua=40.0)
    assert other.key() != FAST.key()
    with pytest.raises(AssertionError, match="rebuilt"):
        load_table(other)
    files[0].write_bytes(b"not a numpy file")                    # a corrupt cache is rebuilt
    monkeypatch.undo()
    assert np.array_equal(load_table(FAST), first)


def test_history_registers_shift_and_look_up_all_phosphenes_at_once(table):
    state = TemporalState(table, 3)
    b = state.step(np.array([1.0, 0.0, 0.5]))
    assert list(state.history) == [1, 0, 1] and np.allclose(b, [table[1], 0, 0.5 * table[1]])
    state.step(np.array([0.0, 0.0, 0.25]))
    assert list(state.history) == [0b10, 0, 0b11]
    for _ in range(12):
        b = state.step(np.array([1.0, 0.0, 0.5]))
    assert list(state.history) == [1023, 0, 1023] and np.allclose(b, [table[1023], 0, 0.5 * table[1023]])
    b = state.step(np.array([0.0, 0.75, 0.0]), frames=3)        # three display frames elapsed at once
    assert list(state.history) == [(1023 << 3) & 1023, 0b111, (1023 << 3) & 1023]
    # switched off: fading from the level of the latest pulse; switched on: its new level
    assert np.allclose(b, [table[(1023 << 3) & 1023], 0.75 * table[0b111], 0.5 * table[(1023 << 3) & 1023]])


def test_bad_table_parameters_are_refused():
    with pytest.raises(ValueError, match="does not fit in a frame"):
        TemporalLUTConfig(frame_ms=0.5, pulse_phase_ms=0.45)
    with pytest.raises(ValueError, match="sample must be one of"):
        TemporalLUTConfig(sample="peak")
    with pytest.raises(ValueError, match="1024 entries"):
        TemporalState(np.zeros(10), 4)
