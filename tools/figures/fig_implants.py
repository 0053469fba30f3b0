#!/usr/bin/env python
"""Real implants with literature phosphene models: one scene of the sim ``apartment`` through
Argus II (axon map; also in edges mode, where a sparse pattern shows the streaks), Alpha-IMS,
PRIMA and Orion (cortical), RASPV next to pulse2percept 0.11 given the same electrode
amplitudes.

    .venv/bin/python tools/figures/fig_implants.py            # → docs/figures/fig_implants.png
    .venv/bin/python tools/figures/fig_implants.py --mode depth

For each device preset the scene (640×480, 60° camera) goes through the representation mode
(``grey``, the paper's downsampling, by default) exactly as in the ``spv`` node, giving one level per
electrode; RASPV draws it with the preset's precomputed sprites (temporal model off: one
frame). pulse2percept gets the same amplitudes (level / 7) on the same implant, placement and
field with the model the preset reproduces (``AxonMapModel``, retinal or cortical
``ScoreboardModel``), and its percept is resampled onto the phosphene image's pixels. Both are
scaled the same way: the whole array at full amplitude is white. The last column is one
electrode of each device alone, each scaled to its own peak, RASPV (green) over pulse2percept
(magenta): grey where they agree. The correlation of each pair is printed in the panel titles.
"""
from __future__ import annotations

import argparse
import math
import sys
import tempfile
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import cv2  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from raspv_sim.simulator import SimConfig, Simulation  # noqa: E402
from raspv_spv.config import spv_config  # noqa: E402
from raspv_spv.frame_inputs import FrameInputs  # noqa: E402
from raspv_spv.retinotopy import image_to_visual_field  # noqa: E402
from raspv_spv.simulator import PhospheneSimulator  # noqa: E402

CAMERA = SimConfig(width=640, height=480, hfov_deg=60.0)
VIEW = (8.0, 1.5, 1.2, 10.0)                         # the living room: x, y [m], yaw [rad], head pitch down [deg]
DEVICES = [("Argus II, axon map\n(rho 300 um, lambda 1000 um)", "argus_ii_axon"),
           ("Argus II, axon map, edges mode\n(a sparse pattern: streaks)", "argus_ii_axon:edges"),
           ("Alpha-IMS, 1500 px\n(scoreboard, rho 36 um)", "alpha_ims_implant"),
           ("PRIMA, 378 px\n(scoreboard, rho 50 um)", "prima"),
           ("Orion on V1\n(cortical scoreboard, rho 1.5 mm)", "orion")]
SIZE = 400
P2P_POINTS = 161


def render_scene():
    with Simulation("apartment", CAMERA) as sim:
        x, y, yaw, pitch = VIEW
        return sim.render_from(x, y, yaw, head_pitch=math.radians(pitch))


def reference_model(device: str, sim: PhospheneSimulator, tmp: str):
    """pulse2percept's model of the preset, on a grid over the phosphene image's field."""
    from pulse2percept.implants import DiskElectrode, ElectrodeArray
    from pulse2percept.implants.cortex import Orion
    from pulse2percept.implants.retina import PRIMA, AlphaIMS, ArgusII, RetinalImplant
    from pulse2percept.models.cortex import ScoreboardModel as CorticalScoreboard
    from pulse2percept.models.retina import AxonMapModel, ScoreboardModel

    d = sim.config.device
    half = math.degrees(math.atan(SIZE / 2 / sim.map.focal_px))
    grid = dict(xrange=(-half, half), yrange=(-half, half), step=2 * half / (P2P_POINTS - 1), verbose=False,
                n_threads=1)
    place = dict(implant_position=(d.implant_x_um, d.implant_y_um), implant_rotation=d.implant_rotation_deg)
    rho = sim.config.sprite_spec().rho(sim.map.target, sim.map)
    if device == "argus_ii_axon":
        model = AxonMapModel(ArgusII(), rho=d.rho_um, lam=d.axlambda_um, axon_pickle=f"{tmp}/axons.pickle", **grid, **place)
    elif device == "orion":
        model = CorticalScoreboard(Orion(), rho=rho, **grid, **place)
    elif device == "prima":
        # PRIMA takes light (mW/mm^2), not current: the same pixel positions as current-driven
        # electrodes, which the scoreboard sees identically
        prima = PRIMA()
        array = ElectrodeArray({n: DiskElectrode(e.x, e.y, 0, 10) for n, e in zip(prima.electrode_names,
                                                                                    prima.electrode_objects)})
        model = ScoreboardModel(RetinalImplant(array), rho=rho, **grid, **place)
    else:
        model = ScoreboardModel(AlphaIMS(), rho=rho, **grid, **place)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.build()
    return model


