"""Sprite models: the shape of every phosphene, precomputed for the sparse renderer (no ROS).

A model turns a built :class:`~raspv_spv.phosphene_map.PhospheneMap` into a
:class:`SpriteBank`: a sparse matrix whose column i is phosphene i's image (×255), so the
per-frame cost is one sparse product whatever the shape (:mod:`raspv_spv.renderer`).

| model | shape | from | parameters |
|---|---|---|---|
| ``gaussian`` | the paper's round spot of ``phosphene_fov_deg`` | RASPV Appendix A | — |
| ``scoreboard`` | exp(−d²/2ρ²) on the retina or cortex | Beyeler 2019; pulse2percept ``ScoreboardModel`` | ρ (µm; default half the electrode pitch) |
| ``axon_map`` | streaks along the nerve-fibre bundles | Beyeler 2019; pulse2percept ``AxonMapModel`` | ρ (300), λ (500 µm), eye |
| ``biphasic_axon_map`` | axon map whose size, streak and brightness follow the pulse | Granley & Beyeler 2021; ``BiphasicAxonMapModel`` | ρ, λ, top amplitude (xTh), phase (ms), rate (Hz) |
| ``dynaphos`` | round, σ = 0.5·√(I/675 µA)/M(e) dva | van der Grinten 2024; dynaphos ``GaussianSimulator`` | current of the top level (µA) |

``biphasic_axon_map`` and ``dynaphos`` draw one sprite per level (a brighter level is a
larger current, so a bigger phosphene): column i·L + (l − 1) for level l of L = N_L − 1.
Every other model has one column per phosphene, scaled by its level. Sprites are normalised
to the model's peak (1 for a unit stimulus; the top level's F_bright for the biphasic model)
and values below 1e-3 of it (a quarter of a grey level) are dropped. Tissue sprites overlap
far more than the paper's (an Argus II streak crosses several electrodes), and a saturating
sum would turn a lit array into a white blob with no shape left; so the bank is scaled so
that every phosphene at the top level together reaches exactly white (the brightest the
array can make), and shapes stay visible where they overlap. A lone phosphene is then dimmer
than white by that factor (``SpriteBank.gain``, ≈ 1/2.6 for Argus II with ρ 300, λ 1000 µm).

The scoreboard's default ρ is half the median electrode pitch on the tissue, so neighbouring
phosphenes just touch (13 % of a phosphene's peak one pitch away): pulse2percept's fixed
100 µm (retina) / 200 µm (cortex) would blur Alpha-IMS' 72 µm pixels into one blob and shrink
Orion's 4.2 mm-spaced discs to dots. Set ``rho_um`` to choose.

Tissue models are smooth on the scale of their narrowest spread σ (ρ, λ, or dynaphos' σ),
so they are sampled on a grid ``scale`` times coarser than the image (σ ≥ 4 coarse pixels,
``scale`` ≤ 8) and interpolated bilinearly when rendered: the interpolation error of a
Gaussian sampled every σ/4 is below 1 % of its peak (h²/8·max|f''| = 1/128), while the
matrix and the per-frame product shrink by ``scale``². Phosphenes too small for that grid
(a cortical map's foveal ones next to its large peripheral ones) stay on the image's own
pixels in a second matrix; ``scale`` is chosen to minimise the pixels added per frame. Banks that take long to build are
cached on disk under ``$RASPV_CACHE_DIR/sprites`` (default ``~/.cache/raspv``), named by a hash
of everything they depend on.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import cv2
import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from raspv_spv.axon_map import AxonBundles, AxonMapParams, axon_sprites, blend_meridian
from raspv_spv.biphasic_axon_map import GranleyEffects, biphasic_axon_sprites, level_amplitudes_xth
from raspv_spv.phosphene_map import PhospheneMap
from raspv_spv.retinotopy import CORTICAL_MAPS, image_to_visual_field, watson_um_per_deg
from raspv_spv.sprite_model_names import LEVELLED_MODELS, SPRITE_MODELS
from raspv_spv.sprites import GaussianSprite
from raspv_spv.tissue_sprites import (cortical_scoreboard_sprites, dynaphos_sigma_deg, dynaphos_sprites,
                                      retinal_scoreboard_sprites)

MIN_WEIGHT = 1e-3
MAX_SCALE = 8
SIGMA_COARSE_PX = 4.0
AXON_BLEND_DEG = 1.0        # pulse2percept AxonMapModel meridian_blend (horizontal meridian)
CORTEX_BLEND_DEG = 0.1      # pulse2percept cortical ScoreboardModel meridian_blend (vertical meridian)
_FORMAT_VERSION = 3


class SpriteModelError(ValueError):
    """A sprite model that cannot be built for this map."""


@dataclass(frozen=True)
class SpriteSpec:
    """Which sprite model and its parameters. ``rho_um`` / ``axlambda_um`` 0: the model's
    default. ``max_amplitude_xth``: the top level's pulse amplitude (multiples of threshold,
    biphasic model); ``pulse_phase_ms`` and ``pulse_rate_hz`` the pulses (biphasic model);
    ``current_ua``: the top level's current (dynaphos)."""

    model: str = "gaussian"
    rho_um: float = 0.0
    axlambda_um: float = 0.0
    eye: str = "right"
    num_levels: int = 8
    max_amplitude_xth: float = 3.0
    pulse_phase_ms: float = 0.45
    pulse_rate_hz: float = 50.0
    current_ua: float = 100.0

    def __post_init__(self) -> None:
        if self.model not in SPRITE_MODELS:
            raise SpriteModelError(f"sprite model must be one of {', '.join(SPRITE_MODELS)}, got {self.model!r}")
        for name in ("rho_um", "axlambda_um"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise SpriteModelError(f"{name} must be >= 0 (0: the model's default), got {v}")
        if self.model == "axon_map" or self.model == "biphasic_axon_map":
            if 0 < self.axlambda_um < 10:
                raise SpriteModelError(f"axlambda must be >= 10 µm for the axon map (use scoreboard below), "
                                       f"got {self.axlambda_um}")
        if not (math.isfinite(self.max_amplitude_xth) and self.max_amplitude_xth >= 1):
            raise SpriteModelError(f"max_amplitude_xth must be >= 1 (threshold), got {self.max_amplitude_xth}")

    @property
    def levelled(self) -> bool:
        return self.model in LEVELLED_MODELS

    def rho(self, target: str, phosphene_map: PhospheneMap | None = None) -> float:
        """ρ (µm) with the model default filled in: 300 for the axon maps (pulse2percept's),
        half the electrode pitch of ``phosphene_map`` for the scoreboard (pulse2percept's 100 on
        the retina, 200 on the cortex without a map)."""
        if self.rho_um > 0:
            return self.rho_um
        if self.model == "scoreboard":
            if phosphene_map is None:
                return 100.0 if target == "retina" else 200.0
            return 0.5 * electrode_pitch_um(phosphene_map)
        return 300.0

    def axlambda(self) -> float:
        return self.axlambda_um if self.axlambda_um > 0 else 500.0

    def check(self, phosphene_map: PhospheneMap) -> None:
        """Raise :class:`SpriteModelError` when this model cannot draw ``phosphene_map``."""
        target = phosphene_map.target
        if self.model in ("axon_map", "biphasic_axon_map") and target != "retina":
            raise SpriteModelError(f"the {self.model} model needs a retinal layout; "
                                   f"{phosphene_map.implant.layout.name} is cortical (use scoreboard or dynaphos)")
        if self.model != "gaussian" and phosphene_map.spec.noise_px > 0:
            raise SpriteModelError(f"position noise applies to the gaussian sprite model only; the {self.model} "
                                   "model draws each phosphene from its electrode's position")
        if self.levelled and self.num_levels < 2:
            raise SpriteModelError("a levelled sprite model needs at least 2 levels")


@dataclass
class SpriteBank:
    """Precomputed sprites: ``matrix`` (coarse pixels × N·levels, CSC float32, values ×255) on
    a grid ``scale`` times coarser than the ``width`` × ``height`` image, plus ``fine``, the
    phosphenes too small for that grid at the image's own pixels; ``levels`` sprites per
    phosphene (1: one sprite scaled by the level)."""

    matrix: sp.csc_matrix
    width: int
    height: int
    scale: int = 1
    levels: int = 1
    build_s: float = 0.0
    cached: bool = False
    gain: float = 1.0          # the scale applied so the whole array at the top level is white
    fine: sp.csc_matrix | None = None   # (height·width, N·levels): sprites too small for the coarse grid

    @property
    def coarse_shape(self) -> tuple[int, int]:
        """(rows, cols) of the grid the matrix is sampled on."""
        return -(-self.height // self.scale), -(-self.width // self.scale)

    @property
    def nnz(self) -> int:
        """Sprite pixels stored (both grids)."""
        return int(self.matrix.nnz + (self.fine.nnz if self.fine is not None else 0))

    @property
    def nbytes(self) -> int:
        return int(sum(m.data.nbytes + m.indices.nbytes + m.indptr.nbytes
                       for m in (self.matrix, self.fine) if m is not None))


def electrode_pitch_um(phosphene_map: PhospheneMap) -> float:
    """Median distance (µm) from each electrode to its nearest neighbour on the tissue."""
    xy = phosphene_map.electrodes_um
    if len(xy) < 2:
        return 200.0
    d, _ = cKDTree(xy).query(xy, k=2)
    return float(np.median(d[:, 1]))


def coarse_grid_deg(phosphene_map: PhospheneMap, scale: int) -> tuple[np.ndarray, np.ndarray]:
    """Visual-field position (dva) of the centres of the ``scale``-times coarser grid over the
    phosphene image, (rows, cols) each."""
    h, w = -(-phosphene_map.height // scale), -(-phosphene_map.width // scale)
    u = (np.arange(w) + 0.5) * scale
    v = (np.arange(h) + 0.5) * scale
    uu, vv = np.meshgrid(u, v, indexing="xy")
    return image_to_visual_field(uu, vv, phosphene_map.focal_px, phosphene_map.width / 2.0, phosphene_map.height / 2.0)


def phosphene_spreads_deg(phosphene_map: PhospheneMap, spec: SpriteSpec) -> np.ndarray:
    """The narrowest spatial spread σ (dva) of each phosphene's sprite (over its levels): what
    the sampling grid must resolve for it."""
    m = phosphene_map
    ecc = np.hypot(m.centres_deg[:, 0], m.centres_deg[:, 1])
    target = m.target
    if spec.model == "gaussian":
        return np.full(m.count, m.spec.phosphene_fov_deg / 4.0)
    if spec.model == "dynaphos":
        cmap = m.implant.cortical_map if m.implant is not None else CORTICAL_MAPS["dynaphos"]
        return dynaphos_sigma_deg(m.centres_deg, spec.current_ua * 1e-6 / (spec.num_levels - 1), cmap)
    rho = spec.rho(target, m)
    spread = rho
    if spec.model in ("axon_map", "biphasic_axon_map"):
        spread = min(rho, spec.axlambda())
        if spec.model == "biphasic_axon_map":
            g = GranleyEffects()
            amps = level_amplitudes_xth(spec.num_levels, spec.max_amplitude_xth)
            f_size = float(np.min(g.size(amps, spec.pulse_phase_ms, rho)))
            f_streak = float(g.streak(spec.pulse_phase_ms, spec.axlambda()))
            spread = min(rho * math.sqrt(f_size), spec.axlambda() * math.sqrt(f_streak))
    if target == "cortex":
        return spread / 1000.0 / m.implant.cortical_map.magnification(ecc)
    return spread / watson_um_per_deg(ecc)


def sampling_plan(phosphene_map: PhospheneMap, spec: SpriteSpec) -> tuple[int, np.ndarray]:
    """(scale S, phosphenes drawn at full resolution): phosphenes whose σ spans at least 4
    pixels of a grid S times coarser go on that grid, the others on the image's own pixels
    (cortical maps mix tiny foveal phosphenes with large peripheral ones). S minimises the
    sprite pixels to add per frame; 1 for the paper's sprites."""
    m = phosphene_map
    if spec.model == "gaussian":
        return 1, np.zeros(0, np.int64)
    sigma = phosphene_spreads_deg(m, spec) * math.pi / 180.0 * m.focal_px
    sigma = np.where(np.isfinite(sigma), sigma, 0.0)
    area = np.minimum(math.pi * (3.72 * sigma) ** 2, float(m.width * m.height))   # px of a sprite at 1e-3
    best, best_cost = 1, float(area.sum())
    for scale in range(2, MAX_SCALE + 1):
        coarse = sigma >= SIGMA_COARSE_PX * scale
        if not coarse.any():
            break
        cost = area[~coarse].sum() + area[coarse].sum() / scale ** 2 + (m.width * m.height if (~coarse).any() else 0)
        if cost < best_cost:
            best, best_cost = scale, cost
    fine = np.flatnonzero(sigma < SIGMA_COARSE_PX * best) if best > 1 else np.zeros(0, np.int64)
    return best, fine


def render_scale(phosphene_map: PhospheneMap, spec: SpriteSpec) -> int:
    """How much coarser than the image the (larger) sprites are sampled (1 for the paper's)."""
    return sampling_plan(phosphene_map, spec)[0]


def model_sprites(phosphene_map: PhospheneMap, spec: SpriteSpec, x_deg: np.ndarray, y_deg: np.ndarray,
                  min_weight: float = MIN_WEIGHT, phosphenes: np.ndarray | None = None) -> sp.csc_matrix:
    """Sparse (points, N·levels) sprites of a tissue model evaluated on a grid (rows, cols) of
    visual-field points (dva), normalised to the model's peak — what the renderer samples and
    what the tests compare with pulse2percept and dynaphos. ``phosphenes``: only those
    (their columns; the others stay empty)."""
    m = phosphene_map
    ids = np.arange(m.count) if phosphenes is None else np.asarray(phosphenes, dtype=np.int64)
    n_lv = spec.num_levels - 1 if spec.levelled else 1
    sub = _model_sprites(m, spec, x_deg, y_deg, min_weight, ids)
    if phosphenes is None:
        return sub
    coo = sub.tocoo()
    cols = ids[coo.col // n_lv] * n_lv + coo.col % n_lv
    return sp.csc_matrix((coo.data, (coo.row, cols)), shape=(sub.shape[0], m.count * n_lv))


def _model_sprites(m: PhospheneMap, spec: SpriteSpec, x_deg, y_deg, min_weight: float, ids: np.ndarray) -> sp.csc_matrix:
    shape = np.shape(x_deg)
    electrodes = m.electrodes_um[ids]
    target = m.target
    rho = spec.rho(target, m)
    if spec.model == "scoreboard":
        if target == "cortex":
            s = cortical_scoreboard_sprites(x_deg, y_deg, electrodes, rho, m.implant.cortical_map, min_weight)
            return blend_meridian(s, shape, x_deg, CORTEX_BLEND_DEG, axis=1)
        return retinal_scoreboard_sprites(x_deg, y_deg, electrodes, rho, min_weight)
    if spec.model == "dynaphos":
        cmap = m.implant.cortical_map if m.implant is not None else CORTICAL_MAPS["dynaphos"]
        levels = np.arange(1, spec.num_levels) / (spec.num_levels - 1)
        return dynaphos_sprites(x_deg, y_deg, m.centres_deg[ids], spec.current_ua * 1e-6 * levels, levels, cmap,
                                min_weight)
    params = AxonMapParams(rho_um=rho, axlambda_um=spec.axlambda(), eye=spec.eye)
    x_range = (float(np.min(x_deg)), float(np.max(x_deg)))
    y_range = (float(np.min(y_deg)), float(np.max(y_deg)))
    axons = AxonBundles(params, x_range, y_range).axons(x_deg, y_deg)
    if spec.model == "axon_map":
        s = axon_sprites(axons, electrodes, rho, min_weight=min_weight)
    else:
        amps = level_amplitudes_xth(spec.num_levels, spec.max_amplitude_xth)
        s = biphasic_axon_sprites(axons, electrodes, rho, spec.axlambda(), amps, spec.pulse_rate_hz,
                                  spec.pulse_phase_ms, min_weight=min_weight)
        s = s * (1.0 / float(GranleyEffects().brightness(spec.pulse_rate_hz, amps[-1], spec.pulse_phase_ms)))
    return blend_meridian(sp.csc_matrix(s), shape, y_deg, AXON_BLEND_DEG, axis=0)


def upsample(values: np.ndarray, coarse_shape: tuple[int, int], scale: int, width: int, height: int) -> np.ndarray:
    """A grid of ``coarse_shape`` sampled every ``scale`` px (values flat) → the image
    (height, width), bilinear (cell centres on pixel centres)."""
    image = np.asarray(values, dtype=np.float32).reshape(coarse_shape)
    if scale == 1:
        return image
    rows, cols = coarse_shape
    image = cv2.resize(image, (cols * scale, rows * scale), interpolation=cv2.INTER_LINEAR)
    return image[:height, :width]


def cached_bank_path(phosphene_map: PhospheneMap, spec: SpriteSpec) -> Path | None:
    """Where the bank of a tissue model is cached (None for the paper's sprites, built in
    milliseconds and not cached)."""
    if spec.model == "gaussian":
        return None
    scale, fine = sampling_plan(phosphene_map, spec)
    return _cache_path(phosphene_map, spec, scale, fine)


def build_sprite_bank(phosphene_map: PhospheneMap, spec: SpriteSpec, use_cache: bool = True) -> SpriteBank:
    """The sprites of ``phosphene_map`` drawn by ``spec``'s model (from the disk cache when a
    tissue model was built before with the same inputs)."""
    spec.check(phosphene_map)
    m = phosphene_map
    t0 = time.perf_counter()
    if spec.model == "gaussian":
        from raspv_spv.renderer import sprite_matrix

        matrix = sprite_matrix(m.display_centres, np.ones(m.count, bool), m.width, m.height,
                               GaussianSprite(m.diameter_px))
        return SpriteBank(matrix, m.width, m.height, 1, 1, time.perf_counter() - t0)
    scale, fine = sampling_plan(m, spec)
    levels = spec.num_levels - 1 if spec.levelled else 1
    path = _cache_path(m, spec, scale, fine) if use_cache else None
    if path is not None and path.exists():
        bank = _load(path, m, scale, levels)
        if bank is not None:
            bank.build_s = time.perf_counter() - t0
            return bank
    coarse_ids = np.setdiff1d(np.arange(m.count), fine)
    x, y = coarse_grid_deg(m, scale)
    coarse = sp.csc_matrix(model_sprites(m, spec, x, y, phosphenes=coarse_ids if fine.size else None), dtype=np.float32)
    fine_part = None
    if fine.size:
        fx, fy = coarse_grid_deg(m, 1)
        fine_part = sp.csc_matrix(model_sprites(m, spec, fx, fy, phosphenes=fine), dtype=np.float32)
    top = np.zeros(coarse.shape[1], np.float32)
    top[levels - 1::levels] = 1.0
    all_on = upsample(coarse @ top, ((m.height + scale - 1) // scale, (m.width + scale - 1) // scale), scale,
                      m.width, m.height)
    if fine_part is not None:
        all_on = all_on + (fine_part @ top).reshape(m.height, m.width)
    peak = float(all_on.max()) if all_on.size else 0.0
    gain = 1.0 / peak if peak > 1.0 else 1.0
    parts = []
    for part in (coarse, fine_part):
        if part is None:
            parts.append(None)
            continue
        part = part * np.float32(255.0 * gain)
        part.data[part.data < MIN_WEIGHT * 255.0 * gain] = 0.0
        part.eliminate_zeros()
        part.sort_indices()
        parts.append(part)
    bank = SpriteBank(parts[0], m.width, m.height, scale, levels, time.perf_counter() - t0, gain=gain, fine=parts[1])
    if path is not None:
        _save(path, bank)
    return bank


# -- disk cache ---------------------------------------------------------------------------------
def cache_dir() -> Path:
    return Path(os.environ.get("RASPV_CACHE_DIR") or Path.home() / ".cache" / "raspv") / "sprites"


def _cache_path(m: PhospheneMap, spec: SpriteSpec, scale: int, fine: np.ndarray) -> Path:
    digest = hashlib.sha256()
    digest.update(json.dumps({"version": _FORMAT_VERSION, "spec": asdict(spec), "width": m.width, "height": m.height,
                              "focal": round(m.focal_px, 9), "scale": scale, "min_weight": MIN_WEIGHT,
                              "cortical_map": m.implant.spec.cortical_map if m.implant else ""},
                             sort_keys=True).encode())
    digest.update(np.ascontiguousarray(m.electrodes_um, dtype=np.float64).tobytes())
    digest.update(np.ascontiguousarray(m.centres_deg, dtype=np.float64).tobytes())
    digest.update(np.ascontiguousarray(fine, dtype=np.int64).tobytes())
    return cache_dir() / f"{spec.model}-{digest.hexdigest()[:24]}.npz"


def _load(path: Path, m: PhospheneMap, scale: int, levels: int) -> SpriteBank | None:
    try:
        with np.load(path, allow_pickle=False) as f:
            parts = []
            for name in ("coarse", "fine"):
                if f"{name}_shape" not in f:
                    parts.append(None)
                    continue
                shape = tuple(int(v) for v in f[f"{name}_shape"])
                parts.append(sp.csc_matrix((f[f"{name}_data"], f[f"{name}_indices"], f[f"{name}_indptr"]), shape=shape))
            gain = float(f["gain"])
    except (OSError, ValueError, KeyError):
        return None                                    # unreadable cache file: rebuild it
    rows, cols = -(-m.height // scale), -(-m.width // scale)
    expected = {"coarse": (rows * cols, m.count * levels), "fine": (m.height * m.width, m.count * levels)}
    for name, part in zip(("coarse", "fine"), parts):
        if part is None:
            continue
        if part.shape != expected[name] or part.data.dtype != np.float32 or not np.all(np.isfinite(part.data)):
            return None
    if parts[0] is None:
        return None
    return SpriteBank(parts[0], m.width, m.height, scale, levels, cached=True, gain=gain, fine=parts[1])


def _save(path: Path, bank: SpriteBank) -> None:
    """Write atomically; an unwritable cache only costs the rebuild next time."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        arrays = {"gain": np.array(bank.gain)}
        for name, part in (("coarse", bank.matrix), ("fine", bank.fine)):
            if part is not None:
                arrays.update({f"{name}_data": part.data, f"{name}_indices": part.indices,
                               f"{name}_indptr": part.indptr, f"{name}_shape": np.array(part.shape)})
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **arrays)
        os.replace(tmp, path)
    except OSError:
        pass
