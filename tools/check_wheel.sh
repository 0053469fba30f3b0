#!/usr/bin/env bash
# Build a wheel of RASPV-py, install it into a fresh venv in /tmp and start the demo from another
# folder: the package works without the repository (configs, worlds, client, models, devices and
# the messages come with it). Prints the sizes and times. Usage: tools/check_wheel.sh [WORK_DIR]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
WORK=${1:-/tmp/raspv-wheel-check}
PY=${PYTHON:-python3}
rm -rf "$WORK" && mkdir -p "$WORK/elsewhere"
say() { echo "check_wheel: $*"; }
quiet_pip() { "$@" 2>&1 | { grep -v -E "is ignored: it is neither a file nor a directory" || true; }; }

say "load average $(cut -d' ' -f1-3 /proc/loadavg)"
t0=$(date +%s)
quiet_pip "$PY" -m pip wheel --no-deps -q -w "$WORK/dist" "$ROOT"
WHEEL=$(ls "$WORK"/dist/raspv-*.whl)
t1=$(date +%s)
say "built $(basename "$WHEEL") ($(du -h "$WHEEL" | cut -f1)) in $((t1 - t0)) s"
"$PY" -m venv "$WORK/venv"
quiet_pip "$WORK/venv/bin/python" -m pip install -q "$WHEEL"
t2=$(date +%s)
say "installed into a fresh venv in $((t2 - t1)) s: $(du -sh "$WORK/venv" | cut -f1)"
cd "$WORK/elsewhere"
"$WORK/venv/bin/raspv" demo --help > /dev/null
"$WORK/venv/bin/raspv" doctor || true
"$WORK/venv/bin/raspv" launch demo --check
# the demo itself, headless, until the bridge prints the client's address (then Ctrl-C)
LOG=$WORK/demo.log
"$WORK/venv/bin/raspv" demo bridge.port:=0 bridge.tcp_port:=-1 > "$LOG" 2>&1 &
PID=$!
for _ in $(seq 240); do
  if grep -q "http://" "$LOG"; then break; fi
  kill -0 $PID 2>/dev/null || break
  sleep 0.5
done
kill -INT $PID 2>/dev/null || true
wait $PID || true
grep -m1 "http://" "$LOG" >/dev/null || { tail -20 "$LOG"; say "the demo did not start from $WORK/elsewhere"; exit 1; }
say "demo started from $WORK/elsewhere: $(grep -m1 'http://' "$LOG")"
