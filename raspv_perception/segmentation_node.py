"""`segmentation` node: colour → ``/segmentation/labels`` (class ids, the colour image's size and
stamp) and, latched, ``/segmentation/classes`` (``raspv_msgs/ClassNames``).

Backends (parameter ``backend``): ``person`` (shipped MediaPipe selfie model, with depth fusion
from ``/scene/labels`` + depth when ``depth_fusion`` is on), ``onnx``/``torchscript`` (a model
file with its YAML), ``sim`` (relays the virtual world's ``/sim/labels`` and names its
``/sim/classes``). Networks run in a worker thread on the newest colour frame, so a slow model
skips frames but never delays the graph; each label image carries the stamp of the colour frame
it was computed from. A model that cannot be used stops the node with one line at start-up.
"""
from __future__ import annotations

import json
import threading
import time
from collections import deque

import numpy as np
from raspv_msgs.msg import ClassNames
from sensor_msgs.msg import Image
from std_msgs.msg import String

from raspv_common import topics
from raspv_common.conversions import ImageEncodingError, array_to_image, image_to_array, rgb_from_image, stamp_to_seconds
from raspv_common.node import ConfigurationError, RaspvNode, run_node
from raspv_common.qos import LATCHED_QOS, SENSOR_QOS
from raspv_common.shutdown_errors import SHUTDOWN_ERRORS, during_shutdown
from raspv_perception.class_table import ClassTable
from raspv_perception.model_spec import ModelError
from raspv_perception.person_fusion import FusionConfig
from raspv_perception.segmentation import Segmenter
from raspv_perception.segmentation_models import load_model
from raspv_perception.segmentation_msg import classes_to_msg
from raspv_perception.segmentation_params import PARAMS



def fusion_config(p: dict) -> FusionConfig:
    return FusionConfig(threshold=p["threshold"], cluster_support=p["cluster_support"], min_area=p["min_area"],
                        depth_jump=p["depth_jump"], keep_without_depth=p["keep_without_depth"])


def closest(buffer, stamp: float, max_age: float):
    """The (stamp, value) of ``buffer`` closest to ``stamp`` within ``max_age`` s, or None."""
    best = min(buffer, key=lambda sv: abs(sv[0] - stamp), default=None)
    return best if best is not None and abs(best[0] - stamp) <= max_age + 1e-9 else None


