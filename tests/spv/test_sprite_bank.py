"""Sprite banks: tissue sprites precomputed on a coarse grid, rendered with a bilinear resize,
one sprite per level for the levelled models, normalised to the all-on array, cached on disk."""
import numpy as np
import pytest

from raspv_spv.config import spv_config
from raspv_spv.simulator import PhospheneSimulator, check_config
from raspv_spv.sprite_models import (SpriteSpec, build_sprite_bank, cache_dir, coarse_grid_deg, model_sprites,
                                     render_scale)


def test_paper_sprites_stay_exact_and_tissue_sprites_are_sampled_coarser():
    assert render_scale(check_config(spv_config("default")), SpriteSpec("gaussian")) == 1
    axon = spv_config("argus_ii_axon", width=800)
    m = check_config(axon)
    s = render_scale(m, axon.sprite_spec())
    assert 4 <= s <= 8                          # rho 300 µm ~ 1.1 deg ~ 29 px: at least 4 coarse px per sigma
    assert render_scale(check_config(spv_config("argus_ii_axon", width=100)), axon.sprite_spec()) == 1


def coarse_and_exact(device, width, phosphenes):
    """(rendered image, the sprite evaluated at every pixel) for single phosphenes at full level."""
    config = spv_config(device, width=width, temporal=False)
    sim = PhospheneSimulator(config)
    m, bank = sim.map, sim.renderer.bank
    assert bank.scale > 1
    full_x, full_y = coarse_grid_deg(m, 1)
    exact = model_sprites(m, config.sprite_spec(), full_x, full_y)
    for i in phosphenes:
        levels = np.zeros(m.count, np.uint8)
        levels[i] = sim.num_levels - 1
        image = sim.render(sim.brightness(levels)).astype(float)
        yield image, exact[:, i].toarray().reshape(image.shape) * 255.0 * bank.gain


def test_bilinear_upsampling_stays_within_one_percent_of_the_peak():
    """A Gaussian sampled every sigma/4 and interpolated bilinearly differs from the Gaussian
    evaluated at every pixel by at most h^2/8 max|f''| = 1/128 of its peak."""
    for image, exact in coarse_and_exact("bva44", 400, (0, 20, 43)):
        assert np.abs(image - exact).max() <= 0.01 * exact.max() + 1.0      # + rounding to 8 bits


@pytest.mark.slow
def test_coarse_axon_map_sprites_lose_only_the_stripes_of_the_discrete_bundles():
    """Evaluated at every pixel, an axon-map phosphene has stripes a few pixels apart: each
    pixel takes its nearest of 1000 discrete bundles (pulse2percept's discretisation, not
    anatomy). The coarse grid smooths them; everything else is kept."""
    for image, exact in coarse_and_exact("argus_ii_axon", 400, (0, 27, 59)):
        lit = exact > 1
        assert np.corrcoef(image[lit], exact[lit])[0, 1] >= 0.98
        assert np.abs(image - exact)[lit].mean() <= 0.03 * exact.max()
        assert image.max() == pytest.approx(exact.max(), rel=0.1)


def test_the_whole_array_at_the_top_level_reaches_white_without_clipping():
    sim = PhospheneSimulator(spv_config("argus_ii_axon", width=300, temporal=False))
    assert 0.2 < sim.renderer.bank.gain < 1.0
    full = sim.render(sim.brightness(np.full(sim.count, sim.num_levels - 1, np.uint8)))
    assert 250 <= full.max() <= 255
    one = np.zeros(sim.count, np.uint8)
    one[30] = sim.num_levels - 1
    lone = int(sim.render(sim.brightness(one)).max())                 # a sprite peaks at <= 1 (its
    assert 0.7 * 255 * sim.renderer.bank.gain <= lone <= 255 * sim.renderer.bank.gain + 1   # pixels miss the axon)


