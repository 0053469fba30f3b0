"""Phosphene maps: the paper's equations 1-6 and the display-only defects (Appendix A)."""
import math

import numpy as np
import pytest

from raspv_spv.phosphene_map import (MapError, MapSpec, PhospheneMap, lattice_centres, lattice_spacing,
                                     phosphene_diameter_px, phosphene_focal_px)


def test_paper_worked_example_default_preset_800x800_hexagonal():
    m = PhospheneMap.build(MapSpec(800, 800, 1000, "hexagonal", "rectangular", 20.0, 0.5))
    assert (m.spacing_x, m.spacing_y) == (27, 23)
    assert m.focal_px == pytest.approx(2268.5, abs=0.05)
    assert m.diameter_px == pytest.approx(2 * 2268.51 * math.tan(math.radians(0.25)), rel=1e-4)   # eq. 6, ~19.8 px
    assert np.allclose(m.K, [[m.focal_px, 0, 400], [0, m.focal_px, 400], [0, 0, 1]])
    assert abs(m.count - 1000) <= 50                                     # "close to N" (paper A-B)


def test_rectangular_spacing_is_eq1_and_argus_ii_gives_its_10x6_array():
    assert lattice_spacing(800, 480, 60, "rectangular") == (80, 80)       # floor(sqrt(800*480/60))
    c = lattice_centres(800, 480, 80, 80, "rectangular")
    assert len(c) == 60
    assert sorted(set(c[:, 0])) == [40.0 + 80 * k for k in range(10)]    # first centre at delta/2
    assert sorted(set(c[:, 1])) == [40.0 + 80 * k for k in range(6)]


def test_hexagonal_rows_are_shifted_by_half_a_spacing():
    dx, dy = lattice_spacing(800, 800, 1000, "hexagonal")
    c = lattice_centres(800, 800, dx, dy, "hexagonal")
    rows = sorted(set(c[:, 1]))
    assert np.allclose(np.diff(rows), dy) and rows[0] == dy / 2
    first_x = [c[c[:, 1] == y, 0].min() for y in rows[:2]]
    assert first_x == [dx / 2, dx]
    # rows run until the centre leaves the image
    assert 800 - dx <= c[:, 0].max() < 800 and 800 - dy <= c[:, 1].max() < 800
    assert len(c) == 18 * 30 + 17 * 29


def test_circular_field_uses_eq3_area_and_keeps_centres_in_the_inscribed_circle():
    dx, dy = lattice_spacing(800, 800, 1000, "hexagonal", "circular")
    assert dx == math.floor(math.sqrt(800 * 800 * 2 / math.sqrt(3) * math.pi / 4 / 1000))
    assert dy == math.floor(math.sqrt(3) / 2 * dx)
    m = PhospheneMap.build(MapSpec(800, 800, 1000, "hexagonal", "circular"))
    r = np.hypot(m.centres[:, 0] - 400, m.centres[:, 1] - 400)
    assert r.max() <= 400 and abs(m.count - 1000) < 80
    # Alpha-IMS in a circle: about N phosphenes too
    alpha = PhospheneMap.build(MapSpec(800, 800, 1500, "rectangular", "circular", 11.0, 0.3))
    assert abs(alpha.count - 1500) < 100


def test_focal_length_and_diameter_follow_eq5_and_eq6():
    assert phosphene_focal_px(800, 90.0) == pytest.approx(400.0)
    assert phosphene_diameter_px(400.0, 90.0) == pytest.approx(800.0)


def test_defects_are_reproducible_and_only_change_what_is_displayed():
    base = PhospheneMap.build(MapSpec(800, 800, 1000, "hexagonal"))
    a = PhospheneMap.build(MapSpec(800, 800, 1000, "hexagonal", dropout=0.2, noise_px=5.0, seed=7))
    b = PhospheneMap.build(MapSpec(800, 800, 1000, "hexagonal", dropout=0.2, noise_px=5.0, seed=7))
    c = PhospheneMap.build(MapSpec(800, 800, 1000, "hexagonal", dropout=0.2, noise_px=5.0, seed=8))
    assert np.array_equal(a.centres, base.centres)                       # sampling positions untouched
    assert np.array_equal(a.dropped, b.dropped) and np.array_equal(a.display_centres, b.display_centres)
    assert not np.array_equal(a.dropped, c.dropped)
    assert a.dropped.sum() == round(0.2 * a.count)
    offsets = a.display_centres - a.centres
    assert abs(offsets.std() - 5.0) < 0.4 and abs(offsets.mean()) < 0.4
    assert np.array_equal(base.display_centres, base.centres) and not base.dropped.any()


def test_raising_dropout_keeps_the_phosphenes_already_dropped():
    low = PhospheneMap.build(MapSpec(dropout=0.1, seed=3)).dropped
    high = PhospheneMap.build(MapSpec(dropout=0.4, seed=3)).dropped
    assert np.all(high[low]) and high.sum() > low.sum()


def test_impossible_maps_are_refused_with_a_reason():
    with pytest.raises(MapError, match="do not fit a 16x16 image"):
        lattice_spacing(16, 16, 1000, "rectangular")
    with pytest.raises(MapError, match="grid must be one of rectangular, hexagonal"):
        MapSpec(grid="triangular")
    with pytest.raises(MapError, match="dropout must be in"):
        MapSpec(dropout=1.5)
