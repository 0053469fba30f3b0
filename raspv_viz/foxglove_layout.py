"""The shipped Foxglove layout, built with foxglove-sdk's layout types (no rclpy).

Left: the phosphene image over the camera's colour image. Middle: the 3-D scene in the world
frame ``map``, following ``base_link`` through the tf tree (/tf, /tf_static) — markers of planes,
obstacles, free floor, stairs, path and phosphenes (`viz` node), the slam node's keyframes,
landmarks and loop edges, the coloured depth cloud, the costmap. Right: latency (camera frame → display, age of the scene
result, ``/raspv/latency``), CPU (the machine and the foxglove process, ``/sysinfo``) and the
parameter panel (``/spv.mode`` & co.).

``python -m raspv_viz.foxglove_layout`` rewrites ``config/foxglove_layout.json`` (a test checks it
is up to date); in the Foxglove app: Layouts → Import from file.
"""
from __future__ import annotations

import json
import sys

from raspv_common import frames, shipped, topics
from raspv_common.extras import require

fl = require("foxglove.layouts", "the Foxglove layout (foxglove-sdk's layout types)")

LAYOUT_FILE = shipped.CONFIG_DIR / "foxglove_layout.json"
LATENCY = "/raspv/latency"
SYSINFO = "/sysinfo"
MARKER_TOPICS = (topics.VIZ_SCENE, topics.VIZ_STAIRS, topics.VIZ_PATH, topics.VIZ_PHOSPHENES)
SLAM_MARKER_TOPICS = (topics.SLAM_MARKERS,)


def image(topic: str, title: str) -> fl.ImagePanel:
    return fl.ImagePanel(title=title, config=fl.ImageConfig(image_mode=fl.ImageModeConfig(image_topic=topic)))


def scene_3d() -> fl.ThreeDeePanel:
    shown: dict = {t: fl.BaseRendererRosMarkerTopicSettings(visible=True) for t in MARKER_TOPICS}
    shown[topics.VIZ_CLOUD] = fl.BaseRendererPointCloudTopicSettings(visible=True, point_size=3.0, color_mode="rgb",
                                                                       color_field="rgb")
    shown[topics.NAV_COSTMAP] = fl.BaseRendererRosOccupancyGridTopicSettings(visible=True, color_mode="costmap")
    shown.update({t: fl.BaseRendererRosMarkerTopicSettings(visible=True) for t in SLAM_MARKER_TOPICS})
    return fl.ThreeDeePanel(title="scene (map frame, tf)",
                            config=fl.ThreeDeeConfig(follow_tf=frames.BASE_LINK, follow_mode="follow-position",
                                                     fixed_frame=frames.MAP, topics=shown))


def plot(title: str, series: list[tuple[str, str]]) -> fl.PlotPanel:
    return fl.PlotPanel(title=title, config=fl.PlotConfig(
        paths=[fl.PlotSeries(value=path, label=label) for path, label in series], show_legend=True))


def build_layout() -> fl.Layout:
    column = lambda *items: fl.SplitContainer(direction="column", items=[fl.SplitItem(content=i) for i in items])  # noqa: E731
    return fl.Layout(content=fl.SplitContainer(direction="row", items=[
        fl.SplitItem(proportion=1, content=column(image(topics.SPV_IMAGE, "phosphenes"),
                                                  image(topics.COLOR, "camera colour"))),
        fl.SplitItem(proportion=2, content=scene_3d()),
        fl.SplitItem(proportion=1, content=column(
            plot("latency [ms]", [(f"{LATENCY}.camera_to_display_ms", "camera frame → display"),
                                  (f"{LATENCY}.scene_age_ms", "age of the scene result")]),
            plot("CPU [%]", [(f"{SYSINFO}.total_cpu_percent", "machine"),
                             (f"{SYSINFO}.process_cpu_percent", "foxglove node")]),
            fl.ParametersPanel(title="parameters (e.g. /spv.mode)"))),
    ]))


def layout_json() -> str:
    """The layout as the shipped file holds it (indented, sorted keys, newline-terminated)."""
    return json.dumps(json.loads(build_layout().to_json()), indent=2, sort_keys=True, ensure_ascii=False) + "\n"


def main(argv: list[str] | None = None) -> int:
    LAYOUT_FILE.write_text(layout_json(), encoding="utf-8")
    print(f"wrote {LAYOUT_FILE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
