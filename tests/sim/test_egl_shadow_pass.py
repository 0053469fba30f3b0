"""The EGL plugin's shadow-map pass (it ignores shadow=0) is turned off when the simulator loads
it; depth and labels do not depend on it, colour loses only the cast shadows; a file that is not
the loaded plugin is left alone with a reason (raspv_sim.egl_shadow_pass)."""
from __future__ import annotations

import importlib.util
import shutil

import numpy as np
import pytest

from raspv_sim.egl_shadow_pass import set_shadow_map
from raspv_sim.simulator import SimConfig, Simulation


@pytest.fixture(scope="module")
def egl_sim():
    s = Simulation("apartment", SimConfig(width=160, height=120, renderer="auto"))
    if s.renderer.name != "egl":
        s.close()
        pytest.skip(f"no EGL renderer here: {s.renderer.description}")
    yield s
    s.close()


def plugin() -> str:
    return importlib.util.find_spec("eglRenderer").origin


def test_the_simulator_turns_the_pass_off_and_only_shadows_change(egl_sim):
    assert "shadow-map pass left on" not in egl_sim.renderer.description
    without = egl_sim.render()
    assert set_shadow_map(plugin(), True) is None           # PyBullet's own behaviour, for comparison
    try:
        with_pass = egl_sim.render()
    finally:
        assert set_shadow_map(plugin(), False) is None
    np.testing.assert_array_equal(np.isnan(without.depth), np.isnan(with_pass.depth))
    # the two passes use different shader programs: depth rounds differently on a few edge pixels
    np.testing.assert_allclose(without.depth, with_pass.depth, rtol=1e-3, equal_nan=True)
    np.testing.assert_array_equal(without.labels, with_pass.labels)
    # cast shadows darken; the shadow shader's lighting differs a little elsewhere (0.5 % of the
    # pixels brighter by more than 3 levels here)
    change = with_pass.rgb.astype(int).sum(axis=2) - without.rgb.astype(int).sum(axis=2)
    assert (change < -3).mean() > 0.05 and (change > 3).mean() < 0.02


def test_files_that_are_not_the_loaded_plugin_are_left_alone(tmp_path, egl_sim):
    garbage = tmp_path / "garbage.so"
    garbage.write_bytes(b"not an ELF file at all")
    assert "could not be read" in set_shadow_map(str(garbage), False)
    copy = tmp_path / "eglRenderer_copy.so"
    shutil.copy(plugin(), copy)                               # the same symbols, not mapped in this process
    assert set_shadow_map(str(copy), False) == "the plugin is not loaded in this process"
    assert "could not be read" in set_shadow_map(str(tmp_path / "missing.so"), False)
