"""Optional realism for the simulated depth camera (off by default; numpy/OpenCV, no rclpy).

Perfect simulated depth flatters every algorithm (the paper says so about its own results).
This model degrades it the way structured-light/stereo RGB-D sensors do, in this order:

1. axial noise growing with distance, σ(z) = ``noise_at_1m`` · z² (Khoshelham & Elberink 2012
   measured ≈ 1.4 mm at 1 m for the Kinect);
2. disparity quantisation: z is snapped to the depth of the nearest 1/``subpixel`` px disparity
   step of a stereo pair with ``baseline`` m and the camera's focal length;
3. missing pixels: at depth edges (a neighbour differs by more than ``edge_jump`` · z, widened by
   ``edge_width`` px), on dark surfaces (grey level < ``dark_level``, dropped with probability
   ``dark_dropout``) and on surfaces marked specular (dropped with ``specular_dropout``);
4. readings beyond ``max_range`` m are missing.
Missing pixels are NaN.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class DepthSensorConfig:
    noise_at_1m: float = 0.0014      # m, σ of the axial noise at 1 m (scales with z²)
    baseline: float = 0.075          # m, for disparity quantisation
    subpixel: float = 8.0            # disparity steps per pixel (0 turns quantisation off)
    edge_jump: float = 0.04          # relative depth jump that makes an edge
    edge_width: int = 1              # px, how far missing edges spread
    dark_level: int = 25             # 0..255 grey level under which a surface is "dark"
    dark_dropout: float = 0.6        # probability a dark pixel has no reading
    specular_dropout: float = 0.7    # probability a specular pixel has no reading
    max_range: float = 6.0           # m

    def __post_init__(self) -> None:
        for name in ("noise_at_1m", "baseline", "subpixel", "edge_jump", "max_range"):
            if getattr(self, name) < 0:
                raise ValueError(f"depth sensor '{name}' must be non-negative, got {getattr(self, name)}")
        for name in ("dark_dropout", "specular_dropout"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"depth sensor '{name}' must be in [0, 1], got {getattr(self, name)}")


def sensor_config_from_params(p: dict) -> DepthSensorConfig | None:
    """The sim node's ``depth_*`` parameters (``depth_noise`` off: None, noise-free depth)."""
    if not p["depth_noise"]:
        return None
    return DepthSensorConfig(noise_at_1m=p["depth_noise_at_1m"], subpixel=p["depth_subpixel"],
                             edge_jump=p["depth_edge_jump"], dark_dropout=p["depth_dark_dropout"],
                             specular_dropout=p["depth_specular_dropout"], max_range=p["depth_max_range"])


class DepthSensorModel:
    """Applies :class:`DepthSensorConfig` to perfect depth images of a camera with focal ``fx`` px."""

    def __init__(self, config: DepthSensorConfig, fx: float, seed: int | None = 0):
        self.config = config
        self.fx = float(fx)
        self.seed = seed
        self.rng = np.random.default_rng(seed)
        w = int(config.edge_width)
        self._kernel = np.ones((2 * w + 1, 2 * w + 1), np.uint8) if w > 0 else None

    def start_trial(self, x: float, y: float, yaw: float) -> None:
        """A trial starts at (x, y) [m, W] facing ``yaw`` [rad]: the noise restarts from the seed
        and that pose, so a trial's noise does not depend on the frames rendered before it (a
        graph that ran earlier trials or rendered while holding, a resumed session, a quick trial)."""
        pose = zlib.crc32(f"{x:.4f},{y:.4f},{yaw:.5f}".encode())
        self.rng = np.random.default_rng(None if self.seed is None else [int(self.seed), pose])

    def apply(self, depth: np.ndarray, rgb: np.ndarray | None = None, specular: np.ndarray | None = None) -> np.ndarray:
        """``depth`` (H, W) float32 m (NaN = none), ``rgb`` (H, W, 3) uint8, ``specular`` (H, W)
        bool → degraded float32 depth."""
        c = self.config
        z = np.array(depth, dtype=np.float32, copy=True)
        valid = np.isfinite(z)
        if c.noise_at_1m > 0:
            z += (self.rng.standard_normal(z.shape, dtype=np.float32) * np.float32(c.noise_at_1m)) * np.nan_to_num(z) ** 2
        if c.subpixel > 0 and c.baseline > 0:
            fb = np.float32(self.fx * c.baseline)
            with np.errstate(divide="ignore", invalid="ignore"):
                disparity = np.round(fb / z * np.float32(c.subpixel)) / np.float32(c.subpixel)
                z = np.where(disparity > 0, fb / disparity, np.nan).astype(np.float32)
        missing = ~valid | ~np.isfinite(z) | (z > c.max_range) | (z <= 0)
        if c.edge_jump > 0:
            filled = np.where(valid, depth, np.float32(1e3)).astype(np.float32)
            jump = np.zeros(z.shape, bool)
            dx = np.abs(np.diff(filled, axis=1)) > c.edge_jump * np.minimum(filled[:, 1:], filled[:, :-1])
            dy = np.abs(np.diff(filled, axis=0)) > c.edge_jump * np.minimum(filled[1:], filled[:-1])
            jump[:, 1:] |= dx
            jump[:, :-1] |= dx
            jump[1:] |= dy
            jump[:-1] |= dy
            if self._kernel is not None:
                jump = cv2.dilate(jump.view(np.uint8), self._kernel).astype(bool)
            missing |= jump
        if rgb is not None and c.dark_dropout > 0:
            grey = cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2GRAY)
            missing |= (grey < c.dark_level) & (self.rng.random(z.shape, dtype=np.float32) < c.dark_dropout)
        if specular is not None and c.specular_dropout > 0:
            missing |= specular & (self.rng.random(z.shape, dtype=np.float32) < c.specular_dropout)
        z[missing] = np.nan
        return z
