"""Sprites and the sparse renderer (paper Appendix A-A and A-D)."""
import numpy as np
import pytest

from raspv_spv.phosphene_map import MapSpec, PhospheneMap
from raspv_spv.renderer import Renderer
from raspv_spv.sprites import BitmapSprite, GaussianSprite


def test_default_sprite_matches_the_authors_29px_gaussian():
    s = GaussianSprite(19.80)
    assert s.size_px == 29 and s.sigma_px == pytest.approx(4.61, abs=0.01)
    assert s.weights(np.array(0.0), np.array(0.0)) == 1.0
    assert s.weights(np.array(14.0), np.array(0.0)) == pytest.approx(0.01)
    assert s.weights(np.array(14.0), np.array(1.0)) == 0.0          # cut to the disc


def one_phosphene(brightness=1.0, centre=(50.5, 40.5), sprite=None, fmt="mono8"):
    r = Renderer(np.array([centre]), np.array([True]), 100, 80, sprite or GaussianSprite(12.0), fmt)
    return r.render(np.array([brightness], np.float32))


def test_levels_scale_the_reference_sprite():
    full = one_phosphene(1.0).astype(int)
    assert full[40, 50] == 255 and full.sum() > 255
    for level in range(8):                                          # S_i = i/(N_L-1) S_r
        img = one_phosphene(level / 7).astype(int)
        assert np.abs(img - np.rint(full * level / 7)).max() <= 1
    assert one_phosphene(0.0).max() == 0


def test_overlapping_sprites_sum_and_saturate():
    sprite = GaussianSprite(12.0)
    centres = np.array([[41.5, 40.5], [43.5, 40.5]])
    r = Renderer(centres, np.array([True, True]), 100, 80, sprite)
    both = r.render(np.array([0.6, 0.6], np.float32)).astype(int)
    a = Renderer(centres[:1], np.array([True]), 100, 80, sprite).render(np.array([0.6], np.float32)).astype(int)
    b = Renderer(centres[1:], np.array([True]), 100, 80, sprite).render(np.array([0.6], np.float32)).astype(int)
    assert np.abs(both - np.minimum(a + b, 255)).max() <= 1
    assert both[40, 42] == 255 > a[40, 42]                         # 0.6 + 0.6 > 1 saturates


def test_subpixel_centres_and_image_borders():
    img = one_phosphene(1.0, centre=(50.0, 40.0)).astype(int)     # centre on a pixel corner
    assert img[39, 49] == img[39, 50] == img[40, 49] == img[40, 50] < 255
    edge = one_phosphene(1.0, centre=(0.5, 0.5))                   # cut by the border, no wrap-around
    assert edge[0, 0] == 255 and edge[:, -5:].max() == 0 and edge[-5:, :].max() == 0


def test_dropped_phosphenes_are_never_drawn_and_noise_moves_sprites():
    clean = PhospheneMap.build(MapSpec(200, 200, 60, "rectangular", fov_deg=20, phosphene_fov_deg=1.0))
    bad = PhospheneMap.build(MapSpec(200, 200, 60, "rectangular", fov_deg=20, phosphene_fov_deg=1.0,
                                     dropout=0.5, noise_px=3.0, seed=1))
    sprite = GaussianSprite(clean.diameter_px)
    ones = np.ones(clean.count, np.float32)
    a = Renderer(clean.display_centres, ~clean.dropped, 200, 200, sprite).render(ones)
    b = Renderer(bad.display_centres, ~bad.dropped, 200, 200, sprite).render(ones)
    assert b.sum() == pytest.approx(a.sum() * 0.5, rel=0.1)
    for i in np.flatnonzero(~bad.dropped)[:5]:
        x, y = bad.display_centres[i]
        assert b[int(y), int(x)] > 200
    for i in np.flatnonzero(bad.dropped):
        x, y = bad.centres[i]
        assert b[int(y), int(x)] < 60


def test_green_output_has_only_the_green_channel():
    img = one_phosphene(1.0, fmt="green")
    assert img.shape == (80, 100, 3) and img.dtype == np.uint8
    assert img[..., 0].max() == 0 and img[..., 2].max() == 0
    assert np.array_equal(img[..., 1], one_phosphene(1.0))


def test_arbitrary_sprite_shapes_render_through_the_same_matrix():
    yy, xx = np.mgrid[-1:1:33j, -1:1:33j]
    ring = np.clip(1 - np.abs(np.hypot(xx, yy) - 0.5) * 6, 0, 1)   # a doughnut phosphene
    img = one_phosphene(1.0, sprite=BitmapSprite(ring, diameter_px=20.0)).astype(int)
    assert img[40, 50] < 40 and img[40, 57] > 200 and img[33, 50] > 200
    with pytest.raises(ValueError, match="square 2-D image"):
        BitmapSprite(np.ones((3, 4)))


def test_default_renderer_is_small():
    m = PhospheneMap.build(MapSpec(800, 800, 1000, "hexagonal"))
    r = Renderer(m.display_centres, ~m.dropped, 800, 800, GaussianSprite(m.diameter_px))
    assert r.nbytes < 50e6
    with pytest.raises(ValueError, match=f"expected brightness for {m.count} phosphenes"):
        r.render(np.ones(3))