class SegmentationNode(RaspvNode):
    def __init__(self) -> None:
        super().__init__("segmentation", PARAMS)
        p = self.params
        self.pub_labels = self.create_publisher(Image, topics.SEGMENTATION_LABELS, SENSOR_QOS)
        self.pub_classes = self.create_publisher(ClassNames, topics.SEGMENTATION_CLASSES, LATCHED_QOS)
        self.frames = self.skipped = 0
        self.model_ms: deque[float] = deque(maxlen=200)
        if p["backend"] == "sim":
            self.segmenter = None
            self.create_subscription(String, topics.SIM_CLASSES, self.on_sim_classes, LATCHED_QOS)
            self.create_subscription(Image, topics.SIM_LABELS, self.on_sim_labels, SENSOR_QOS)
            self.get_logger().info("backend sim: relaying the virtual world's labels")
            return
        try:
            model = load_model(p["backend"], p["model"], p["labels"], p["threshold"], p["threads"])
            self.segmenter = Segmenter(model, fusion_config(p) if p["depth_fusion"] else None)
        except (ModelError, ValueError) as exc:
            raise ConfigurationError(str(exc)) from None
        self.publish_classes(self.segmenter.classes, p["backend"], str(model.path))
        self._lock = threading.Condition()
        self._color: tuple[float, object, np.ndarray] | None = None     # (stamp, header, rgb) newest unprocessed
        self._scene: deque[tuple[float, np.ndarray]] = deque(maxlen=8)
        self._depth: deque[tuple[float, np.ndarray]] = deque(maxlen=8)
        self.create_subscription(Image, topics.COLOR, self.on_color, SENSOR_QOS)
        if self.segmenter.is_person:
            self.create_subscription(Image, topics.SCENE_LABELS, self.on_scene_labels, SENSOR_QOS)
            self.create_subscription(Image, topics.DEPTH, self.on_depth, SENSOR_QOS)
        self._stop = threading.Event()
        self._worker = threading.Thread(target=self._work, name="segmentation", daemon=True)
        self._worker.start()
        self.get_logger().info(self.segmenter.model.describe()
                               + (f"; depth fusion {'on' if p['depth_fusion'] else 'off'}" if self.segmenter.is_person else ""))

    # -- parameters -------------------------------------------------------------------------------
    def on_parameters(self, changes):
        if self.segmenter is None:
            return None
        merged = {**self.params, **changes}
        try:
            fusion = fusion_config(merged)
        except ValueError as exc:
            return str(exc)
        self.segmenter.fusion = fusion
        self.segmenter.use_depth = merged["depth_fusion"]
        return None

    def publish_classes(self, table: ClassTable, backend: str, model: str) -> None:
        self.pub_classes.publish(classes_to_msg(table, self.header(""), backend, model))

    # -- sim backend --------------------------------------------------------------------------------
    def on_sim_classes(self, msg: String) -> None:
        try:
            doc = json.loads(msg.data)
            table = ClassTable.for_world(doc["classes"])
        except (ValueError, KeyError, TypeError) as exc:
            self.warn_throttled("classes", f"ignoring {topics.SIM_CLASSES}: {exc}")
            return
        self.publish_classes(table, "sim", str(doc.get("world", "")))

    def on_sim_labels(self, msg: Image) -> None:
        if msg.encoding not in ("mono8", "8UC1"):
            self.warn_throttled("labels", f"ignoring {topics.SIM_LABELS}: expected mono8, got {msg.encoding!r}")
            return
        msg.encoding = "mono8"
        self.pub_labels.publish(msg)
        self.frames += 1

    # -- network backends ---------------------------------------------------------------------------
    def on_color(self, msg: Image) -> None:
        try:
            rgb = rgb_from_image(msg)
        except ImageEncodingError as exc:
            self.warn_throttled("color", f"ignoring colour image on {topics.COLOR}: {exc}")
            return
        with self._lock:
            if self._color is not None:
                self.skipped += 1                    # the model is busy: the newest frame wins
            self._color = (stamp_to_seconds(msg.header.stamp), msg.header, rgb)
            self._lock.notify_all()

    def on_scene_labels(self, msg: Image) -> None:
        if msg.encoding not in ("mono8", "8UC1"):
            self.warn_throttled("scene", f"ignoring {topics.SCENE_LABELS}: expected mono8, got {msg.encoding!r}")
            return
        with self._lock:
            self._scene.append((stamp_to_seconds(msg.header.stamp), image_to_array(msg)))
            self._lock.notify_all()

    def on_depth(self, msg: Image) -> None:
        depth = self.read_depth(msg)
        if depth is not None:
            with self._lock:
                self._depth.append((stamp_to_seconds(msg.header.stamp), depth))

    def _scene_for(self, stamp: float) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Scene labels (and their depth) for a colour stamp: wait up to ``scene_max_age`` for
        labels at or after it, then take the closest within that age (caller holds the lock)."""
        max_age = self.params["scene_max_age"]
        deadline = time.monotonic() + max_age
        while not self._stop.is_set():
            newest = self._scene[-1][0] if self._scene else -np.inf
            remaining = deadline - time.monotonic()
            if newest >= stamp - 1e-9 or remaining <= 0:
                break
            self._lock.wait(remaining)
        scene = closest(self._scene, stamp, max_age)
        if scene is None:
            return None, None
        depth = closest(self._depth, scene[0], 1e-6)
        return scene[1], (None if depth is None else depth[1])

    def _work(self) -> None:
        while not self._stop.is_set():
            with self._lock:
                while self._color is None and not self._stop.is_set():
                    self._lock.wait(0.5)
                if self._stop.is_set():
                    return
                stamp, header, rgb = self._color
                self._color = None
            seg = self.segmenter
            scene = depth = None
            if seg.is_person and seg.use_depth:
                with self._lock:
                    scene, depth = self._scene_for(stamp)
                if scene is None:
                    self.warn_throttled("no-scene", f"no {topics.SCENE_LABELS} within {self.params['scene_max_age']} s "
                                                    "of the colour frame (is a scene node running?): publishing the "
                                                    "network's mask without depth fusion", 10.0)
                elif depth is not None and depth.shape != scene.shape:
                    depth = None
            try:
                result = seg.segment(rgb, scene, depth)
            except ValueError as exc:
                self.warn_throttled("segment", f"cannot segment this frame: {exc}")
                continue
            self.model_ms.append(result.timings.get("model", 0.0))
            encoding = "mono8" if result.labels.dtype == np.uint8 else "mono16"
            if not self.context.ok():
                return
            try:
                self.pub_labels.publish(array_to_image(result.labels, encoding, header))
            except SHUTDOWN_ERRORS as exc:          # the context can end while publishing at shutdown
                if not during_shutdown(exc, self.context):
                    raise
                return
            self.frames += 1

    def close(self) -> None:
        stop = getattr(self, "_stop", None)
        if stop is not None:
            stop.set()
            with self._lock:
                self._lock.notify_all()
            self._worker.join(timeout=2.0)
        model = f", model median {float(np.median(self.model_ms)):.1f} ms" if getattr(self, "model_ms", None) else ""
        print(f"segmentation: {self.frames} label images published, {self.skipped} colour frames skipped "
              f"(model busy){model}", flush=True)


def main(argv=None) -> None:
    run_node(SegmentationNode, argv, priority="perception")


if __name__ == "__main__":
    main()
