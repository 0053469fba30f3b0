"""The colcon description of every ``raspv_*`` package, generated from the code (no rclpy).

Each top-level ``raspv_<pkg>/`` folder *is* its Python package, and ``pyproject.toml`` installs
them all as one distribution (``make install``, editable). colcon wants one package per folder
with a ``package.xml`` and a ``setup.py`` beside a sub-folder holding the Python package. So
``colcon/<pkg>/`` holds a standard ament_python package description whose ``<pkg>`` entry is a
symbolic link to the source folder (``../../<pkg>``): nothing moves, the editable install is
untouched, and ``colcon build`` and ``colcon build --symlink-install`` both work (a setup.py
inside the source folder would need ``package_dir={'<pkg>': '.'}``, which colcon's symlink
install cannot lay out). ``raspv_msgs/`` stays an ament_cmake package where it is.

What is generated, per package: ``package.xml`` with the dependencies its modules import (other
``raspv_*`` packages, ROS packages, rosdep keys of Python libraries), ``setup.cfg`` (packages,
package data, the ament index marker, one ``lib/<pkg>/<kind>`` executable per node kind of
:mod:`raspv_bringup.registry`), a two-line ``setup.py`` and the ``resource/<pkg>`` marker.
The code finds ``config/`` (device presets, graphs) and ``experiments/`` beside its package
folder, so the packages that read them install them beside themselves in site-packages.

``python -m raspv_bringup.colcon_workspace`` rewrites ``colcon/``; ``--check`` lists what is
out of date (a test runs it).
"""
from __future__ import annotations

import argparse
import ast
import os
import sys
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from xml.sax.saxutils import escape

REPO_ROOT = Path(__file__).resolve().parents[1]
COLCON_DIR = "colcon"
VERSION = "0.1.0"
MAINTAINER = ("raspv@example.org", "RASPV-py developers")
LICENSE = "BSD-3-Clause"

# Python libraries → rosdep key (checked against rosdep's python.yaml), or None where rosdep
# has none: those come from pip (requirements/python.txt) and are named in a comment.
PYTHON_DEPS: dict[str, str | None] = {
    "numpy": "python3-numpy", "scipy": "python3-scipy", "cv2": "python3-opencv", "yaml": "python3-yaml",
    "matplotlib": "python3-matplotlib", "psutil": "python3-psutil", "websockets": "python3-websockets",
    "open3d": "python3-open3d-pip", "pybullet": "python3-pybullet-pip", "pybullet_data": "python3-pybullet-pip",
    "pybullet_utils": "python3-pybullet-pip", "onnxruntime": "python3-onnxruntime-pip",
    "rosbags": None, "foxglove": None, "gtsam": None, "evo": None, "lz4": None, "compression": None, "backports": None, "elftools": None,
}
PIP_NAMES = {"rosbags": "rosbags", "gtsam": "gtsam", "evo": "evo", "foxglove": "foxglove-sdk", "elftools": "pyelftools", "lz4": "rosbags", "compression": "rosbags",
             "backports": "rosbags"}
# Imported only when a user asks for them (camera SDKs, torch models, Ray sweeps, image metrics):
# optional extras of pyproject.toml, not package dependencies.
OPTIONAL = {"pyrealsense2", "openni", "depthai", "libusb_package", "torch", "ray", "skimage",
            "pulse2percept", "dynaphos", "ai_edge_litert", "onnx", "playwright", "tqdm", "imageio_ffmpeg",
            "pytest"}   # pytest: the test harness (raspv_bringup.testing.dev_requirement), only under pytest
