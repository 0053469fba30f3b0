"""The avatar's RGB-D camera rendered by PyBullet, with intrinsics that match the pixels exactly.

Renderer: the ``eglRenderer`` plugin (OpenGL through EGL; headless with Mesa llvmpipe) when it
loads, otherwise PyBullet's software TinyRenderer. The two put pixel centres at different
places for the same projection matrix (EGL at (u + ½, v + ½) like OpenGL; TinyRenderer shifted by
half a pixel in x and −½ in y), so the projection matrix is built per renderer from the
intrinsics, which follow the project's convention (integer pixel coordinates at pixel centres,
``raspv_common.intrinsics``). Depth is metric z along the optical axis, float32, NaN where
nothing is closer than ``far``. The EGL plugin's shadow-map pass, which ignores ``shadow=0``
and costs most of a frame without a GPU, is turned off (:mod:`raspv_sim.egl_shadow_pass`).
"""
from __future__ import annotations

import importlib.util
import re
from dataclasses import dataclass

import numpy as np
import pybullet

from raspv_common.intrinsics import CameraIntrinsics
from raspv_sim.egl_shadow_pass import disable_shadow_map
from raspv_sim.native_output import captured_native_output

# Continuous pixel coordinate, in the project's convention, of the point a symmetric projection
# puts at the image centre: centre = (W/2 + dx, H/2 + dy).
_CENTRE_OFFSET = {"egl": (-0.5, -0.5), "tiny": (0.0, -1.0)}
# optical frame (x right, y down, z forward) → OpenGL camera frame (x right, y up, z backward)
_OPTICAL_TO_GL = np.diag([1.0, -1.0, -1.0, 1.0])


@dataclass(frozen=True)
class RendererInfo:
    name: str            # "egl" or "tiny"
    description: str     # for the start-up message
    flag: int            # PyBullet renderer constant


def load_renderer(client, prefer: str = "auto") -> RendererInfo:
    """Load the EGL plugin into ``client`` unless ``prefer`` is "tiny"; fall back to TinyRenderer
    when it does not load (``prefer="egl"`` then raises RuntimeError)."""
    if prefer not in ("auto", "egl", "tiny"):
        raise ValueError(f"renderer must be auto, egl or tiny, got {prefer!r}")
    reason = "TinyRenderer requested"
    if prefer != "tiny":
        spec = importlib.util.find_spec("eglRenderer")
        if spec is None or not spec.origin:
            reason = "the eglRenderer plugin is not installed with pybullet"
        else:
            with captured_native_output() as out:
                plugin = client.loadPlugin(spec.origin, "_eglRendererPlugin")
                ok = plugin >= 0 and _renders(client, pybullet.ER_BULLET_HARDWARE_OPENGL)
            if ok:
                gl = re.search(r"GL_RENDERER=(.*)", out.text)
                kept = disable_shadow_map(spec.origin)        # the plugin ignores shadow=0 (egl_shadow_pass.py)
                shadow = f"; shadow-map pass left on: {kept}" if kept else ""
                return RendererInfo("egl", f"EGL OpenGL ({gl.group(1).strip() if gl else 'unknown GL renderer'}"
                                           f"{shadow})", pybullet.ER_BULLET_HARDWARE_OPENGL)
            if plugin >= 0:
                client.unloadPlugin(plugin)
            reason = "the EGL plugin did not load (" + (" ".join(out.text.split())[-120:] or "no EGL display") + ")"
        if prefer == "egl":
            raise RuntimeError(f"EGL renderer requested but unavailable: {reason}")
    return RendererInfo("tiny", f"TinyRenderer (software; {reason})", pybullet.ER_TINY_RENDERER)


def _renders(client, flag: int) -> bool:
    try:
        w, h, rgb, _, _ = client.getCameraImage(8, 8, renderer=flag)
    except pybullet.error:
        return False
    return (w, h) == (8, 8)


