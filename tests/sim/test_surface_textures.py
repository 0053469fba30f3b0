"""Surface textures (raspv_sim.surface_textures): seamless, tinted by the part's colour, tiled per
metre by the box's texture coordinates, and drawn by the renderer (a textured wall has detail a
flat one lacks; labels unchanged)."""
from __future__ import annotations

import numpy as np
import pytest

from raspv_sim.surface_textures import box_obj_text, periodic_noise, texture_image


def test_noise_is_seamless_and_seeded():
    n = periodic_noise((48, 64), seed=3)
    assert n.min() == 0.0 and n.max() == 1.0
    # across the seam (last column → first) the step is like any neighbouring step
    inner = np.abs(np.diff(n, axis=1)).mean()
    assert np.abs(n[:, -1] - n[:, 0]).mean() < 2 * inner
    assert np.abs(n[-1] - n[0]).mean() < 2 * np.abs(np.diff(n, axis=0)).mean()
    assert np.array_equal(n, periodic_noise((48, 64), seed=3)) and not np.array_equal(n, periodic_noise((48, 64), 4))


def test_texture_keeps_the_colour_and_walls_get_notices():
    wall = texture_image("wall", (0.9, 0.5, 0.2), seed=1, size_m=(6.0, 2.7))
    assert wall.shape == (346, 768, 3)                         # 128 px per metre, no repeats along the wall
    plaster = wall[:60].reshape(-1, 3) / 255.0                 # top 0.5 m: above the notices
    assert plaster.mean(axis=0) == pytest.approx([0.9, 0.5, 0.2], abs=0.06)
    dark = (wall.max(axis=2) < 40)                             # the notices' frames
    rows = np.nonzero(dark.any(axis=1))[0]
    assert dark.sum() > 500 and 346 - rows.max() > 0.6 * 128 and 346 - rows.min() < 2.0 * 128    # at eye level
    floor = texture_image("floor", (0.7, 0.7, 0.7)).astype(float)
    assert floor.std() > 10                                    # grout lines and mottling


def test_box_texture_coordinates_are_metric():
    text = box_obj_text((6.0, 0.12, 2.7), "m", "m.mtl", tile=(2.0, 2.0))
    uv = np.array([[float(v) for v in line.split()[1:]] for line in text.splitlines() if line.startswith("vt ")])
    assert uv[:, 0].max() == pytest.approx(3.0) and uv[:, 1].max() == pytest.approx(2.7 / 2.0) and uv.min() == 0.0
    assert sum(line.startswith("f ") for line in text.splitlines()) == 12


def test_a_textured_world_renders_detail_where_the_flat_one_has_none(private_cache):
    from raspv_sim.simulator import SimConfig, Simulation

    views = {}
    for textures in (False, True):
        with Simulation("apartment", SimConfig(width=320, height=240, textures=textures)) as sim:
            frame = sim.render_from(1.0, 3.8, 0.3)
            views[textures] = frame
    import cv2

    patch = (slice(60, 180), slice(20, 140))                      # the near wall on the left, one plane
    depth = views[False].depth[patch]
    assert np.isfinite(depth).all() and len(np.unique(views[False].labels[patch])) == 1
    detail = {k: float(cv2.Laplacian(v.rgb.mean(axis=2), cv2.CV_64F)[patch].std()) for k, v in views.items()}
    assert detail[True] > 3.0 * detail[False] + 0.5, detail
    assert np.array_equal(views[False].labels, views[True].labels)
