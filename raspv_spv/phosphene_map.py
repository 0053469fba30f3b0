"""Phosphene maps (paper Appendix A, eqs. 1–6), no ROS.

Phosphene image I: ``width`` × ``height`` px, continuous pixel coordinates with the origin at
the top-left corner of the top-left pixel (pixel (col j, row i) has its centre at (j+½, i+½)).

- Spacing (eqs. 1–3): rectangular δ = ⌊√(A/N)⌋; hexagonal δx = ⌊√(A·2/√3 / N)⌋,
  δy = ⌊√3/2·δx⌋, where A = w·h for the whole-image field and π·r² for the circular field
  (r = min(w, h)/2, the inscribed circle; π/4·w·h for a square image as in eq. 3).
- Centres: first at (δx/2, δy/2), side by side δx apart until the row ends (the centre leaves
  the image), rows δy apart, odd hexagonal rows shifted by δx/2; the circular field keeps the
  centres inside the inscribed circle. The count is close to, not exactly, N (paper A-B).
- K_P (eqs. 4–5): f_P = w / (2·tan(FOV/2)), c = (w/2, h/2), square pixels.
- Phosphene diameter (eq. 6): φ = 2·f_P·tan(FOV_P/2) px.
- Implant layouts (``MapSpec.layout``): instead of the lattice, one phosphene per electrode of
  a real device (:mod:`raspv_spv.implant_layout`), placed on the retina or cortex, each where
  the electrode's phosphene appears in the visual field, projected through K_P
  (:func:`raspv_spv.retinotopy.visual_field_to_image`); electrodes the cortical map sends
  nowhere are left out. The spacing reported is the median nearest-neighbour distance.
- Every map also knows each phosphene's visual-field position (``centres_deg``, dva) and its
  electrode on the tissue (``electrodes_um``, µm; for the lattice, the retinal point under
  each centre by Watson 2014), which the tissue sprite models draw from.
- Defects (Appendix A-C): dropout (round(d·N) phosphenes, a fixed random subset) and Gaussian
  position noise σ px, drawn from ``seed``. They change only what is displayed
  (``display_centres``, ``dropped``), never ``centres``, which the modes sample with. The
  dropout order and the unit noise offsets depend only on the seed, so raising d keeps the
  phosphenes already dropped and changing σ scales the same offsets.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from raspv_spv.implant_layout import LayoutSpec, PlacedImplant
from raspv_spv.retinotopy import image_to_visual_field, visual_field_to_image, watson_dva_to_ret

GRIDS = ("rectangular", "hexagonal")
FIELDS = ("rectangular", "circular")
MAX_PHOSPHENES = 20000


class MapError(ValueError):
    """A phosphene map that cannot be built from the given parameters."""


@dataclass(frozen=True)
class MapSpec:
    """Inputs of a phosphene map (sizes px, angles deg of visual field)."""

    width: int = 800
    height: int = 800
    num_phosphenes: int = 1000
    grid: str = "hexagonal"
    field: str = "rectangular"
    fov_deg: float = 20.0
    phosphene_fov_deg: float = 0.5
    dropout: float = 0.0
    noise_px: float = 0.0
    seed: int = 0
    layout: LayoutSpec | None = None

    def __post_init__(self) -> None:
        problems = []
        if not (isinstance(self.width, int) and isinstance(self.height, int)) or not (16 <= self.width <= 4096 and 16 <= self.height <= 4096):
            problems.append(f"image size must be integers in [16, 4096] px, got {self.width}x{self.height}")
        if self.layout is None and (not isinstance(self.num_phosphenes, int)
                                    or not 1 <= self.num_phosphenes <= MAX_PHOSPHENES):
            problems.append(f"num_phosphenes must be an integer in [1, {MAX_PHOSPHENES}], got {self.num_phosphenes!r}")
        if self.grid not in GRIDS:
            problems.append(f"grid must be one of {', '.join(GRIDS)}, got {self.grid!r}")
        if self.field not in FIELDS:
            problems.append(f"field must be one of {', '.join(FIELDS)}, got {self.field!r}")
        if not (math.isfinite(self.fov_deg) and 0 < self.fov_deg < 170):
            problems.append(f"fov_deg must be in (0, 170), got {self.fov_deg}")
        if not (math.isfinite(self.phosphene_fov_deg) and 0 < self.phosphene_fov_deg < 20):
            problems.append(f"phosphene_fov_deg must be in (0, 20), got {self.phosphene_fov_deg}")
        if not (math.isfinite(self.dropout) and 0 <= self.dropout <= 1):
            problems.append(f"dropout must be in [0, 1], got {self.dropout}")
        if not (math.isfinite(self.noise_px) and self.noise_px >= 0):
            problems.append(f"noise_px must be >= 0, got {self.noise_px}")
        if not isinstance(self.seed, int) or self.seed < 0:
            problems.append(f"seed must be a non-negative integer, got {self.seed!r}")
        if problems:
            raise MapError("; ".join(problems))


def field_area(width: int, height: int, field: str) -> float:
    """Area [px²] phosphenes are spread over: the image or its inscribed circle."""
    if field == "circular":
        r = min(width, height) / 2.0
        return math.pi * r * r
    return float(width * height)


def lattice_spacing(width: int, height: int, num_phosphenes: int, grid: str, field: str = "rectangular") -> tuple[int, int]:
    """(δx, δy) in px from eqs. 1–3."""
    area = field_area(width, height, field)
    if grid == "hexagonal":
        dx = math.floor(math.sqrt(area * 2.0 / math.sqrt(3.0) / num_phosphenes))
        dy = math.floor(math.sqrt(3.0) / 2.0 * dx)
    else:
        dx = dy = math.floor(math.sqrt(area / num_phosphenes))
    if dx < 1 or dy < 1:
        raise MapError(f"{num_phosphenes} phosphenes do not fit a {width}x{height} image "
                       f"(spacing below 1 px); use fewer phosphenes or a larger image")
    return dx, dy


def lattice_centres(width: int, height: int, dx: int, dy: int, grid: str, field: str = "rectangular") -> np.ndarray:
    """Phosphene centres (N, 2) as (x, y) px, row by row from the top-left: rows at
    y = δy/2 + i·δy and columns at x = δx/2 (+ δx/2 on odd hexagonal rows) + j·δx while the
    centre is inside the image."""
    ys = dy / 2.0 + dy * np.arange(int(math.ceil((height - dy / 2.0) / dy)))
    rows = []
    for i, y in enumerate(ys):
        x0 = dx / 2.0 + (dx / 2.0 if grid == "hexagonal" and i % 2 == 1 else 0.0)
        xs = x0 + dx * np.arange(max(0, int(math.ceil((width - x0) / dx))))
        rows.append(np.stack([xs, np.full(xs.size, y)], axis=1))
    centres = np.concatenate(rows) if rows else np.zeros((0, 2))
    if field == "circular":
        r = min(width, height) / 2.0
        d2 = (centres[:, 0] - width / 2.0) ** 2 + (centres[:, 1] - height / 2.0) ** 2
        centres = centres[d2 <= r * r + 1e-9]
    return centres


def phosphene_focal_px(width: int, fov_deg: float) -> float:
    """f_P = w / (2·tan(FOV/2)) (eq. 5)."""
    return width / (2.0 * math.tan(math.radians(fov_deg) / 2.0))


def phosphene_diameter_px(focal_px: float, phosphene_fov_deg: float) -> float:
    """φ = 2·f_P·tan(FOV_P/2) (eq. 6)."""
    return 2.0 * focal_px * math.tan(math.radians(phosphene_fov_deg) / 2.0)


def defect_draws(count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(dropout order (count,), unit normal offsets (count, 2)) for ``seed``: independent
    streams so dropout and noise never influence each other's draws."""
    order = np.random.default_rng([seed, 1]).permutation(count)
    unit = np.random.default_rng([seed, 2]).standard_normal((count, 2))
    return order, unit


