"""Optional dependencies ("extras") imported by need, with one line naming the fix (no ROS).

The default install has what the demo, graphs, recordings and experiments need. What only some
users need is an extra of ``pyproject.toml`` (its exact pins in ``requirements/<extra>.txt``):

- ``learn``: torch (CPU build), onnx, tqdm — ``raspv learn``, the differentiable twin;
- ``cameras``: the RealSense, OpenNI2 and DepthAI SDKs — the ``camera`` node;
- ``cluster``: Ray — ``raspv experiment sweep --ray``;
- ``foxglove``: foxglove-sdk — the ``foxglove`` node (the graph live in the Foxglove app);
- ``video``: imageio-ffmpeg's FFmpeg — ``raspv render --codec h264`` (browser-playable mp4; the
  default mp4v needs no extra);
- ``dev``: all of the above, the test runner, the peers the benchmarks compare against
  (pulse2percept, dynaphos), Playwright's browser driver, colcon and MkDocs.

Every import of such a package goes through :func:`require`, which raises
:class:`MissingExtra` (an ``ImportError``) whose message is the one line to print; the ``raspv``
command prints it instead of a traceback. :func:`install_command` is the command for this kind
of install: ``make install EXTRAS=…`` in a repository checkout, ``pip install 'raspv[…]'``
otherwise.
"""
from __future__ import annotations

import importlib
import sys
from pathlib import Path
from types import ModuleType

REPO_ROOT = Path(__file__).resolve().parents[1]
# the index of PyTorch's CPU wheels: the public index gives torch's CUDA build on Linux
TORCH_CPU_INDEX = "https://download.pytorch.org/whl/cpu"
TORCH_PIN = "torch==2.13.0"

EXTRAS: dict[str, str] = {
    "learn": "learned encoders (raspv learn): torch CPU build, onnx, tqdm",
    "cameras": "real RGB-D cameras: RealSense, OpenNI2, DepthAI SDKs",
    "cluster": "sweeps on a Ray cluster",
    "foxglove": "the foxglove node (the graph live in the Foxglove app): foxglove-sdk",
    "video": "H.264 videos (raspv render --codec h264): imageio-ffmpeg",
    "dev": "tests, benchmarks' peers, browser driver, colcon, MkDocs (includes learn, cameras, cluster, foxglove, video)",
}

# importable module -> (extra, distribution) for every optional package
OPTIONAL_MODULES: dict[str, tuple[str, str]] = {
    "torch": ("learn", "torch"),
    "onnx": ("learn", "onnx"),
    "tqdm": ("learn", "tqdm"),
    "pyrealsense2": ("cameras", "pyrealsense2"),
    "openni": ("cameras", "openni"),
    "depthai": ("cameras", "depthai"),
    "ray": ("cluster", "ray"),
    "imageio_ffmpeg": ("video", "imageio-ffmpeg"),
    "foxglove": ("foxglove", "foxglove-sdk"),
    "playwright": ("dev", "playwright"),
    "pulse2percept": ("dev", "pulse2percept"),
    "dynaphos": ("dev", "dynaphos"),
    "pytest": ("dev", "pytest"),
    "mkdocs": ("dev", "mkdocs"),
}


INSTALL_STAMP = ".raspv-install-stamp"   # written by tools/install.sh into the venv it completed


def installed_extras(prefix: str | Path | None = None) -> set[str] | None:
    """The extras ``tools/install.sh`` installed into the environment at ``prefix`` (default:
    the running one), from its stamp; None when no install script completed there (a ``pip
    install``). A stamp without the extras line is from the install that put everything in."""
    stamp = Path(prefix or sys.prefix) / INSTALL_STAMP
    try:
        lines = stamp.read_text().splitlines()
    except OSError:
        return None
    if len(lines) < 2:
        return set(EXTRAS)
    return {e for e in lines[1].split() if e in EXTRAS}


class MissingExtra(ImportError):
    """An optional package is not installed; ``str(exc)`` is one line naming the command that
    installs it."""


def in_checkout() -> bool:
    """True when running from a repository checkout (``make install`` is there)."""
    return (REPO_ROOT / "tools" / "install.sh").is_file() and (REPO_ROOT / "Makefile").is_file()


def install_command(extra: str) -> str:
    """The command that installs ``extra`` into the running environment."""
    if in_checkout():
        return f"make install EXTRAS={extra}   (in {REPO_ROOT})"
    pip = f"{sys.executable} -m pip install"
    if extra in ("learn", "dev"):  # torch's CPU wheel first, or the public index brings CUDA's
        return f"{pip} {TORCH_PIN} --index-url {TORCH_CPU_INDEX} && {pip} 'raspv[{extra}]'"
    return f"{pip} 'raspv[{extra}]'"


def require(module: str, purpose: str = "", extra: str | None = None, dist: str | None = None) -> ModuleType:
    """Import ``module`` (a key of :data:`OPTIONAL_MODULES`, or a submodule of one, unless
    ``extra`` and ``dist`` name them); raise :class:`MissingExtra` naming the extra and its
    install command when it is not installed."""
    top = module.split(".")[0]
    if extra is None or dist is None:
        extra, dist = OPTIONAL_MODULES[top]
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name is None or exc.name.split(".")[0] != top:
            raise  # the package is there but one of its own dependencies is not: not ours to word
        what = f"{purpose} needs {dist}" if purpose else f"{dist} is not installed"
        raise MissingExtra(f"{what} (the '{extra}' extra): {install_command(extra)}") from None


def installed(module: str) -> bool:
    """Whether ``module`` can be found, without importing it."""
    import importlib.util

    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False