ROS_PACKAGES = {"rclpy", "ament_index_python", "launch", "launch_ros"}
# Extra files a package installs: (directory inside the repository, glob patterns). Installed
# as site-packages/<dir>/… beside the package: raspv_common.shipped looks for config/ and
# experiments/ beside raspv_common (in a colcon install every package has a prefix of its own).
DATA_DIRS: dict[str, dict[str, list[str]]] = {
    "raspv_common": {"config": ["*.yaml", "*.xml", "*.json", "*.rviz", "devices/*.yaml", "layouts/*.yaml",
                                "layouts/*.csv", "layouts/*.md"],
                     "experiments": ["*.yaml", "worlds/*.yaml", "results/*.csv", "results/*.yaml", "results/*.md"]},
}
# Files installed under share/<pkg>/ (ROS conventions: ros2 launch PKG FILE, RViz configs).
SHARE_FILES: dict[str, dict[str, str]] = {
    "raspv_bringup": {"launch": "launch/*.launch.py", "config": "config/fastdds_shm.xml config/fastdds_multihost.xml"},
    "raspv_viz": {"config": "config/raspv.rviz config/foxglove_layout.json"},
}
DESCRIPTIONS = {
    "raspv_bags": "RASPV-py bags: recording, reading, repair, playback, offline phosphene rendering, dataset import",
    "raspv_bringup": "RASPV-py launcher and command line: graph files, supervisor, test harness, ros2 launch export",
    "raspv_camera": "RASPV-py RGB-D sources: real cameras through their SDKs, bag replay, a synthetic room",
    "raspv_common": "RASPV-py shared pieces: camera model, conversions, node base, parameter schemas, occupancy grids",
    "raspv_experiments": "RASPV-py experiments: protocols, sessions with subjects, scripted subjects, sweeps, reports",
    "raspv_hmd": "RASPV-py headset bridge: phosphene frames to browser and native clients, head pose and teleop back",
    "raspv_learn": "RASPV-py learned encoders: a differentiable twin of the phosphene simulator, training, ONNX export",
    "raspv_nav": "RASPV-py navigation assistant: costmaps from depth, A* global planner, DWA, guidance",
    "raspv_perception": "RASPV-py scene perception: floor, planes, obstacles, free floor, stairs, segmentation, odometry",
    "raspv_sim": "RASPV-py virtual world on PyBullet: world files, the BlindBot avatar, people, RGB-D camera",
    "raspv_slam": "RASPV-py RGB-D SLAM: keyframe tracking, loop closure with GTSAM, saved maps, localisation mode",
    "raspv_spv": "RASPV-py phosphene simulator: phosphene maps, sprites, temporal model, representation modes",
    "raspv_viz": "RASPV-py live views: RViz markers and point clouds of what perception found, a Foxglove server",
}
PACKAGE_DATA = ["*.yaml", "*.html", "*.js", "*.css", "*.xml", "*.json", "*.obj", "*.urdf", "*.png",
                "worlds/*.yaml", "worlds/meshes/*.obj", "models/*.onnx", "models/*.md", "models/LICENSE*"]
SETUP_PY = ('"""colcon (ament_python) build of this package: everything is in setup.cfg, written by\n'
            '``python -m raspv_bringup.colcon_workspace`` (see docs/DEVELOPING.md)."""\n'
            "from setuptools import setup\n\nsetup()\n")


# Development tools, not part of the workspace: the benchmarks import the test harness and their
# peers (pulse2percept, dynaphos, Open3D, …); they run from the repository's venv (`raspv bench`).
NOT_IN_WORKSPACE = {"raspv_bench"}


def package_names(root: Path = REPO_ROOT) -> list[str]:
    """The Python packages (top-level ``raspv_*`` folders with an ``__init__.py``) but the
    development tools (:data:`NOT_IN_WORKSPACE`)."""
    return sorted(p.name for p in root.glob("raspv_*") if (p / "__init__.py").is_file() and p.name not in NOT_IN_WORKSPACE)