@dataclass(frozen=True)
class PhospheneMap:
    """A built map: sampling centres, displayed centres and everything the renderer needs."""

    spec: MapSpec
    spacing_x: int
    spacing_y: int
    focal_px: float
    diameter_px: float
    centres: np.ndarray = field(repr=False)           # (N, 2) P_i, what modes sample with
    display_centres: np.ndarray = field(repr=False)   # (N, 2) P̂_i = P_i + noise
    dropped: np.ndarray = field(repr=False)           # (N,) bool
    centres_deg: np.ndarray = field(repr=False, default=None)     # (N, 2) visual field of P_i [dva]
    electrodes_um: np.ndarray = field(repr=False, default=None)   # (N, 2) electrode on the tissue [µm]
    implant: PlacedImplant | None = field(repr=False, default=None)   # the layout, when there is one

    @classmethod
    def build(cls, spec: MapSpec) -> "PhospheneMap":
        focal = phosphene_focal_px(spec.width, spec.fov_deg)
        cx, cy = spec.width / 2.0, spec.height / 2.0
        implant = None
        if spec.layout is not None:
            implant = PlacedImplant.build(spec.layout)
            centres = np.stack(visual_field_to_image(implant.centres_deg[:, 0], implant.centres_deg[:, 1],
                                                     focal, cx, cy), axis=1)
            dx = dy = int(round(_median_neighbour_distance(centres)))
            centres_deg = implant.centres_deg
            electrodes = implant.electrodes_um
        else:
            dx, dy = lattice_spacing(spec.width, spec.height, spec.num_phosphenes, spec.grid, spec.field)
            centres = lattice_centres(spec.width, spec.height, dx, dy, spec.grid, spec.field)
            if len(centres) == 0:
                raise MapError(f"no phosphene fits a {spec.width}x{spec.height} image with spacing {dx}x{dy} px")
            centres_deg = np.stack(image_to_visual_field(centres[:, 0], centres[:, 1], focal, cx, cy), axis=1)
            electrodes = np.stack(watson_dva_to_ret(centres_deg[:, 0], centres_deg[:, 1]), axis=1)
        order, unit = defect_draws(len(centres), spec.seed)
        dropped = np.zeros(len(centres), dtype=bool)
        dropped[order[: int(round(spec.dropout * len(centres)))]] = True
        display = centres + spec.noise_px * unit
        for a in (centres, display, dropped, centres_deg, electrodes):
            a.flags.writeable = False
        return cls(spec, dx, dy, focal, phosphene_diameter_px(focal, spec.phosphene_fov_deg), centres, display, dropped,
                   centres_deg, electrodes, implant)

    @property
    def count(self) -> int:
        return len(self.centres)

    @property
    def target(self) -> str:
        """The tissue the phosphenes come from: "retina" (lattice or retinal implant) or "cortex"."""
        return self.implant.layout.target if self.implant is not None else "retina"

    @property
    def width(self) -> int:
        return self.spec.width

    @property
    def height(self) -> int:
        return self.spec.height

    @property
    def K(self) -> np.ndarray:
        """K_P (eq. 4), 3×3, principal point at the image centre (w/2, h/2)."""
        f = self.focal_px
        return np.array([[f, 0.0, self.width / 2.0], [0.0, f, self.height / 2.0], [0.0, 0.0, 1.0]])

    def rays(self) -> np.ndarray:
        """Rays r_i = K_P⁻¹·P_i (N, 3) with z = 1, in the camera frame (x right, y down)."""
        f = self.focal_px
        x = (self.centres[:, 0] - self.width / 2.0) / f
        y = (self.centres[:, 1] - self.height / 2.0) / f
        return np.stack([x, y, np.ones_like(x)], axis=1)


def _median_neighbour_distance(points: np.ndarray) -> float:
    """Median distance from each point to its nearest neighbour (1 for a single point)."""
    if len(points) < 2:
        return 1.0
    d, _ = cKDTree(points).query(points, k=2)
    return max(1.0, float(np.median(d[:, 1])))
