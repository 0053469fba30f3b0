"""raspv topics / hz / echo / param against a running graph."""
import subprocess
import sys

import pytest
from sensor_msgs.msg import Image

from raspv_common import topics

pytestmark = pytest.mark.integration

SOURCE = {"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}]},
          "cam": {"ros__parameters": {"rate": 10.0, "width": 64, "height": 48}}}


def raspv(*args, timeout=60):
    return subprocess.run([sys.executable, "-m", "raspv_bringup.cli", *args], capture_output=True, text=True,
                          timeout=timeout)


def test_introspection_commands(graph, probe):
    graph(SOURCE)
    probe.wait_for_message(topics.COLOR, Image, timeout=60)
    out = raspv("topics", "-t")
    assert "/camera/color/image_raw  [sensor_msgs/msg/Image]" in out.stdout, out
    hz = raspv("hz", topics.COLOR, "--duration", "3")
    assert hz.returncode == 0
    rates = [float(x.split()[2]) for x in hz.stdout.splitlines() if x.startswith("average rate")]
    assert rates and 5.0 < rates[-1] < 15.0, hz.stdout
    echo = raspv("echo", topics.CAMERA_INFO, "--once")
    assert "width: 64" in echo.stdout and "k: [" in echo.stdout, echo.stdout
    assert raspv("param", "get", "cam", "width").stdout.strip() == "64"
    bad = raspv("param", "set", "cam", "walk_speed", "99")
    assert bad.returncode == 1 and "refused" in bad.stderr
    good = raspv("param", "set", "cam", "walk_speed", "1")
    assert good.returncode == 0, good.stderr
    assert raspv("param", "get", "cam", "walk_speed").stdout.strip() == "1.0"
    unknown = raspv("param", "get", "cam", "nonsense")
    assert unknown.returncode == 1 and "has no parameter 'nonsense'" in unknown.stderr


def test_tools_report_missing_topics_and_nodes_clearly():
    res = raspv("echo", "/nothing/here", "--wait", "1")
    assert res.returncode == 1 and "did not appear" in res.stderr and "Traceback" not in res.stderr
    res = raspv("param", "get", "ghost_node", "x", "--timeout", "1")
    assert res.returncode == 1 and "not running" in res.stderr