def imported_modules(package_dir: Path) -> set[str]:
    """Top-level names of the modules the package's own code imports (stdlib left out)."""
    found: set[str] = set()
    for path in sorted(package_dir.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                found.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                found.add(node.module.split(".")[0])
    return {m for m in found if m not in sys.stdlib_module_names and m not in ("__future__", package_dir.name)}


@dataclass
class PackageDescription:
    name: str
    description: str
    raspv_deps: list[str] = field(default_factory=list)
    ros_deps: list[str] = field(default_factory=list)
    rosdep_keys: list[str] = field(default_factory=list)
    pip_only: list[str] = field(default_factory=list)
    executables: dict[str, str] = field(default_factory=dict)   # kind → "module:main"


@lru_cache(maxsize=None)
def describe(name: str, root: Path = REPO_ROOT) -> PackageDescription:
    """What ``colcon/<name>/`` must say about the package ``name``; ValueError for an import
    this module does not know how to declare (add it to PYTHON_DEPS or OPTIONAL)."""
    from raspv_bringup.registry import NODES

    modules = imported_modules(root / name)
    unknown = sorted(m for m in modules if not (m.startswith("raspv_") or _is_ros(m) or m in PYTHON_DEPS
                                                or m in OPTIONAL))
    if unknown:
        raise ValueError(f"{name}: imports {', '.join(unknown)}: declare each in "
                         "raspv_bringup/colcon_workspace.py PYTHON_DEPS (rosdep key or None) or OPTIONAL")
    return PackageDescription(
        name=name, description=DESCRIPTIONS.get(name, name),
        raspv_deps=sorted(m for m in modules if m.startswith("raspv_")),
        ros_deps=sorted(m for m in modules if _is_ros(m)),
        rosdep_keys=sorted({PYTHON_DEPS[m] for m in modules if PYTHON_DEPS.get(m)}),
        pip_only=sorted({PIP_NAMES[m] for m in modules if m in PYTHON_DEPS and PYTHON_DEPS[m] is None}),
        executables={kind: f"{spec.module}:main" for kind, spec in sorted(NODES.items())
                     if spec.module.split(".")[0] == name},
    )


def _is_ros(module: str) -> bool:
    return module in ROS_PACKAGES or ((module.endswith("_msgs") or module.endswith("_interfaces"))
                                      and not module.startswith("raspv_"))


def package_xml(d: PackageDescription) -> str:
    deps = [*d.raspv_deps, *d.ros_deps, *d.rosdep_keys]
    lines = ['<?xml version="1.0"?>',
             "<!-- Generated by `python -m raspv_bringup.colcon_workspace` from the package's imports. -->",
             '<package format="3">',
             f"  <name>{d.name}</name>",
             f"  <version>{VERSION}</version>",
             f"  <description>{escape(d.description)}</description>",
             f'  <maintainer email="{MAINTAINER[0]}">{MAINTAINER[1]}</maintainer>',
             f"  <license>{LICENSE}</license>",
             *(f"  <exec_depend>{dep}</exec_depend>" for dep in deps)]
    if d.pip_only:
        lines.append(f"  <!-- from pip (no rosdep key): {', '.join(d.pip_only)} (requirements/python.txt) -->")
    lines += ["  <test_depend>python3-pytest</test_depend>",
              "  <export>", "    <build_type>ament_python</build_type>", "  </export>", "</package>", ""]
    return "\n".join(lines)


def setup_cfg(d: PackageDescription, root: Path = REPO_ROOT) -> str:
    n = d.name
    data_dirs = DATA_DIRS.get(n, {})
    packages = [f"{n}", f"{n}.*", *data_dirs]
    lines = ["# Generated by `python -m raspv_bringup.colcon_workspace`: the ament_python build of this package.",
             "[metadata]", f"name = {n}", f"version = {VERSION}", f"description = {d.description}",
             f"license = {LICENSE}", "",
             "[options]", "packages = find_namespace:", "zip_safe = False", "",
             "[options.packages.find]", "include =", *(f"    {p}" for p in packages), "",
             "[options.package_data]"]
    for package in _package_tree(root / n):
        lines += [f"{package} =", *(f"    {p}" for p in PACKAGE_DATA)]
    for directory, patterns in data_dirs.items():
        lines += [f"{directory} =", *(f"    {p}" for p in patterns)]
    lines += ["", "[options.data_files]",
              "share/ament_index/resource_index/packages =", f"    resource/{n}",
              f"share/{n} =", "    package.xml"]
    for sub, patterns in SHARE_FILES.get(n, {}).items():
        lines += [f"share/{n}/{sub} =", *(f"    {p}" for p in patterns.split())]
    if d.executables:
        lines += ["", "[options.entry_points]", "console_scripts ="]
        lines += [f"    {kind} = {target}" for kind, target in d.executables.items()]
    lines += ["", "[develop]", f"script_dir = $base/lib/{n}", "", "[install]", f"install_scripts = $base/lib/{n}", ""]
    return "\n".join(lines)


def _package_tree(package_dir: Path) -> list[str]:
    """The package and its sub-folders as (namespace) package names: each gets the data patterns."""
    def holds_files(d: Path) -> bool:
        return any(f.is_file() and (f.suffix == ".py" or any(f.match(p) for p in PACKAGE_DATA)) for f in d.iterdir())
    subs = sorted(p for p in package_dir.rglob("*") if p.is_dir() and p.name != "__pycache__" and holds_files(p))
    return [package_dir.name, *(".".join((package_dir.name, *p.relative_to(package_dir).parts)) for p in subs)]


def links(name: str) -> dict[str, str]:
    """Symbolic links inside ``colcon/<name>/`` → their targets (relative)."""
    out = {name: f"../../{name}"}
    for directory in [*DATA_DIRS.get(name, {}), *(Path(p).parts[0] for p in
                                                 " ".join(SHARE_FILES.get(name, {}).values()).split())]:
        out[directory] = f"../../{directory}"
    return out


def expected_files(root: Path = REPO_ROOT) -> dict[Path, str]:
    """Relative path → text of every generated regular file."""
    files: dict[Path, str] = {}
    for name in package_names(root):
        d = describe(name, root)
        base = Path(COLCON_DIR) / name
        files[base / "package.xml"] = package_xml(d)
        files[base / "setup.cfg"] = setup_cfg(d, root)
        files[base / "setup.py"] = SETUP_PY
        files[base / "resource" / name] = ""
    return files


def check(root: Path = REPO_ROOT) -> list[str]:
    """One line per generated file or link that is missing or differs from what the code says."""
    problems = []
    for rel, text in expected_files(root).items():
        path = root / rel
        if not path.is_file() or path.read_text(encoding="utf-8") != text:
            problems.append(f"{rel}: {'missing' if not path.is_file() else 'out of date'}")
    for name in package_names(root):
        for link, target in links(name).items():
            path = root / COLCON_DIR / name / link
            if not path.is_symlink() or os.readlink(path) != target:
                problems.append(f"{path.relative_to(root)}: expected a link to {target}")
    known = {root / COLCON_DIR / n for n in package_names(root)}
    for stale in sorted(p for p in (root / COLCON_DIR).glob("*") if p.is_dir() and p not in known):
        problems.append(f"{stale.relative_to(root)}: no package {stale.name} any more")
    return problems


def write(root: Path = REPO_ROOT) -> list[Path]:
    """(Re)write ``colcon/``; returns the files written."""
    written = []
    for rel, text in expected_files(root).items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.is_file() or path.read_text(encoding="utf-8") != text:
            path.write_text(text, encoding="utf-8")
            written.append(rel)
    for name in package_names(root):
        for link, target in links(name).items():
            path = root / COLCON_DIR / name / link
            if path.is_symlink() and os.readlink(path) == target:
                continue
            if path.is_symlink() or path.exists():
                path.unlink()
            path.symlink_to(target)
            written.append(path.relative_to(root))
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m raspv_bringup.colcon_workspace", description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="list what is out of date; exit 1 if anything is")
    args = parser.parse_args(argv)
    try:
        if args.check:
            problems = check()
            for line in problems:
                print(line)
            return 1 if problems else 0
        for rel in write():
            print(f"wrote {rel}")
    except ValueError as exc:
        print(f"colcon_workspace: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
