"""The default install stays lean (docs/install.md): open3d, dash, evo and gtsam are installed
without the dependencies they declare for parts the project never uses (requirements/no-deps.txt).

Checked from the requirement files and the packages' own metadata, not from this venv's
contents (a dev venv has everything): the default requirements' dependency closure never brings
the dropped packages back; every package the project's code imports is in that closure or in an
extra; and Open3D, evo and GTSAM, as the project calls them, work with every module outside the
closure made unimportable.
"""
from __future__ import annotations

import ast
import importlib.metadata as md
import subprocess
import sys
import textwrap
from functools import lru_cache
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parents[2]
REQ = ROOT / "requirements"
DEFAULT_FILES = ("ros.txt", "python.txt", "no-deps.txt")
EXTRA_FILES = ("learn.txt", "cameras.txt", "cluster.txt", "video.txt", "foxglove.txt", "dev.txt")
# declared by open3d, dash, evo or gtsam, never imported by what the project uses of them; and the
# extras' packages (issue 34: no torch, Ray, DepthAI, Playwright or ffmpeg by default; Foxglove's server)
MUST_STAY_OUT = {"flask", "nbformat", "ipywidgets", "ipython", "jedi", "configargparse", "pandas", "seaborn",
                 "numexpr", "natsort", "requests", "pytest", "torch", "ray", "depthai", "playwright",
                 "imageio-ffmpeg", "pyrealsense2", "foxglove-sdk"}
# the project and the messages tools/install.sh builds into the venv with cmake
BUILT = {"raspv", "raspv-msgs", "tf2-msgs"}


def pins(name: str) -> list[str]:
    out = []
    for line in (REQ / name).read_text().splitlines():
        line = line.split("#")[0].strip()
        if line:
            out.append(canonicalize_name(Requirement(line).name))
    return out


def requires(dist: str) -> list[str]:
    """The distributions ``dist`` declares for a plain install on this platform (no extras)."""
    try:
        declared = md.requires(dist) or []
    except md.PackageNotFoundError:
        pytest.fail(f"{dist} (a default requirement) is not installed here: make install")
    out = []
    for spec in declared:
        req = Requirement(spec)
        if req.marker is None or req.marker.evaluate({"extra": ""}):
            out.append(canonicalize_name(req.name))
    return out


@lru_cache(maxsize=None)
def default_closure() -> frozenset[str]:
    """Every distribution the default install has: the pins and what they declare, not following
    the no-deps packages' own declarations."""
    no_deps = set(pins("no-deps.txt"))
    seen: set[str] = set()
    stack = [p for f in DEFAULT_FILES for p in pins(f)] + ["pip", "setuptools"]
    while stack:
        dist = stack.pop()
        if dist in seen:
            continue
        seen.add(dist)
        if dist not in no_deps:
            stack += requires(dist)
    return frozenset(seen)


def modules_outside_the_default_install() -> set[str]:
    """Top-level modules whose every providing distribution is outside the default closure."""
    closure = default_closure() | BUILT
    outside = set()
    for module, dists in md.packages_distributions().items():
        if module.isidentifier() and all(canonicalize_name(d) not in closure for d in dists):
            outside.add(module)
    return outside


def test_the_default_requirements_never_bring_back_the_dropped_packages():
    closure = default_closure()
    assert not closure & MUST_STAY_OUT, sorted(closure & MUST_STAY_OUT)
    # and the no-deps packages really lack what they declare: open3d's Jupyter viewer, evo's plots
    assert {"flask", "nbformat", "ipywidgets"} <= set(requires("open3d-cpu"))
    assert "pandas" in requires("evo")


def test_every_package_the_project_imports_is_in_the_default_install_or_an_extra():
    provided = md.packages_distributions()
    allowed = default_closure() | BUILT | {d for f in EXTRA_FILES for d in pins(f)}
    allowed |= {d2 for f in EXTRA_FILES for d in pins(f) for d2 in requires(d)}
    stdlib = set(sys.stdlib_module_names)
    wrong = {}
    for package in sorted(p for p in ROOT.glob("raspv_*") if (p / "__init__.py").is_file()):
        for path in package.rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                    [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else []
                for name in names:
                    top = name.split(".")[0]
                    dists = {canonicalize_name(d) for d in provided.get(top, [])}
                    if top in stdlib or top.startswith("raspv_") or not dists:
                        continue  # the standard library, ours, or built into the venv (the messages)
                    if not dists & allowed:
                        wrong[f"{path.relative_to(ROOT)}: {top}"] = sorted(dists)
    assert not wrong, wrong


# Made unimportable in the child: the project's use of open3d, evo and gtsam (and their imports)
USE = textwrap.dedent("""
    import sys
    from importlib.abc import MetaPathFinder

    BLOCKED = set(sys.argv[1].split(","))

    class Absent(MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in BLOCKED:
                raise ModuleNotFoundError(f"No module named {name!r} (outside the default install)", name=name)
            return None

    sys.meta_path.insert(0, Absent())
    import numpy as np
    import open3d as o3d
    import gtsam
    from raspv_slam import evaluation

    # Open3D: point-to-plane ICP and RGB-D images as the odometry and SLAM cores use them
    rng = np.random.default_rng(0)
    pts = rng.uniform(-1, 1, (500, 3))
    src = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    dst = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts + [0.02, 0.0, 0.0]))
    dst.estimate_normals()
    fit = o3d.pipelines.registration.registration_icp(
        src, dst, 0.1, np.eye(4), o3d.pipelines.registration.TransformationEstimationPointToPlane())
    assert abs(fit.transformation[0, 3] - 0.02) < 1e-3, fit.transformation
    # GTSAM: a two-pose graph
    graph = gtsam.NonlinearFactorGraph()
    noise = gtsam.noiseModel.Isotropic.Sigma(6, 0.1)
    graph.add(gtsam.PriorFactorPose3(0, gtsam.Pose3(), noise))
    graph.add(gtsam.BetweenFactorPose3(0, 1, gtsam.Pose3(gtsam.Rot3(), [1.0, 0, 0]), noise))
    values = gtsam.Values()
    values.insert(0, gtsam.Pose3())
    values.insert(1, gtsam.Pose3())
    result = gtsam.LevenbergMarquardtOptimizer(graph, values).optimize()
    assert abs(result.atPose3(1).x() - 1.0) < 1e-6
    # evo: TUM files and ATE/RPE through raspv_slam.evaluation
    stamps = np.arange(60) * 0.1
    poses = np.repeat(np.eye(4)[None], 60, axis=0)
    poses[:, :3, 3] = np.column_stack([np.cos(stamps), np.sin(stamps), 0.1 * stamps])   # a helix [m]
    path = sys.argv[2]
    evaluation.write_trajectory(path, stamps, poses)
    s, p = evaluation.read_trajectory(path)
    errors = evaluation.trajectory_errors(s, p, stamps, poses)
    assert errors.matched == 60 and errors.ate_rmse < 1e-6, errors
    print("ok", len(BLOCKED))
""")


def test_open3d_evo_and_gtsam_work_as_we_use_them_without_the_dropped_packages(tmp_path):
    blocked = modules_outside_the_default_install()
    present = set(md.packages_distributions())
    assert {m for m in ("flask", "pandas", "IPython") if m in present} <= blocked   # where installed, blocked
    res = subprocess.run([sys.executable, "-c", USE, ",".join(sorted(blocked)), str(tmp_path / "traj.txt")],
                         capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert res.returncode == 0 and res.stdout.startswith("ok"), res.stderr[-3000:]
