"""Every command on the README's front page is run (issue 34), as written, in a fresh working
folder with the environment active. Which are cut short, and how:

- ``make demo`` runs until the bridge prints the headset client's address and the camera's
  first frame is out (then the tour's commands run against it), then gets Ctrl-C;
- ``raspv bag record -o my_run`` records until 10 camera frames went by after it subscribed
  to the camera, then gets Ctrl-C (a complete bag is the promise);
- ``make test`` is what CI runs (``.ci/run``): this test is part of it.

The README's Python block runs on a frame of the synthetic room (its ``rgb``, ``depth`` and
``camera`` are the reader's own in the README).
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.docs.tutorial_runner import run_block, user_env

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
BASH = re.compile(r"^```bash\n(.*?)^```", re.S | re.M)
PYTHON = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def readme_commands() -> list[str]:
    out = []
    for block in BASH.findall(README.read_text(encoding="utf-8")):
        for line in block.splitlines():
            command = re.sub(r"\s+#.*$", "", line).strip()
            if command:
                out.append(command)
    return out


# README command -> the script lines that run it (README's text itself, plus what cuts it short)
RUNS = {
    "make demo": 'make -C "$ROOT" demo DEMO_ARGS="bridge.port:=0 bridge.tcp_port:=-1" > demo.log 2>&1 &\n'
                 'until grep -q "headset client: open" demo.log; do sleep 0.5; kill -0 %1 || exit 1; done',
    "source .venv/bin/activate": 'source "$ROOT/.venv/bin/activate"\n'
                                 'raspv echo /camera/color/camera_info --once --wait 90 > /dev/null',
    "raspv param set spv mode chess_floor": "raspv param set spv mode chess_floor",
    "raspv param set spv device argus_ii": "raspv param set spv device argus_ii",
    "raspv bag record -o my_run": "raspv bag record -o my_run > record.log 2>&1 &\n"
                                  'until grep -q "+ /camera/color/image_raw" record.log; do sleep 0.5; kill -0 %2 || exit 1; done\n'
                                  "raspv echo /camera/color/camera_info -n 10 --wait 30 > /dev/null\n"
                                  "kill -INT %2 && wait %2\n"
                                  "kill -INT %1; wait %1 || true",   # the demo's make: Ctrl-C is its way out
    "raspv render my_run -o my_run.mp4 --mode depth --side-by-side":
        "raspv render my_run -o my_run.mp4 --mode depth --side-by-side",
    "raspv experiment run example --subject scripted": "raspv experiment run example --subject scripted",
    "raspv experiment report sessions/example -o report": "raspv experiment report sessions/example -o report",
    "make test": None,       # .ci/run runs it: the whole suite, this file included
}


def test_every_readme_command_is_run_here():
    commands = readme_commands()
    assert set(commands) == set(RUNS), ("README commands and the ones this test runs differ: "
                                        f"{sorted(set(commands) ^ set(RUNS))}")
    assert "make test" in (ROOT / ".ci" / "run").read_text().split()[-2:] or \
        (ROOT / ".ci" / "run").read_text().rstrip().endswith("make test")


@pytest.mark.slow
@pytest.mark.integration
def test_readme_commands_run_in_order(tmp_path):
    script = f'ROOT="{ROOT}"\n' + "\n".join(RUNS[c] for c in readme_commands() if c != "make test")
    run = run_block("bash", script, tmp_path, user_env("readme"), timeout=1200)
    print(run.output[-3000:], f"\n({run.seconds:.0f} s)")
    assert (tmp_path / "my_run.mp4").stat().st_size > 0
    assert (tmp_path / "report" / "report.html").exists()
    assert "complete bag" in (tmp_path / "record.log").read_text() or list((tmp_path / "my_run").iterdir())


def test_the_readme_python_block_runs(tmp_path):
    [code] = PYTHON.findall(README.read_text(encoding="utf-8"))
    frame = ("from raspv_camera.synthetic_scene import SyntheticRoom\n"
             "from raspv_common.intrinsics import CameraIntrinsics\n"
             "camera = CameraIntrinsics.from_hfov(320, 240, 70.0)\n"
             "room = SyntheticRoom(camera)\n"
             "rgb, depth = room.render(room.pose_at(4.0))\n")
    check = "\nassert image.ndim in (2, 3) and image.max() > 0, image.shape\n"
    run_block("python", frame + code + check, tmp_path, user_env("readme"), timeout=300)
