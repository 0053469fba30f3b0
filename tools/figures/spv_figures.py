#!/usr/bin/env python
"""Figures of the phosphene model (the paper's Figs. 5/6, 16, 17, 18, 19 and the basic modes).

    .venv/bin/python tools/figures/spv_figures.py            # all figures
    .venv/bin/python tools/figures/spv_figures.py maps fov   # some of them

PNGs go to docs/figures/ (``--out`` to change). Everything is drawn by the same simulator
the ``spv`` node runs (:mod:`raspv_spv.simulator`); real frames come from tests/data/rgbd.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from raspv_common.intrinsics import CameraIntrinsics  # noqa: E402
from raspv_common.rgbd_files import read_color, read_depth_scaled, read_nyu_disparity  # noqa: E402
from raspv_spv.config import spv_config  # noqa: E402
from raspv_spv.frame_inputs import FrameInputs  # noqa: E402
from raspv_spv.simulator import PhospheneSimulator  # noqa: E402
from raspv_spv.sprites import GaussianSprite  # noqa: E402
from raspv_spv.temporal import (Horsager2009, Nanduri2012, current_on_grid,  # noqa: E402
                                pulse_train_breakpoints)
from raspv_spv.temporal_lut import TemporalLUTConfig, load_table  # noqa: E402

DATA = ROOT / "tests" / "data" / "rgbd"
PRIMESENSE = CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)


def all_on(device: str, **settings) -> tuple[np.ndarray, PhospheneSimulator]:
    """Phosphene image with every phosphene at full level."""
    sim = PhospheneSimulator(spv_config(device, temporal=False, **settings))
    return sim.render(np.ones(sim.count, np.float32)), sim


def show(ax, img, title):
    ax.imshow(img, cmap="gray", vmin=0, vmax=255, interpolation="nearest")
    ax.set_title(title, fontsize=9)
    ax.set_xticks([])
    ax.set_yticks([])


def fig_sprites(out: Path) -> Path:
    """Fig. 16: the N_L = 8 sprites S_i = i/7 S_r of the default preset."""
    sprite = GaussianSprite(2 * 2268.5 * math.tan(math.radians(0.25)))
    r = int(sprite.radius_px) + 2
    yy, xx = np.mgrid[-r:r + 1, -r:r + 1].astype(float)
    ref = sprite.weights(xx, yy)
    fig, axes = plt.subplots(1, 8, figsize=(12, 2))
    for i, ax in enumerate(axes):
        show(ax, np.rint(ref * 255 * i / 7), f"S{i}" + (" = Sr" if i == 7 else ""))
    fig.suptitle(f"Phosphene sprites, default preset: {sprite.size_px} px drawn, sigma {sprite.sigma_px:.2f} px, "
                 f"0.01 at the border (paper Fig. 16)", fontsize=10)
    return save(fig, out / "fig16_sprites.png")


def fig_maps(out: Path) -> Path:
    """Fig. 17: maps for Argus II (60) and Alpha-IMS (1500)."""
    fig, axes = plt.subplots(2, 4, figsize=(14, 8.6))
    for row, device in enumerate(("argus_ii", "alpha_ims")):
        cases = [("(a) rectangular map", dict(grid="rectangular")),
                 ("(b) hexagonal map", dict(grid="hexagonal")),
                 ("(c) rectangular visual field", dict(grid="hexagonal", height=800)),
                 ("(d) circular visual field", dict(grid="hexagonal", height=800, field="circular"))]
        for col, (title, settings) in enumerate(cases):
            img, sim = all_on(device, **settings)
            show(axes[row, col], img, f"{device} {title}\n{sim.count} phosphenes, "
                                      f"dx={sim.map.spacing_x} dy={sim.map.spacing_y} px, {img.shape[1]}x{img.shape[0]}")
    fig.suptitle("Phosphene maps (paper Fig. 17): Argus II, N=60 (top); Alpha-IMS, N=1500 (bottom)", fontsize=11)
    return save(fig, out / "fig17_maps.png")


def fig_defects(out: Path) -> Path:
    """Fig. 18: dropout and position noise (default preset)."""
    cases = [("(a) dropout d = 0.2", dict(dropout=0.2)), ("(b) noise sigma = 5 px", dict(noise_px=5.0)),
             ("(c) d = 0.4, sigma = 10 px", dict(dropout=0.4, noise_px=10.0))]
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.8))
    for ax, (title, settings) in zip(axes, cases):
        img, sim = all_on("default", seed=1, **settings)
        show(ax, img, f"{title}\n{int(sim.map.dropped.sum())} of {sim.count} dropped")
    fig.suptitle("Map defects, applied to the display only (paper Fig. 18); seed 1", fontsize=11)
    return save(fig, out / "fig18_defects.png")


def tum_frame():
    color = read_color(DATA / "tum_color.png")
    depth = read_depth_scaled(DATA / "tum_depth.png", 1 / 5000)
    return color, depth, PRIMESENSE


def nyu_frame():
    return read_color(DATA / "nyu_color.ppm"), read_nyu_disparity(DATA / "nyu_depth.pgm"), PRIMESENSE


def fig_fov(out: Path) -> Path:
    """Fig. 19: field of view and phosphene size on a real frame (grey mode)."""
    color, depth, cam = tum_frame()
    cases = [(10.0, 0.5), (20.0, 1.0), (30.0, 1.0), (30.0, 2.0)]
    fig, axes = plt.subplots(2, 4, figsize=(15, 7.4))
    for col, (fov, size) in enumerate(cases):
        sim = PhospheneSimulator(spv_config("default", fov_deg=fov, phosphene_fov_deg=size, temporal=False))
        frame = sim.step(FrameInputs(color=color, camera=cam))
        s = sim.sampling(cam)
        ax = axes[0, col]
        ax.imshow(color)
        ax.plot(s.uv[s.inside, 0], s.uv[s.inside, 1], ".", color="lime", ms=0.8, alpha=0.5)
        corners = np.array([[0, 0], [800, 0], [800, 800], [0, 800], [0, 0]], float)
        rays = np.c_[(corners - 400) / sim.map.focal_px, np.ones(5)]
        u, v, _ = cam.project(rays)
        ax.plot(u, v, "-", color="lime", lw=1.2)
        ax.set_title(f"({'abcd'[col]}) FOV = {fov:g} deg, FOV_P = {size:g} deg\n"
                     f"camera {cam.hfov_deg:.0f}x{cam.vfov_deg:.0f} deg, phosphene rays in green", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
        show(axes[1, col], frame.image, f"downsampling, {sim.count} phosphenes, diameter {sim.map.diameter_px:.1f} px")
    fig.suptitle("Field of view and phosphene size (paper Fig. 19) on a real RGB-D frame (TUM desk, PrimeSense)",
                 fontsize=11)
    return save(fig, out / "fig19_fov_size.png")


def fig_temporal_response(out: Path) -> Path:
    """Fig. 5 equivalent: the continuous models' response to one pulse and to a pulse train, and
    the discretised model (look-up table) frame by frame."""
    dt = 1.0 / 128
    cfg = TemporalLUTConfig()
    t_end = 400.0
    n = int(t_end / dt)
    t = np.arange(n) * dt
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.4))
    for ax, (title, onsets) in zip(axes, [("one pulse at t = 0", [0.0]),
                                         ("a pulse every 20 ms frame for 100 ms", np.arange(0.0, 100.0, 20.0))]):
        times, values = pulse_train_breakpoints(onsets, cfg.pulse)
        current = current_on_grid(times, values, dt, n)
        for model, style in ((Horsager2009(dt=dt), "-"), (Nanduri2012(dt=dt), "--")):
            r = model.response(current)
            ax.plot(t, r / r.max(), style, label=f"{model.name} (continuous, normalised)")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("time [ms]")
        ax.set_ylabel("brightness")
    table = load_table(cfg)
    frames = np.arange(20)
    for ax, pulses in zip(axes, [[0], list(range(5))]):
        history, lut = 0, []
        for k in frames:
            history = ((history << 1) | int(k in pulses)) & 1023
            lut.append(table[history])
        scale = 1.0 / max(lut)
        ax.step(frames * cfg.frame_ms, np.array(lut) * scale, where="post", color="k",
                label=f"look-up table, mean over each {cfg.frame_ms:g} ms frame (x{scale:.1f})")
        ax.legend(fontsize=8)
    fig.suptitle(f"Temporal model (paper Fig. 5): biphasic pulses {cfg.pulse_amplitude_ua:g} uA, "
                 f"{cfg.pulse_phase_ms:g} ms per phase - fast rise, slow decay", fontsize=11)
    return save(fig, out / "fig05_temporal_response.png")


def fig_moving_bar(out: Path) -> Path:
    """Fig. 6 equivalent: a bright bar moving to the right, without and with the temporal model,
    and the brightness of the phosphenes of the middle row."""
    cam = CameraIntrinsics.from_hfov(640, 480, 60.0)
    still = PhospheneSimulator(spv_config("optimist", temporal=False))
    moving = PhospheneSimulator(spv_config("optimist", temporal=True))
    centres = still.map.centres
    row = np.abs(centres[:, 1] - centres[np.argmin(np.abs(centres[:, 1] - 400)), 1]) < 1e-6
    order = np.argsort(centres[row, 0])
    speed, width = 8, 60                                         # camera px per 20 ms frame, bar width px
    shown = [4, 12, 20, 28]
    fig, axes = plt.subplots(3, len(shown), figsize=(14, 10.5))
    col = 0
    for k in range(shown[-1] + 1):
        img = np.zeros((480, 640, 3), np.uint8)
        x0 = 150 + speed * k
        img[100:380, x0:x0 + width] = 255
        inputs = FrameInputs(color=img, camera=cam)
        a = still.step(inputs)
        b = moving.step(inputs)
        if k in shown:
            show(axes[0, col], a.image, f"frame {k} ({k * 20} ms): no temporal model")
            show(axes[1, col], b.image, f"frame {k}: discretised Horsager 2009 model")
            x = centres[row, 0][order]
            axes[2, col].plot(x, a.brightness[row][order], "o-", ms=3, label="no temporal model")
            axes[2, col].plot(x, b.brightness[row][order], "s-", ms=3, label="temporal model")
            axes[2, col].set_ylim(-0.05, 1.05)
            axes[2, col].set_xlabel("phosphene x [px], middle row")
            axes[2, col].set_ylabel("brightness")
            axes[2, col].legend(fontsize=8, loc="upper left")
            col += 1
    fig.suptitle(f"A bar moving right, {speed} camera px per 20 ms frame (paper Fig. 6), optimist preset: with the "
                 "temporal model the bar lights up over a few frames and leaves a fading trail", fontsize=11)
    return save(fig, out / "fig06_moving_bar.png")


def fig_modes(out: Path) -> Path:
    """The basic representation modes on two real RGB-D frames (optimist preset)."""
    frames = [("TUM desk", tum_frame()), ("NYU basement", nyu_frame())]
    modes = ["grey", "depth", "edges", "edges_depth"]
    fig, axes = plt.subplots(2, 5, figsize=(17, 6.8))
    for row, (name, (color, depth, cam)) in enumerate(frames):
        axes[row, 0].imshow(color)
        axes[row, 0].set_title(f"{name} (real RGB-D)", fontsize=9)
        axes[row, 0].axis("off")
        for col, mode in enumerate(modes, start=1):
            sim = PhospheneSimulator(spv_config("optimist", mode=mode, temporal=False,
                                                mode_settings={"max_depth": 5.0}))
            show(axes[row, col], sim.step(FrameInputs(color=color, depth=depth, camera=cam)).image,
                 f"{mode}" + (" (max depth 5 m)" if "depth" in mode else ""))
    fig.suptitle("Basic representation modes, optimist preset (1000 hexagonal phosphenes, 45 deg)", fontsize=11)
    return save(fig, out / "modes.png")


def save(fig, path: Path) -> Path:
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


FIGURES = {"sprites": fig_sprites, "maps": fig_maps, "defects": fig_defects, "fov": fig_fov,
           "temporal": fig_temporal_response, "moving_bar": fig_moving_bar, "modes": fig_modes}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("names", nargs="*", help=f"figures to draw: {', '.join(FIGURES)} (default all)")
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "figures")
    args = p.parse_args(argv)
    unknown = [n for n in args.names if n not in FIGURES]
    if unknown:
        p.error(f"unknown figure(s) {', '.join(unknown)}; known: {', '.join(FIGURES)}")
    args.out.mkdir(parents=True, exist_ok=True)
    for name in args.names or FIGURES:
        print(FIGURES[name](args.out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
