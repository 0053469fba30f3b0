"""The shipped Foxglove layout and RViz config: up to date with their generator and showing
the topics the graph publishes (markers, cloud, phosphene image, costmap, latency, CPU)."""
from __future__ import annotations

import json

import yaml

from raspv_bringup.testing import dev_requirement
from raspv_common import shipped, topics

VIZ_TOPICS = {topics.VIZ_SCENE, topics.VIZ_STAIRS, topics.VIZ_PATH, topics.VIZ_PHOSPHENES, topics.VIZ_CLOUD}
GRAPH_TOPICS = {v for k, v in vars(topics).items() if k.isupper() and isinstance(v, str)}


def _walk(node):
    if isinstance(node, dict):
        yield node
        for v in node.values():
            yield from _walk(v)
    elif isinstance(node, list):
        for v in node:
            yield from _walk(v)


def test_foxglove_layout_is_up_to_date_and_names_real_topics():
    dev_requirement("foxglove", "foxglove-sdk")   # the foxglove extra
    from raspv_viz.foxglove_layout import LATENCY, LAYOUT_FILE, SYSINFO, layout_json

    assert LAYOUT_FILE.read_text() == layout_json(), "run: python -m raspv_viz.foxglove_layout"
    layout = json.loads(LAYOUT_FILE.read_text())
    panels = [n for n in _walk(layout) if n.get("type") == "panel"]
    kinds = {p["panelType"] for p in panels}
    assert {"Image", "ThreeDee", "Plot", "Parameters"} <= kinds
    images = {p["config"]["imageMode"]["imageTopic"] for p in panels if p["panelType"] == "Image"}
    assert images == {topics.SPV_IMAGE, topics.COLOR}
    [scene] = [p for p in panels if p["panelType"] == "ThreeDee"]
    assert (scene["config"]["followTf"], scene["config"]["fixedFrame"]) == ("base_link", "map")
    assert set(scene["config"]["topics"]) == VIZ_TOPICS | {topics.NAV_COSTMAP, topics.SLAM_MARKERS}
    plotted = {s["value"].split(".")[0] for p in panels if p["panelType"] == "Plot" for s in p["config"]["paths"]}
    assert plotted == {LATENCY, SYSINFO}
    assert (images | set(scene["config"]["topics"])) <= GRAPH_TOPICS


def test_rviz_config_shows_every_viz_topic_and_the_tf_tree_in_the_map_frame():
    doc = yaml.safe_load((shipped.CONFIG_DIR / "raspv.rviz").read_text())
    manager = doc["Visualization Manager"]
    assert manager["Global Options"]["Fixed Frame"] == "map"
    assert "rviz_default_plugins/TF" in {d["Class"] for d in manager["Displays"]}
    shown = {d["Topic"]["Value"]: d["Class"] for d in manager["Displays"] if "Topic" in d}
    assert VIZ_TOPICS <= set(shown) and set(shown) <= GRAPH_TOPICS
    assert shown[topics.VIZ_CLOUD] == "rviz_default_plugins/PointCloud2"
    assert all(shown[t] == "rviz_default_plugins/MarkerArray" for t in VIZ_TOPICS - {topics.VIZ_CLOUD} | {topics.SLAM_MARKERS})
