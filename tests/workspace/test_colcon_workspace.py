"""The repository as a ROS 2 workspace: colcon (from PyPI) builds every package into a temporary
directory, the ament index lists them, every node kind has its `ros2 run` executable
(lib/<package>/<kind>), and a node started from the install publishes its topic.

The message packages (raspv_msgs, tf2_msgs: ament_cmake, C and C++ type support) are taken from
the venv as an underlay, where `make install` built them from the same CMakeLists with cmake:
compiling them again here cost 2 min quiet and several under load, for a build the install
already checks."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from sensor_msgs.msg import Image

from raspv_bringup.colcon_workspace import REPO_ROOT, check, describe, package_names
from raspv_bringup.registry import NODES
from raspv_common import topics

VENV = Path(sys.prefix)
MESSAGE_PACKAGES = ("raspv_msgs",)   # built into the venv by make install (tools/install.sh); tf2_msgs has COLCON_IGNORE


def test_colcon_descriptions_are_up_to_date_with_the_code():
    assert check() == [], "run: python -m raspv_bringup.colcon_workspace"


def test_package_dependencies_follow_the_imports():
    spv = describe("raspv_spv")
    assert {"raspv_common", "raspv_msgs", "raspv_perception"} <= set(spv.raspv_deps)
    assert {"rclpy", "sensor_msgs"} <= set(spv.ros_deps) and "python3-numpy" in spv.rosdep_keys
    assert describe("raspv_common").raspv_deps == []                       # the bottom of the stack
    assert "foxglove-sdk" in describe("raspv_viz").pip_only
    # every node kind is some package's executable
    assert {k for n in package_names() for k in describe(n).executables} == set(NODES)


def test_package_dependencies_have_no_cycle():
    """colcon orders packages topologically and refuses a cycle (the slow build below would
    fail on it): a cycle is named here in a second."""
    deps = {n: set(describe(n).raspv_deps) for n in package_names()}
    state: dict[str, str] = {}

    def visit(name: str, path: list[str]) -> None:
        if state.get(name) == "done":
            return
        assert state.get(name) != "open", "package cycle: " + " -> ".join(path[path.index(name):] + [name])
        state[name] = "open"
        for dep in sorted(deps.get(name, ())):
            visit(dep, path + [name])
        state[name] = "done"

    for name in sorted(deps):
        visit(name, [])


def colcon_env() -> dict[str, str]:
    """The venv's ROS (ament, rosidl, cmake modules) for building raspv_msgs, as tools/install.sh.
    MAKEFLAGS: colcon-cmake otherwise adds ``-l<cores>``, and make then runs one job at a time
    whenever the machine's load average is above the core count."""
    return {**os.environ, "AMENT_PREFIX_PATH": str(VENV), "CMAKE_PREFIX_PATH": str(VENV),
            "PATH": f"{VENV / 'bin'}:{os.environ['PATH']}", "MAKEFLAGS": f"-j{os.cpu_count() or 2}"}


def sourced(install: Path) -> dict[str, str]:
    """The environment after `. install/setup.sh` (what a user's shell has)."""
    out = subprocess.run(["sh", "-c", f". '{install}/setup.sh' && env -0"], capture_output=True, check=True,
                         env=os.environ.copy(), timeout=120).stdout
    return dict(item.split("=", 1) for item in out.decode().split("\0") if "=" in item)


@pytest.mark.integration
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_colcon_build_of_the_repository(tmp_path, probe):
    ws = tmp_path / "ws"
    build = subprocess.run(
        [str(VENV / "bin" / "colcon"), "--log-base", str(ws / "log"), "build", "--base-paths", str(REPO_ROOT),
         "--build-base", str(ws / "build"), "--install-base", str(ws / "install"), "--event-handlers", "console_direct-",
         "--packages-ignore", *MESSAGE_PACKAGES,
         "--cmake-args", f"-DPython3_EXECUTABLE={sys.executable}", "-DBUILD_TESTING=OFF", "-DCMAKE_BUILD_TYPE=Release"],
        cwd=tmp_path, env=colcon_env(), capture_output=True, text=True, timeout=800)
    assert build.returncode == 0, build.stdout[-4000:] + build.stderr[-4000:]
    install = ws / "install"
    expected = set(package_names())
    finished = {line.split()[2] for line in build.stdout.splitlines() if line.startswith("Finished <<< ")}
    assert finished == expected, build.stdout[-3000:]

    env = sourced(install)
    index = subprocess.run([sys.executable, "-c", "from ament_index_python.packages import get_packages_with_prefixes as g;"
                            "print('\\n'.join(f'{k} {v}' for k, v in sorted(g().items())))"],
                           env=env, cwd=tmp_path, capture_output=True, text=True, check=True, timeout=120).stdout.split("\n")
    listed = dict(line.split(" ", 1) for line in index if line)
    assert {p: Path(listed.get(p, "")) for p in expected} == {p: install / p for p in expected}
    for kind, spec in NODES.items():                                    # what `ros2 run PKG KIND` runs
        package = spec.module.split(".")[0]
        assert os.access(install / package / "lib" / package / kind, os.X_OK), f"no executable for {kind}"
    assert (install / "raspv_bringup" / "share" / "raspv_bringup" / "launch" / "demo.launch.py").is_file()
    assert (install / "raspv_viz" / "share" / "raspv_viz" / "config" / "raspv.rviz").is_file()

    # the packages now import from the install, config/ beside them included (cwd: not the repository)
    where = subprocess.run([sys.executable, "-c", "import raspv_camera, raspv_msgs.msg, raspv_spv.device as d;"
                            "print(raspv_camera.__file__, raspv_msgs.msg.__file__, d.DEVICES_DIR.is_dir())"],
                           env=env, cwd=tmp_path, capture_output=True, text=True, check=True, timeout=120).stdout.split()
    assert where[0].startswith(str(install / "raspv_camera")) and where[1].startswith(str(VENV))   # the underlay
    assert where[2] == "True"

    node = subprocess.Popen([str(install / "raspv_camera" / "lib" / "raspv_camera" / "synthetic"),
                             "--ros-args", "-p", "rate:=5.0", "-p", "width:=160", "-p", "height:=120"],
                            env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            start_new_session=True)
    try:
        msg = probe.wait_for_message(topics.COLOR, Image, timeout=120)
        assert (msg.width, msg.height) == (160, 120)
    finally:
        node.send_signal(signal.SIGINT)
        try:
            node.wait(30)
        except subprocess.TimeoutExpired:
            node.kill()
            node.wait()


def test_the_recipe_counts_the_packages_and_keeps_colcon_logs_out_of_the_repository():
    """Issue 36: docs/DEVELOPING.md said 11 ament_python packages, and its in-repository colcon
    build left a `log/` folder that git did not ignore."""
    import re

    text = (REPO_ROOT / "docs" / "DEVELOPING.md").read_text()
    count = re.search(r"raspv_msgs \(ament_cmake\) \+ (\d+) ament_python packages", text)
    assert count and int(count.group(1)) == len(package_names()), (count, package_names())
    in_repository = [line for line in text.splitlines() if "colcon" in line and "--base-paths ." in line]
    assert in_repository and all("--log-base" in line for line in in_repository), in_repository
    assert "/log/" in (REPO_ROOT / ".gitignore").read_text().split()