def projection_matrix(intr: CameraIntrinsics, near: float, far: float, renderer: str) -> list[float]:
    """Column-major OpenGL projection for ``renderer`` ("egl" or "tiny") whose pixels follow
    ``intr`` exactly (focal lengths and principal point in px)."""
    W, H = intr.width, intr.height
    dx, dy = _CENTRE_OFFSET[renderer]
    P = np.zeros((4, 4))
    P[0, 0] = 2.0 * intr.fx / W
    P[1, 1] = 2.0 * intr.fy / H
    # a principal point moved by (Δu, Δv) px from the symmetric one shifts NDC by (−2Δu/W, +2Δv/H)
    P[0, 2] = -2.0 * (intr.cx - (W / 2 + dx)) / W
    P[1, 2] = 2.0 * (intr.cy - (H / 2 + dy)) / H
    P[2, 2] = -(far + near) / (far - near)
    P[2, 3] = -2.0 * far * near / (far - near)
    P[3, 2] = -1.0
    return P.flatten(order="F").tolist()


def view_matrix(world_from_camera: np.ndarray) -> list[float]:
    """Column-major OpenGL view matrix for a camera whose optical frame is ``world_from_camera``."""
    gl_from_world = np.linalg.inv(np.asarray(world_from_camera, dtype=float) @ _OPTICAL_TO_GL)
    return gl_from_world.flatten(order="F").tolist()


@dataclass
class RawFrame:
    """One render: ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float32 m (NaN: nothing within far),
    ``body`` (H, W) int32 PyBullet body id per pixel (−1: nothing)."""

    rgb: np.ndarray
    depth: np.ndarray
    body: np.ndarray | None            # None when rendered without the id buffer


class SimCamera:
    """Renders RGB, metric depth and the body-id buffer of one client at fixed intrinsics.

    ``near`` clips the view; ``far`` is the depth sensor's range (farther depth is NaN), while
    colour and labels are rendered out to ``view_distance`` m, as a real RGB-D camera sees
    colour beyond its depth range."""

    def __init__(self, client, intrinsics: CameraIntrinsics, near: float = 0.05, far: float = 8.0,
                 renderer: RendererInfo | None = None, light_direction=(0.4, 0.25, 1.0), view_distance: float = 100.0):
        if not 0 < near < far:
            raise ValueError(f"clipping planes must satisfy 0 < near < far, got near={near}, far={far}")
        self.client = client
        self.intrinsics = intrinsics
        self.near, self.far = float(near), float(far)
        self.clip_far = max(self.far, float(view_distance))
        self.renderer = renderer or load_renderer(client)
        self.light_direction = list(light_direction)
        self._proj = projection_matrix(intrinsics, near, self.clip_far, self.renderer.name)
        if self.renderer.name == "egl":
            with captured_native_output():  # the plugin reports its GL vendor on the first render
                sky = np.eye(4)
                sky[2, 3] = 1e4           # far above everything, looking up: nothing to draw
                self.client.getCameraImage(8, 8, view_matrix(sky), self._proj, renderer=self.renderer.flag)

    def render(self, world_from_camera: np.ndarray, body: bool = True) -> RawFrame:
        """RGB, depth and (``body``) the body-id buffer; without it ``body`` is None and the
        render is cheaper (EGL draws the id buffer in a pass of its own: 465×366, 52 → 44 ms)."""
        W, H = self.intrinsics.width, self.intrinsics.height
        _, _, rgba, zbuf, seg = self.client.getCameraImage(
            W, H, view_matrix(world_from_camera), self._proj, renderer=self.renderer.flag,
            lightDirection=self.light_direction, shadow=0, flags=0 if body else pybullet.ER_NO_SEGMENTATION_MASK)
        rgba = np.asarray(rgba, dtype=np.uint8).reshape(H, W, 4)
        zbuf = np.asarray(zbuf, dtype=np.float32).reshape(H, W)
        ids = np.asarray(seg, dtype=np.int32).reshape(H, W) if body else None
        return RawFrame(np.ascontiguousarray(rgba[..., :3]), self.metric_depth(zbuf), ids)

    def metric_depth(self, zbuf: np.ndarray) -> np.ndarray:
        """Depth-buffer values in [0, 1] → z [m] along the optical axis (NaN beyond ``far``)."""
        n, f = np.float32(self.near), np.float32(self.clip_far)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = (f * n) / (f - (f - n) * zbuf)
        z[~(zbuf < 1.0) | ~(z <= np.float32(self.far))] = np.nan
        return z.astype(np.float32, copy=False)
