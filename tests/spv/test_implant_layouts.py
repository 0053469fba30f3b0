"""Implant layouts: the shipped electrode positions are pulse2percept's, placement is its
``implant_rotation`` + ``implant_position``, Neuralink threads come from the cortical map as
its factory places them, every device preset builds, and bad layout files are one line."""
import warnings

import numpy as np
import pytest

from raspv_spv.config import spv_config
from raspv_spv.device import DeviceError, load_device, preset_names
from raspv_bringup.testing import dev_requirement
from raspv_spv.implant_layout import (LayoutError, LayoutSpec, PlacedImplant, layout_names, load_layout,
                                      neuralink_layout)
from raspv_spv.simulator import check_config

P2P_CLASSES = {"argus_i": ("retina", "ArgusI"), "argus_ii": ("retina", "ArgusII"), "alpha_ims": ("retina", "AlphaIMS"),
               "alpha_ams": ("retina", "AlphaAMS"), "prima": ("retina", "PRIMA"), "prima75": ("retina", "PRIMA75"),
               "prima55": ("retina", "PRIMA55"), "prima40": ("retina", "PRIMA40"),
               "bva24": ("retina", "Suprachoroidal24"), "bva44": ("retina", "Suprachoroidal44"),
               "orion": ("cortex", "Orion"), "icvp": ("cortex", "ICVP")}


def test_every_shipped_layout_is_a_real_device_with_its_published_geometry():
    assert set(P2P_CLASSES) | {"neuralink"} == set(layout_names())
    counts = {n: load_layout(n).count for n in layout_names()}
    assert counts["argus_ii"] == 60 and counts["alpha_ims"] == 1500 and counts["alpha_ams"] == 1600
    assert counts["prima"] == 378 and counts["orion"] == 60 and counts["icvp"] == 16 and counts["bva44"] == 44
    a = load_layout("argus_ii")
    pitch = np.sort(np.unique(np.round(np.diff(np.sort(np.unique(a.xy_um[:, 0]))))))
    assert pitch.tolist() == [575.0] and a.target == "retina" and a.placement == "epiretinal"
    assert load_layout("orion").target == "cortex"


@pytest.mark.parametrize("name", sorted(P2P_CLASSES))
def test_shipped_layouts_equal_pulse2percept(name):
    implants = dev_requirement("pulse2percept.implants")
    kind, cls = P2P_CLASSES[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        implant = getattr(getattr(implants, kind), cls)()
    theirs = {n: (e.x, e.y) for n, e in zip(implant.electrode_names, implant.electrode_objects)
              if e.activated and not (cls.startswith("Suprachoroidal") and n in ("R1", "R2"))}
    ours = load_layout(name)
    assert set(ours.names) == set(theirs)
    for n, xy in zip(ours.names, ours.xy_um):
        assert np.allclose(xy, theirs[n], atol=1e-3), n


def test_placement_is_pulse2percepts_rotation_then_translation():
    retina = dev_requirement("pulse2percept.implants.retina")
    from pulse2percept.models.retina import ScoreboardModel

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = ScoreboardModel(retina.ArgusII(), implant_position=(-1896, -542), implant_rotation=-44, xrange=(-5, 5),
                                yrange=(-5, 5), step=1, verbose=False, n_threads=1).build()
    x, y, _ = model.spatial._electrode_coords(model.implant.electrode_array, None,
                                              electrodes=model.implant.electrode_names)
    ours = load_layout("argus_ii").placed(-1896, -542, -44)
    order = [list(load_layout("argus_ii").names).index(n) for n in model.implant.electrode_names]
    assert np.allclose(ours[order], np.stack([x, y], axis=1), atol=0.01)


def test_neuralink_threads_are_where_pulse2percepts_factory_puts_them():
    cortex = dev_requirement("pulse2percept.implants.cortex")
    from pulse2percept.topography.cortex import Polimeni2006Map

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        implant = cortex.Neuralink.from_visual_field_map(cortex.LinearEdgeThread, Polimeni2006Map())
    theirs = np.unique(np.round([[e.x, e.y] for e in implant.electrode_objects], 1), axis=0)
    ours = neuralink_layout()
    assert len(theirs) == ours.count == 49 and len(implant.electrode_objects) == 49 * 32
    assert np.allclose(np.unique(np.round(ours.xy_um, 1), axis=0), theirs, atol=0.2)


def test_phosphenes_appear_where_the_electrodes_map_and_off_map_electrodes_are_left_out():
    placed = PlacedImplant.build(LayoutSpec("argus_ii"))
    # centred array, right eye: electrode A1 (top left on the retina, x -2587, y -1437 µm) is
    # in the upper-left visual field
    a1 = placed.centres_deg[placed.names.index("A1")]
    assert a1[0] < -8 and a1[1] > 4
    orion = PlacedImplant.build(LayoutSpec("orion", 20000, -5000))
    assert orion.left_out == ("96",) and len(orion.names) == 59
    assert (orion.centres_deg[:, 0] < 0).all()                          # right hemisphere: left field
    with pytest.raises(LayoutError, match="no electrode of icvp placed at"):
        PlacedImplant.build(LayoutSpec("icvp", 0.0, -200000.0))


@pytest.mark.parametrize("text, error", [
    ("name: x\ntarget: retina\n", "missing key\\(s\\) electrodes"),
    ("name: x\ntarget: lens\nelectrodes: [[a, 0, 0, 1]]\n", "target must be one of retina, cortex"),
    ("name: x\ntarget: retina\nelectrodes: [[a, 0, zero, 1]]\n", "non-numeric position"),
    ("name: x\ntarget: retina\nelectrodes: [[a, 0, 0, 1], [a, 1, 1, 1]]\n", "names must be unique"),
    ("name: x\ntarget: retina\nelectrodes: [[a, 0, 0]]\n", "must be \\[name, x_um, y_um, radius_um\\]"),
    ("[unclosed\n", "cannot read layout YAML"),
])
def test_bad_layout_files_are_one_clear_line(tmp_path, text, error):
    path = tmp_path / "mine.yaml"
    path.write_text(text)
    with pytest.raises(LayoutError, match=error) as info:
        load_layout(path)
    assert "\n" not in str(info.value)


def test_unknown_layouts_and_sprite_models_in_devices_are_refused(tmp_path):
    with pytest.raises(LayoutError, match="unknown implant layout 'argus_iv'; layouts: alpha_ams"):
        load_layout("argus_iv")
    bad = tmp_path / "dev.yaml"
    bad.write_text("name: d\nfov_deg: 20\nnum_levels: 8\nlayout: argus_ii\nsprite_model: axion\n")
    with pytest.raises(DeviceError, match="sprite_model must be one of gaussian, scoreboard"):
        load_device(bad)
    bad.write_text("name: d\nfov_deg: 20\nnum_levels: 8\nlayout: argus_iv\n")
    with pytest.raises(DeviceError, match="unknown implant layout 'argus_iv'"):
        load_device(bad)
    with pytest.raises(ValueError, match="needs a retinal layout; orion is cortical"):
        check_config(spv_config("orion", sprite_model="axon_map"))
    with pytest.raises(ValueError, match="position noise applies to the gaussian sprite model only"):
        check_config(spv_config("argus_ii_axon", noise_px=2.0))


def test_every_device_preset_builds_its_map():
    for name in preset_names():
        m = check_config(spv_config(name, width=200))
        device = load_device(name)
        if device.layout:
            assert m.implant is not None and m.count + len(m.implant.left_out) == load_layout(device.layout).count
        assert np.isfinite(m.centres).all() and np.isfinite(m.centres_deg).all()