@pytest.mark.slow
def test_levelled_models_draw_each_level_with_its_own_sprite_and_fade_with_that_shape():
    sim = PhospheneSimulator(spv_config("argus_ii_biphasic", width=800, temporal=False))
    assert sim.renderer.levels == sim.num_levels - 1
    sizes, peaks = [], []
    for level in (1, 4, 7):
        levels = np.zeros(sim.count, np.uint8)
        levels[30] = level
        img = sim.render(sim.brightness(levels))
        sizes.append(int((img > 10).sum()))
        peaks.append(int(img.max()))
    assert sizes[0] < sizes[1] < sizes[2] and peaks[0] < peaks[1] < peaks[2]      # stronger pulse: bigger, brighter
    # with the temporal model a phosphene switched off fades with the sprite of its last pulse
    sim = PhospheneSimulator(spv_config("argus_ii_biphasic", width=800, temporal=True))
    on = np.zeros(sim.count, np.uint8)
    on[30] = 3
    for _ in range(10):
        held = sim.render(sim.brightness(on)).astype(float)
    fading = sim.render(sim.brightness(np.zeros(sim.count, np.uint8))).astype(float)
    bright = held > 0.3 * held.max()
    assert held.max() > 20
    ratio = fading[bright] / held[bright]
    assert 0.2 < ratio.mean() < 1.0 and ratio.std() < 0.05                 # the same shape, dimmer


def test_dropped_phosphenes_are_never_drawn_with_tissue_sprites():
    sim = PhospheneSimulator(spv_config("prima", width=200, dropout=0.5, temporal=False))
    dropped = np.flatnonzero(sim.map.dropped)
    assert len(dropped) == round(0.5 * sim.count)
    levels = np.zeros(sim.count, np.uint8)
    levels[dropped] = 7
    assert sim.render(sim.brightness(levels)).max() == 0


def test_banks_are_cached_on_disk_and_a_corrupt_cache_file_is_rebuilt(lut_cache):
    config = spv_config("argus_ii_axon", width=160, seed=5)
    m = check_config(config)
    for path in cache_dir().glob("axon_map-*.npz"):
        path.unlink()
    first = build_sprite_bank(m, config.sprite_spec())
    files = list(cache_dir().glob("axon_map-*.npz"))
    assert not first.cached and len(files) == 1
    second = build_sprite_bank(m, config.sprite_spec())
    assert second.cached and second.gain == first.gain
    assert (second.matrix != first.matrix).nnz == 0
    files[0].write_bytes(b"not a numpy file")
    third = build_sprite_bank(m, config.sprite_spec())
    assert not third.cached and (third.matrix != first.matrix).nnz == 0
    # another rho is another file
    other = build_sprite_bank(m, SpriteSpec("axon_map", 200, 1000))
    assert not other.cached and len(list(cache_dir().glob("axon_map-*.npz"))) == 2


def test_a_lower_priority_subprocess_builds_the_slow_parts_into_the_caches(tmp_path, monkeypatch):
    from raspv_spv.prebuild import PrebuildError, missing_from_cache, prebuild_in_subprocess

    config = spv_config("bva44", width=120, pulse_phase_ms=0.3)        # a temporal table no other test builds
    m = check_config(config)
    assert missing_from_cache(config, m) == ["sprites", "temporal table"]
    # started from a directory with another raspv_spv in it, the subprocess still runs this one
    (tmp_path / "raspv_spv").mkdir()
    (tmp_path / "raspv_spv" / "__init__.py").write_text("raise ImportError('the wrong checkout')\n")
    monkeypatch.chdir(tmp_path)
    prebuild_in_subprocess(config)
    assert missing_from_cache(config, m) == []
    sim = PhospheneSimulator(config, phosphene_map=m)
    assert sim.renderer.bank.cached
    # a failure in the subprocess comes back as one line
    layout = tmp_path / "mine.yaml"
    layout.write_text("name: mine\ntarget: retina\nelectrodes: [[a, 0, 0, 100], [b, 500, 0, 100]]\n")
    device = tmp_path / "dev.yaml"
    device.write_text(f"name: dev\nfov_deg: 20\nnum_levels: 8\nlayout: {layout}\nsprite_model: scoreboard\n")
    config = spv_config(str(device), width=100)
    layout.unlink()
    with pytest.raises(PrebuildError, match=r"LayoutError: layout file .*mine.yaml does not exist"):
        prebuild_in_subprocess(config)
