"""Build steps pyproject.toml cannot declare, for a wheel that works outside the repository.

``pip install .`` / ``pip wheel .`` (not the editable install ``make install`` makes):

- copies the shipped data folders ``config/`` and ``experiments/`` into
  ``raspv_common/shipped/`` (:mod:`raspv_common.shipped` finds them there);
- builds the message packages ``tf2_msgs`` (not among PyPI's ROS wheels) and ``raspv_msgs``
  with cmake against the ROS 2 wheels of the build environment (the ``build-system``
  requirements) and puts their Python packages (with the ``.msg`` files) and their shared
  libraries into the wheel; the libraries go to ``ros_raspv_msgs.libs/``, a folder the ROS
  wheels' bootstrapper adds to the library path. The wheel is therefore platform-specific.

Needs ``cmake`` and a C++ compiler, like ``make install``.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

from setuptools import Distribution, setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
SHIPPED = ("config", "experiments")
MESSAGE_PACKAGES = ("tf2_msgs", "raspv_msgs")      # built in this order (as tools/install.sh does)
LIBS_DIR = "ros_raspv_msgs.libs"
_WHEEL_PYTHON = re.compile(r"/opt/python/cp3[0-9]+-cp3[0-9]+")


def _point_cmake_files_at_this_python(prefix: Path) -> None:
    """The ROS wheels' exported CMake files name their builder's Python (/opt/python/cp3XX-…):
    point them at this interpreter's headers and numpy (as tools/install.sh does)."""
    import numpy

    py_include = sysconfig.get_paths()["include"]
    np_include = numpy.get_include()
    for path in (prefix / "share").rglob("*.cmake"):
        text = path.read_text(errors="replace")
        if not _WHEEL_PYTHON.search(text):
            continue
        text = re.sub(r"/opt/python/cp3[0-9]+-cp3[0-9]+/lib/python3\.[0-9]+/site-packages/numpy/_core/include",
                      np_include, text)
        text = re.sub(r"/opt/python/cp3[0-9]+-cp3[0-9]+/include/python3\.[0-9]+", py_include, text)
        path.write_text(text)


def build_messages(build_lib: Path, work: Path) -> None:
    """The message packages → ``build_lib/<pkg>`` (Python) and ``build_lib/ros_raspv_msgs.libs`` (C)."""
    # the prefix the ROS build wheels are installed in: pip's isolated build environment (an
    # overlay on sys.path, not sys.prefix) or the venv of a --no-build-isolation build
    import ament_package

    prefix = Path(ament_package.__file__).resolve().parents[4]
    if shutil.which("cmake") is None:
        raise SystemExit("building raspv_msgs needs cmake: sudo apt-get install cmake g++")
    _point_cmake_files_at_this_python(prefix)
    install = work / "install"
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    install.mkdir()
    env = dict(os.environ, AMENT_PREFIX_PATH=f"{install}{os.pathsep}{prefix}",
               CMAKE_PREFIX_PATH=f"{install}{os.pathsep}{prefix}",
               PATH=f"{prefix / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}",
               LD_LIBRARY_PATH=os.pathsep.join(p for p in (str(install / "lib"), str(prefix / "lib"),
                                                           os.environ.get("LD_LIBRARY_PATH")) if p))
    for pkg in MESSAGE_PACKAGES:
        build = work / pkg
        build.mkdir()
        log = build / "build.log"
        with open(log, "w") as out:
            for cmd in (["cmake", str(ROOT / pkg), f"-DCMAKE_INSTALL_PREFIX={install}",
                         f"-DPython3_EXECUTABLE={sys.executable}", "-DBUILD_TESTING=OFF", "-DCMAKE_BUILD_TYPE=Release"],
                        ["make", f"-j{os.cpu_count() or 2}", "install"]):
                if subprocess.run(cmd, cwd=build, env=env, stdout=out, stderr=subprocess.STDOUT).returncode != 0:
                    tail = log.read_text(errors="replace").splitlines()[-25:]
                    raise SystemExit(f"building {pkg} failed:\n" + "\n".join(tail))
        package = next(install.glob(f"lib/python3*/site-packages/{pkg}"))
        shutil.copytree(package, build_lib / pkg, dirs_exist_ok=True)
        for kind in ("msg", "srv"):  # the definitions too: rosbags builds its types from them
            for f in (ROOT / pkg / kind).glob(f"*.{kind}"):
                shutil.copy2(f, build_lib / pkg / kind / f.name)
    libs = build_lib / LIBS_DIR
    libs.mkdir(exist_ok=True)
    for lib in install.glob("lib/*.so"):
        shutil.copy2(lib, libs / lib.name)


class BuildPyWithData(build_py):
    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            return  # an editable install uses the checkout's folders and make install's messages
        build_lib = Path(self.build_lib)
        for name in SHIPPED:
            shutil.copytree(ROOT / name, build_lib / "raspv_common" / "shipped" / name, dirs_exist_ok=True,
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        build_messages(build_lib, ROOT / "build" / "wheel_msgs")


class BinaryDistribution(Distribution):
    """The wheel carries compiled message libraries: a platform wheel, not py3-none-any."""

    def has_ext_modules(self):
        return True


setup(cmdclass={"build_py": BuildPyWithData}, distclass=BinaryDistribution)
