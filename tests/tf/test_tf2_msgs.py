"""tf2_msgs/TFMessage built into the venv (tools/install.sh) has upstream ROS 2 Jazzy's type hash.

The hash (RIHS01, REP 2011) is what a system ROS 2 announces for /tf and /tf_static and matches
publishers to subscribers by; a definition that differed in any field name or type would give
another one and RViz, Foxglove or a tf2 listener would not take our transforms. Three sources
that do not depend on each other agree:
- UPSTREAM: the value ROS 2 Jazzy/Rolling nodes announce for tf2_msgs::msg::dds_::TFMessage_
  (rmw_zenoh key expressions in published ROS 2 code, beside sensor_msgs/PointCloud2's
  RIHS01_9198cabf…, which the PyPI Jazzy wheel here generates too: same generator, same hash);
- the JSON the rosidl type-description generator wrote into ``<venv>/share/tf2_msgs/msg``;
- rosbags' ROS 2 Jazzy typestore, its own copy of upstream's definitions hashed by its own code.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from rosbags.typesys import Stores, get_typestore

UPSTREAM = "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087"
POINTCLOUD2_UPSTREAM = "RIHS01_9198cabf7da3796ae6fe19c4cb3bdd3525492988c70522628af5daa124bae2b5"
ROOT = Path(__file__).resolve().parents[2]


def generated_hash(package: str, name: str) -> str:
    doc = json.loads((Path(sys.prefix) / "share" / package / "msg" / f"{name}.json").read_text())
    return next(h["hash_string"] for h in doc["type_hashes"] if h["type_name"] == f"{package}/msg/{name}")


def test_the_generated_type_hash_is_upstreams():
    assert generated_hash("sensor_msgs", "PointCloud2") == POINTCLOUD2_UPSTREAM     # the reference is Jazzy's
    assert generated_hash("tf2_msgs", "TFMessage") == UPSTREAM
    assert get_typestore(Stores.ROS2_JAZZY).hash_rihs01("tf2_msgs/msg/TFMessage") == UPSTREAM


def test_the_definition_and_package_are_upstreams():
    store = get_typestore(Stores.ROS2_JAZZY)
    upstream_text = store.generate_msgdef("tf2_msgs/msg/TFMessage", ros_version=2)[0].split("\n=====")[0]
    assert (ROOT / "tf2_msgs" / "msg" / "TFMessage.msg").read_text().strip() == upstream_text.strip()
    assert "<name>tf2_msgs</name>" in (ROOT / "tf2_msgs" / "package.xml").read_text()
    from tf2_msgs.msg import TFMessage          # the runtime the nodes publish with
    assert TFMessage.get_fields_and_field_types() == {"transforms": "sequence<geometry_msgs/TransformStamped>"}
