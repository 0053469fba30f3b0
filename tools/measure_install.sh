#!/usr/bin/env bash
# Size and time of the install from a fresh clone: the default install (`make install`), then the
# full one (`make install EXTRAS=dev`, what `make test` installs) on top of it. Prints wall and
# CPU seconds with the load average before and after (a busy machine stretches the wall time,
# not the CPU time). Usage: tools/measure_install.sh [REPO (default: this checkout)] [WORK_DIR]
set -euo pipefail
REPO=${1:-$(cd "$(dirname "$0")/.." && pwd)}
WORK=${2:-/tmp/raspv-install-measure}
rm -rf "$WORK" && git clone -q "$REPO" "$WORK" && cd "$WORK"
say() { echo "measure_install: $*"; }
step() {
  local name=$1; shift
  local before; before=$(cut -d' ' -f1-3 /proc/loadavg)
  /usr/bin/time -f "%e %U %S" -o "$WORK/.time" "$@" > "$WORK/$name.log" 2>&1 || { tail -20 "$WORK/$name.log"; exit 1; }
  read -r wall user sys < "$WORK/.time"
  say "$name: $(du -sb .venv | awk '{printf "%.2f GB", $1 / 1e9}'), wall $wall s, CPU $(awk -v u="$user" -v s="$sys" 'BEGIN { print u + s }') s" \
      "(load average $before before, $(cut -d' ' -f1-3 /proc/loadavg) after)"
}
step default make install
# the extras' packages, and what open3d/evo/gtsam declare but the project never imports (requirements/no-deps.txt)
found=$(.venv/bin/pip list 2>/dev/null | grep -iE "^(torch|ray|depthai|playwright|imageio-ffmpeg|pyrealsense2|foxglove-sdk|flask|pandas|ipython|pytest) " | cut -d' ' -f1 | tr '\n' ' ' || true)
say "default: of torch, Ray, DepthAI, Playwright, imageio-ffmpeg, pyrealsense2, foxglove-sdk, Flask, pandas, IPython, pytest installed: ${found:-none} (none expected)"
step full make install EXTRAS=dev
