"""`raspv export-launch`: ros2 launch files with the graph's nodes, parameters and restart policy.

ros2launch is not on PyPI, so the generated files are parsed (ast) and every node, parameter,
environment variable and the restart policy are checked against the graph they came from; the
file's own code runs against stand-ins of `launch` and `launch_ros` that record what it builds.
"""
from __future__ import annotations

import ast
import subprocess
import sys
import types
from pathlib import Path

import pytest

from raspv_bringup.colcon_workspace import describe
from raspv_bringup.export_launch_cli import LAUNCH_DIR, shipped_graphs, shipped_text
from raspv_bringup.graph import load_graph
from raspv_bringup.launch_export import node_env, package_of

RASPV = [sys.executable, "-m", "raspv_bringup.cli"]


def launch_nodes(text: str) -> list[dict]:
    """The ``NODES`` literal of a launch file: Node keyword arguments per node."""
    tree = ast.parse(text)
    assert any(isinstance(n, ast.FunctionDef) and n.name == "generate_launch_description" for n in tree.body)
    [nodes] = [n.value for n in tree.body if isinstance(n, ast.Assign) and [t.id for t in n.targets] == ["NODES"]]
    return ast.literal_eval(nodes)


def assert_matches_graph(text: str, graph) -> None:
    nodes = launch_nodes(text)
    assert [n["name"] for n in nodes] == [e.name for e in graph.nodes]
    for launched, entry in zip(nodes, graph.nodes):
        package = package_of(entry)
        assert launched["package"] == package
        assert launched["executable"] == entry.kind
        assert entry.kind in describe(package).executables      # lib/<package>/<kind> exists after colcon build
        assert launched["respawn"] is entry.restart
        assert launched["parameters"] == [entry.params]
        for name, value in entry.params.items():                 # same types as the launcher's params file
            assert type(launched["parameters"][0][name]) is type(value), name
        assert launched["additional_env"] == node_env(graph, entry)
        assert "remappings" not in launched                      # graphs remap nothing but the node name


@pytest.mark.parametrize("path", shipped_graphs(), ids=lambda p: p.stem)
def test_shipped_launch_files_are_up_to_date_and_match_their_graph(path):
    shipped = LAUNCH_DIR / f"{path.stem}.launch.py"
    assert shipped.is_file(), f"{shipped} missing: run `raspv export-launch --shipped`"
    text = shipped.read_text()
    assert text == shipped_text(path), f"{shipped} is out of date: run `raspv export-launch --shipped`"
    assert_matches_graph(text, load_graph(path, check_files=False))


def test_export_with_overrides_restart_and_env(tmp_path):
    graph_file = tmp_path / "g.yaml"
    graph_file.write_text("""
launch:
  env: {RASPV_X: "1"}
  nodes:
    - kind: synthetic
      name: cam
      restart: true
      env: {OMP_NUM_THREADS: "2"}
    - kind: spv
cam:
  ros__parameters: {rate: 5.0, width: 160}
spv:
  ros__parameters: {mode: depth, overlays: [path]}
""")
    out = tmp_path / "g.launch.py"
    done = subprocess.run([*RASPV, "export-launch", str(graph_file), "spv.mode:=edges", "-o", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    graph = load_graph(graph_file, ["spv.mode:=edges"])
    assert_matches_graph(out.read_text(), graph)
    cam, spv = launch_nodes(out.read_text())
    assert cam["respawn"] is True and cam["respawn_delay"] == 0.0 and spv["respawn"] is False
    assert cam["additional_env"]["OMP_NUM_THREADS"] == "2" and cam["additional_env"]["RASPV_X"] == "1"
    # camera_source: set by the launcher from the graph's source (a synthetic camera: on nobody's head)
    assert spv["parameters"] == [{"camera_source": "unknown", "mode": "edges", "overlays": ["path"]}]


def test_bad_graph_is_one_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("launch:\n  nodes: [{kind: spv}]\nspv:\n  ros__parameters: {mode: nonsense}\n")
    done = subprocess.run([*RASPV, "export-launch", str(bad)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "spv.ros__parameters.mode" in done.stderr and "Traceback" not in done.stderr
    missing = subprocess.run([*RASPV, "export-launch", str(tmp_path / "none.yaml")], capture_output=True, text=True,
                             timeout=120)
    assert missing.returncode == 2 and "no such graph file" in missing.stderr


def test_the_launch_file_builds_its_nodes_after_the_middleware_defaults(monkeypatch):
    """The file's code against stand-ins of launch/launch_ros (not on PyPI) that record calls."""
    built = []

    def recorder(kind):
        return lambda *args, **kwargs: built.append((kind, args, kwargs)) or (kind, args, kwargs)
    fakes = {"launch": {"LaunchDescription": recorder("LaunchDescription")},
             "launch.actions": {"SetEnvironmentVariable": recorder("SetEnvironmentVariable")},
             "launch.substitutions": {"EnvironmentVariable": recorder("EnvironmentVariable"),
                                      "PathJoinSubstitution": recorder("PathJoinSubstitution")},
             "launch_ros.actions": {"Node": recorder("Node")},
             "launch_ros.substitutions": {"FindPackageShare": recorder("FindPackageShare")}}
    for name, attrs in {**fakes, "launch_ros": {}}.items():
        module = types.ModuleType(name)
        module.__dict__.update(attrs)
        monkeypatch.setitem(sys.modules, name, module)
    path = LAUNCH_DIR / "demo.launch.py"
    namespace: dict = {}
    exec(compile(path.read_text(), str(path), "exec"), namespace)
    kind, (actions,), _ = namespace["generate_launch_description"]()
    assert kind == "LaunchDescription"
    env = [a[1][0] for a in actions if a[0] == "SetEnvironmentVariable"]
    assert env == ["RMW_IMPLEMENTATION", "ROS_AUTOMATIC_DISCOVERY_RANGE", "FASTRTPS_DEFAULT_PROFILES_FILE"]
    nodes = [a[2] for a in actions if a[0] == "Node"]
    graph = load_graph(shipped_graphs()[[p.stem for p in shipped_graphs()].index("demo")], check_files=False)
    assert [n["name"] for n in nodes] == [e.name for e in graph.nodes]
    assert all(n["output"] == "screen" for n in nodes)
    assert actions.index(next(a for a in actions if a[0] == "Node")) == len(env)      # env first
