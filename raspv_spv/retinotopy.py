"""Where things are: phosphene image ↔ visual field ↔ retina or visual cortex (no ROS).

Coordinates and units (the conventions of pulse2percept 0.11, so numbers transfer):

- **Visual field**: degrees of visual angle (dva), x right, y up, origin at fixation; a point
  is (eccentricity, polar angle) written as Cartesian coordinates (azimuthal equidistant).
- **Phosphene image**: px, continuous, origin at the top-left corner (as
  :mod:`raspv_spv.phosphene_map`); a pixel is the ray K_P⁻¹·(u, v, 1), whose angle to the
  optical axis is its eccentricity — :func:`image_to_visual_field` / :func:`visual_field_to_image`.
- **Retina**: µm on the retinal surface, origin at the fovea, x towards the right of the
  visual field, y towards the bottom of it (the image on the retina is upside down), from
  Watson 2014 (J. Vision 14(7):15), eqs. A5 (dva → mm) and A6 (mm → dva).
- **Visual cortex (V1)**: µm, the wedge-dipole map (Polimeni et al. 2006, NeuroImage
  30:1412; Schwartz's dipole with a wedge): w = k·log(b(z + a) / (a(z + b))), z = r·e^{iαθ}.
  As in pulse2percept's ``Polimeni2006Map`` the right hemisphere (left visual field) has x ≥ 0
  and the left hemisphere is mirrored to x ≤ ``left_offset_um`` (−20 mm); upper visual field
  is y < 0. dynaphos (van der Grinten et al. 2024) uses the same map on one hemisphere in mm,
  so its cortex coordinates are the right hemisphere's here divided by 1000.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# Watson 2014 eq. A5 (dva -> mm) and A6 (mm -> dva) polynomial coefficients, lowest order first.
_A5 = (0.268, 3.427e-4, -8.3309e-6)
_A6 = (3.556, 0.05993, -0.007358, 3.027e-4)


# -- phosphene image <-> visual field -----------------------------------------------------------
def image_to_visual_field(u, v, focal_px: float, cx: float, cy: float) -> tuple[np.ndarray, np.ndarray]:
    """Visual-field position (x, y) dva of phosphene-image points (u, v) px (continuous
    coordinates; K_P with focal ``focal_px`` and principal point (cx, cy))."""
    x = (np.asarray(u, dtype=np.float64) - cx) / focal_px
    y = -(np.asarray(v, dtype=np.float64) - cy) / focal_px
    r = np.hypot(x, y)
    ecc = np.degrees(np.arctan(r))
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(r > 0, ecc / np.where(r > 0, r, 1.0), math.degrees(1.0))
    return x * scale, y * scale


def visual_field_to_image(x_deg, y_deg, focal_px: float, cx: float, cy: float) -> tuple[np.ndarray, np.ndarray]:
    """Phosphene-image position (u, v) px of visual-field points (x, y) dva; NaN at or beyond
    90° of eccentricity (behind the image plane)."""
    x = np.asarray(x_deg, dtype=np.float64)
    y = np.asarray(y_deg, dtype=np.float64)
    ecc = np.hypot(x, y)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(ecc < 90.0, np.tan(np.radians(np.minimum(ecc, 89.999))), np.nan)
        scale = np.where(ecc > 0, r / np.where(ecc > 0, ecc, 1.0), math.radians(1.0))
    return cx + focal_px * x * scale, cy - focal_px * y * scale


# -- retina (Watson 2014) -------------------------------------------------------------------------
def _polar(x, y):
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    return np.arctan2(y, x), np.hypot(x, y)


def watson_dva_to_ret(x_deg, y_deg) -> tuple[np.ndarray, np.ndarray]:
    """Retinal position (µm) of visual-field points (dva): Watson 2014 eq. A5, y flipped."""
    theta, r = _polar(x_deg, y_deg)
    mm = (_A5[0] + (_A5[1] + _A5[2] * r) * r) * r
    return 1000.0 * mm * np.cos(theta), -1000.0 * mm * np.sin(theta)


def watson_ret_to_dva(x_um, y_um) -> tuple[np.ndarray, np.ndarray]:
    """Visual-field position (dva) of retinal points (µm) by Watson 2014 eq. A6 (its own fit of
    the reverse direction; a few % from inverting A5)."""
    theta, r_um = _polar(x_um, y_um)
    mm = r_um / 1000.0
    deg = (_A6[0] + (_A6[1] + (_A6[2] + _A6[3] * mm) * mm) * mm) * mm
    return deg * np.cos(theta), -deg * np.sin(theta)


def watson_ret_to_dva_exact(x_um, y_um) -> tuple[np.ndarray, np.ndarray]:
    """Visual-field position (dva) of retinal points (µm) inverting eq. A5 (Newton from the A6
    value): the exact inverse of :func:`watson_dva_to_ret`, so a phosphene drawn around an
    electrode has its brightest point here."""
    theta, r_um = _polar(x_um, y_um)
    mm = r_um / 1000.0
    deg = (_A6[0] + (_A6[1] + (_A6[2] + _A6[3] * mm) * mm) * mm) * mm
    for _ in range(4):
        f = (_A5[0] + (_A5[1] + _A5[2] * deg) * deg) * deg - mm
        df = _A5[0] + (2.0 * _A5[1] + 3.0 * _A5[2] * deg) * deg
        deg = deg - f / df
    return deg * np.cos(theta), -deg * np.sin(theta)


def watson_um_per_deg(ecc_deg) -> np.ndarray:
    """Local scale of the retina (µm per dva) at eccentricity ``ecc_deg`` (derivative of A5)."""
    e = np.asarray(ecc_deg, dtype=np.float64)
    return 1000.0 * (_A5[0] + (2.0 * _A5[1] + 3.0 * _A5[2] * e) * e)


# -- visual cortex (wedge-dipole) -----------------------------------------------------------------
@dataclass(frozen=True)
class WedgeDipoleMap:
    """V1 map w = k·log(b(z + a) / (a(z + b))) with z = r·e^{iα·θ} (k mm, a and b dva, α the
    wedge: the fraction of the hemifield's polar angle V1 spans), both hemispheres as in
    pulse2percept's ``Polimeni2006Map``."""

    k: float = 15.0
    a: float = 0.69
    b: float = 80.0
    alpha: float = 1.0
    left_offset_um: float = -20000.0

    def __post_init__(self) -> None:
        if not (self.k > 0 and 0 < self.a < self.b and 0 < self.alpha <= 1):
            raise ValueError(f"wedge-dipole map needs k > 0, 0 < a < b and 0 < alpha <= 1, got {self}")

    def dva_to_v1(self, x_deg, y_deg) -> tuple[np.ndarray, np.ndarray]:
        """V1 position (µm) of visual-field points (dva); NaN on the vertical meridian itself
        and beyond 90° (points exactly at x = 0 belong to neither hemisphere)."""
        x = np.asarray(x_deg, dtype=np.float64)
        y = np.asarray(y_deg, dtype=np.float64)
        left_field = x < 0
        theta = np.arctan2(y, np.abs(x))                 # the right half-field's angle, in (-pi/2, pi/2)
        r = np.hypot(x, y)
        z = r * np.exp(-1j * self.alpha * theta)          # upper field -> negative V1 y
        with np.errstate(divide="ignore", invalid="ignore"):
            w = self.k * np.log(self.b * (z + self.a) / (self.a * (z + self.b)))
        xv, yv = 1000.0 * w.real, 1000.0 * w.imag
        xv = np.where(left_field, xv, -xv + self.left_offset_um)
        bad = (x == 0) | (r > 90) | ~np.isfinite(xv)
        return np.where(bad, np.nan, xv), np.where(bad, np.nan, yv)

    def v1_to_dva(self, x_um, y_um) -> tuple[np.ndarray, np.ndarray]:
        """Visual-field position (dva) of V1 points (µm); NaN outside the map."""
        x = np.asarray(x_um, dtype=np.float64)
        y = np.asarray(y_um, dtype=np.float64)
        left_hemisphere = x < self.left_offset_um / 2.0   # -> right visual field
        xr = np.where(left_hemisphere, -x + self.left_offset_um, x)
        w = (xr + 1j * y) / 1000.0
        e = np.exp(w / self.k)
        z = self.a * self.b * (e - 1.0) / (self.b - self.a * e)
        r = np.abs(z)
        theta = -np.angle(z) / self.alpha                 # the right half-field's angle
        xd = r * np.cos(theta)
        yd = r * np.sin(theta)
        xd = np.where(left_hemisphere, xd, -xd)
        bad = (np.abs(theta) >= np.pi / 2) & (r > 0) | (r > 90) | (np.abs(w.imag) >= self.k * np.pi)
        return np.where(bad, np.nan, xd), np.where(bad, np.nan, yd)

    def hemisphere(self, x_um) -> np.ndarray:
        """True where a V1 x coordinate (µm) is in the left hemisphere (right visual field)."""
        return np.asarray(x_um, dtype=np.float64) < self.left_offset_um / 2.0

    def magnification(self, ecc_deg) -> np.ndarray:
        """Cortical magnification M (mm of V1 per dva) at eccentricity ``ecc_deg`` along the
        horizontal meridian: k·(1/(r + a) − 1/(r + b))."""
        r = np.asarray(ecc_deg, dtype=np.float64)
        return self.k * (1.0 / (r + self.a) - 1.0 / (r + self.b))


#: pulse2percept 0.11 ``Polimeni2006Map`` defaults (Polimeni et al. 2006, §4.6 averages).
POLIMENI2006 = WedgeDipoleMap(k=15.0, a=0.69, b=80.0, alpha=1.0)
#: dynaphos 0.1.3's published ``cortex_model`` (van der Grinten et al. 2024, eLife): the
#: dipole model (its configuration also lists a wedge α = 0.95, used only by "wedge-dipole").
DYNAPHOS = WedgeDipoleMap(k=17.3, a=0.75, b=120.0, alpha=1.0)
CORTICAL_MAPS = {"polimeni2006": POLIMENI2006, "dynaphos": DYNAPHOS}
