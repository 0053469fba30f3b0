"""Visual field <-> phosphene image <-> retina (Watson 2014) <-> V1 (wedge-dipole), against
pulse2percept 0.11's Watson2014Map / Polimeni2006Map and dynaphos 0.1.3's cortex model."""
import math

import numpy as np
import pytest

from raspv_bringup.testing import dev_requirement
from raspv_spv.retinotopy import (DYNAPHOS, POLIMENI2006, WedgeDipoleMap, image_to_visual_field, visual_field_to_image,
                                  watson_dva_to_ret, watson_ret_to_dva, watson_ret_to_dva_exact, watson_um_per_deg)

RNG = np.random.default_rng(0)
X, Y = RNG.uniform(-40, 40, 3000), RNG.uniform(-40, 40, 3000)


def test_image_and_visual_field_round_trip_and_eccentricity_is_the_ray_angle():
    f, cx, cy = 1000.0, 400.0, 300.0
    u, v = RNG.uniform(0, 800, 500), RNG.uniform(0, 600, 500)
    x, y = image_to_visual_field(u, v, f, cx, cy)
    ray = np.stack([(u - cx) / f, (v - cy) / f, np.ones_like(u)], axis=1)
    angle = np.degrees(np.arccos(ray[:, 2] / np.linalg.norm(ray, axis=1)))
    assert np.allclose(np.hypot(x, y), angle)                          # eccentricity = angle to the axis
    assert np.all(np.sign(y) == -np.sign(v - cy))                      # image rows grow downwards
    u2, v2 = visual_field_to_image(x, y, f, cx, cy)
    assert np.allclose(u2, u) and np.allclose(v2, v)
    assert image_to_visual_field(cx, cy, f, cx, cy) == (0.0, 0.0)
    assert np.isnan(visual_field_to_image(95.0, 0.0, f, cx, cy)[0])


def test_watson_2014_matches_pulse2percept_and_inverts_exactly():
    retina = dev_requirement("pulse2percept.topography.retina")
    w = retina.Watson2014Map()
    assert np.allclose(watson_dva_to_ret(X, Y), w.dva_to_ret(X, Y), atol=1e-6)           # eq. A5, µm
    assert np.allclose(watson_ret_to_dva(X * 280, Y * 280), w.ret_to_dva(X * 280, Y * 280), atol=1e-9)   # eq. A6
    xr, yr = watson_dva_to_ret(X, Y)
    assert np.allclose(watson_ret_to_dva_exact(xr, yr), (X, Y), atol=1e-9)
    # A6 is a separate fit: it differs from inverting A5 by a few %, which is why phosphenes are
    # placed with the exact inverse (the peak of the sprite drawn around the electrode)
    gap = np.hypot(*np.subtract(watson_ret_to_dva(xr, yr), (X, Y))) / np.hypot(X, Y)
    assert 0.001 < gap.max() < 0.06
    # local scale: the derivative of A5, about 268 µm per degree at the fovea
    e = np.array([0.0, 5.0, 20.0])
    h = 1e-4
    numeric = (watson_dva_to_ret(e + h, 0 * e)[0] - watson_dva_to_ret(e - h, 0 * e)[0]) / (2 * h)
    assert np.allclose(watson_um_per_deg(e), numeric, rtol=1e-6) and watson_um_per_deg(0.0) == pytest.approx(268.0)


def test_polimeni_2006_map_matches_pulse2percept_both_ways():
    cortex = dev_requirement("pulse2percept.topography.cortex")
    m = cortex.Polimeni2006Map()
    theirs = np.array(m.dva_to_v1(X.astype(np.float32), Y.astype(np.float32)), dtype=float)
    ours = np.array(POLIMENI2006.dva_to_v1(X, Y))
    assert np.isnan(ours).sum() == np.isnan(theirs).sum() == 0
    assert np.abs(ours - theirs).max() < 0.05                          # µm; theirs is float32
    assert (ours[0] >= 0).sum() == (X < 0).sum()                       # left field -> right hemisphere x >= 0
    back = np.array(POLIMENI2006.v1_to_dva(*ours))
    assert np.allclose(back, (X, Y), atol=1e-7)
    assert np.allclose(back, np.array(m.v1_to_dva(*ours), dtype=float), atol=1e-4)
    # beyond the map: pulse2percept says NaN, so do we
    far = np.array([[0.0, -60000.0], [5000.0, 50000.0]])
    assert np.isnan(POLIMENI2006.v1_to_dva(far[:, 0], far[:, 1])[0]).all()
    assert np.isnan(np.array(m.v1_to_dva(far[:, 0], far[:, 1]), dtype=float)[0]).all()


def test_dynaphos_cortex_model_is_the_right_hemisphere_in_mm():
    dev_requirement("torch")
    from dynaphos.cortex_models import (get_cortical_magnification, get_mapping_from_cortex_to_visual_field,
                                        get_mapping_from_visual_field_to_cortex)
    from dynaphos.utils import Map

    params = {"model": "dipole", "k": 17.3, "a": 0.75, "b": 120, "alpha": 0.95}
    w = RNG.uniform(0, 60, 400) + 1j * RNG.uniform(-25, 25, 400)
    z = Map(z=get_mapping_from_cortex_to_visual_field(params)(w)).flip(hor=True, vert=True)
    ours = np.array(DYNAPHOS.v1_to_dva(w.real * 1000, w.imag * 1000))
    ok = np.isfinite(ours[0])
    assert ok.mean() > 0.7                                             # the rest lies beyond 90 deg
    assert np.allclose(ours[:, ok], np.array(z.cartesian)[:, ok], atol=1e-9)
    fwd = get_mapping_from_visual_field_to_cortex(params)(-X[X < 0] - 1j * Y[X < 0])   # dynaphos flips the field
    assert np.allclose(DYNAPHOS.dva_to_v1(X[X < 0], Y[X < 0]), (fwd.real * 1000, fwd.imag * 1000), atol=1e-6)
    e = np.array([0.5, 2.0, 10.0])
    assert np.allclose(DYNAPHOS.magnification(e), get_cortical_magnification(e, params))


def test_map_parameters_are_checked():
    with pytest.raises(ValueError, match="0 < a < b"):
        WedgeDipoleMap(a=90.0, b=80.0)
    assert not math.isnan(POLIMENI2006.magnification(1.0))
