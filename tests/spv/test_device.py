"""Device presets in config/devices and user device files."""
import pytest

from raspv_spv.device import DeviceError, load_device, preset_names

# The authors' presets (reference-facts.md): N, FOV, grid, phosphene size, levels, aspect.
EXPECTED = {
    "default": (1000, 20.0, "hexagonal", 0.5, 8, 1.0),
    "argus_ii": (60, 20.0, "rectangular", 1.5, 8, 0.6),
    "argus_iii": (240, 20.0, "rectangular", 1.0, 8, 0.6),
    "alpha_ims": (1500, 11.0, "rectangular", 0.3, 8, 0.95),
    "optimist": (1000, 45.0, "hexagonal", 1.2, 8, 1.0),
}


def test_shipped_presets_have_the_reference_values():
    assert set(EXPECTED) <= set(preset_names())
    for name, values in EXPECTED.items():
        d = load_device(name)
        assert (d.num_phosphenes, d.fov_deg, d.grid, d.phosphene_fov_deg, d.num_levels, d.aspect) == values
        assert d.dropout == 0.0 and d.noise_px == 0.0 and d.name == name


def test_a_user_file_with_the_same_keys_is_a_device(tmp_path):
    path = tmp_path / "mine.yaml"
    path.write_text("name: mine\nnum_phosphenes: 100\nfov_deg: 15\ngrid: hexagonal\nphosphene_fov_deg: 1\n"
                    "num_levels: 4\nfield: circular\ndropout: 0.1\n")
    d = load_device(path)
    assert (d.num_phosphenes, d.fov_deg, d.field, d.num_levels, d.dropout) == (100, 15.0, "circular", 4, 0.1)


@pytest.mark.parametrize("text, message", [
    ("name: x\nnum_phosphenes: 10\nfov_deg: 20\ngrid: hexagonal\nphosphene_fov_deg: 1\nnum_levels: 8\ncolour: red\n",
     "unknown key\\(s\\) colour"),
    ("name: x\nnum_phosphenes: 10\nfov_deg: 20\ngrid: hexagonal\n", "missing key\\(s\\) num_levels, phosphene_fov_deg"),
    ("name: x\nnum_phosphenes: -3\nfov_deg: 20\ngrid: hexagonal\nphosphene_fov_deg: 1\nnum_levels: 8\n",
     "num_phosphenes must be a positive integer"),
    ("name: x\nnum_phosphenes: 10\nfov_deg: 20\ngrid: round\nphosphene_fov_deg: 1\nnum_levels: 1\n",
     "grid must be one of rectangular, hexagonal.*num_levels must be an integer in \\[2, 256\\]"),
    ("- just\n- a list\n", "expected a mapping"),
    ("name: [unclosed\n", "line 2, column 1: invalid YAML"),
])
def test_bad_device_files_get_one_clear_error(tmp_path, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(DeviceError, match=message) as info:
        load_device(path)
    assert str(path) in str(info.value)


def test_unknown_preset_lists_the_presets():
    with pytest.raises(DeviceError, match="unknown device preset 'argus_iv'; presets: alpha_ims, alpha_ims_implant, argus_ii"):
        load_device("argus_iv")
    with pytest.raises(DeviceError, match="does not exist"):
        load_device("/nonexistent/device.yaml")