def reference_image(model, sim: PhospheneSimulator, amplitudes: np.ndarray, full: float | None = None):
    """pulse2percept's percept for per-electrode ``amplitudes`` (order of our map), resampled
    onto the phosphene image's pixels, and the all-on maximum it is scaled by."""
    from pulse2percept.stimuli import Stimulus

    names = list(sim.map.implant.names)
    all_names = [n for n in model.implant.electrode_names]
    stim = {n: float(a) for n, a in zip(names, amplitudes)}
    percept = model.predict_percept(Stimulus({n: stim.get(n, 0.0) for n in all_names})).data[..., 0]
    if full is None:
        full = float(model.predict_percept(Stimulus({n: (1.0 if n in stim else 0.0) for n in all_names})).data.max())
    gx, gy = model.spatial.grid.x, model.spatial.grid.y
    step = gx[0, 1] - gx[0, 0]
    u = np.arange(SIZE) + 0.5
    uu, vv = np.meshgrid(u, u)
    x, y = image_to_visual_field(uu, vv, sim.map.focal_px, SIZE / 2, SIZE / 2)
    cols = ((x - gx[0, 0]) / step).astype(np.float32)
    rows = ((gy[0, 0] - y) / step).astype(np.float32)
    img = cv2.remap(percept.astype(np.float32), cols, rows, cv2.INTER_LINEAR)
    return np.clip(img / full * 255.0, 0, 255), full


def draw_positions(rgb: np.ndarray, sim: PhospheneSimulator, camera) -> np.ndarray:
    """The scene with the point each electrode samples (its phosphene's direction)."""
    img = rgb.copy()
    s = sim.sampling(camera)
    for (u, v), inside in zip(s.uv, s.inside):
        if inside:
            cv2.circle(img, (int(round(u)), int(round(v))), 3, (255, 230, 0), -1, lineType=cv2.LINE_AA)
    return img


def corr(a, b) -> float:
    return float(np.corrcoef(np.ravel(a), np.ravel(b))[0, 1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mode", default="grey", help="representation mode (default grey)")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "figures" / "fig_implants.png")
    args = ap.parse_args(argv)
    frame = render_scene()
    inputs = FrameInputs(color=frame.rgb, depth=frame.depth, camera=frame.intrinsics)
    fig, axes = plt.subplots(len(DEVICES), 4, figsize=(13, 3.3 * len(DEVICES)))
    with tempfile.TemporaryDirectory() as tmp:
        for row, (title, entry) in enumerate(DEVICES):
            device, _, mode = entry.partition(":")
            mode = mode or args.mode
            sim = PhospheneSimulator(spv_config(device, width=SIZE, height=SIZE, temporal=False, mode=mode,
                                                mode_settings={"max_depth": 6.0, "edge_low": 50.0, "edge_high": 150.0}))
            levels = sim.levels(inputs)
            ours = sim.render(sim.brightness(levels)).astype(np.float32)
            model = reference_model(device, sim, tmp)
            theirs, full = reference_image(model, sim, levels / (sim.num_levels - 1))
            one = np.zeros(sim.count, np.uint8)
            pick = int(np.argmin(np.hypot(*(sim.map.centres - SIZE * np.array([0.4, 0.4])).T)))
            one[pick] = sim.num_levels - 1
            ours_one = sim.render(sim.brightness(one)).astype(np.float32)
            theirs_one, _ = reference_image(model, sim, one / (sim.num_levels - 1), full)
            a, b = theirs_one / max(1e-6, theirs_one.max()), ours_one / max(1e-6, ours_one.max())
            overlay = (255 * np.stack([a, b, a], axis=2)).astype(np.uint8)
            panels = [(draw_positions(frame.rgb, sim, frame.intrinsics), f"{title}\n{sim.count} electrodes"),
                      (ours, f"RASPV ({mode} mode)"), (theirs, f"pulse2percept, same amplitudes\n"
                                                                   f"r = {corr(ours, theirs):.3f}"),
                      (overlay, f"one electrode ({sim.map.implant.names[pick]}): RASPV green,\n"
                                f"pulse2percept magenta, r = {corr(ours_one, theirs_one):.3f}")]
            for ax, (img, label) in zip(axes[row], panels):
                ax.imshow(img, cmap="gray", vmin=0, vmax=255, interpolation="nearest")
                ax.set_title(label, fontsize=9)
                ax.set_xticks([])
                ax.set_yticks([])
            print(f"{device}: r = {corr(ours, theirs):.3f} (scene), {corr(ours_one, theirs_one):.3f} (one electrode)")
    fig.suptitle(f"The same apartment view through four implants: RASPV's precomputed sprites vs pulse2percept 0.11 "
                 f"({SIZE}x{SIZE} px)", fontsize=11)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=80)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
