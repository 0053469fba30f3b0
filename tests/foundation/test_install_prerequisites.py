"""tools/install.sh stops with one line naming a missing prerequisite and how to install it."""
import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TOOLS = ["bash", "dirname", "cat", "sha256sum", "cut", "python3", "cmake", "c++", "g++", "env", "nproc"]


def run_with_path_lacking(missing: set[str], tmp_path: Path) -> subprocess.CompletedProcess:
    bindir = tmp_path / "bin"
    bindir.mkdir()
    for tool in TOOLS:
        src = shutil.which(tool)
        if tool == "python3" and src:  # resolve pyenv-style shims to the real interpreter
            src = subprocess.check_output([src, "-c", "import sys; print(sys.executable)"], text=True).strip()
        if src and tool not in missing:
            (bindir / tool).symlink_to(src)
    env = {"PATH": str(bindir), "RASPV_VENV": str(tmp_path / "venv"), "HOME": os.environ.get("HOME", "/tmp")}
    return subprocess.run([str(bindir / "bash"), str(ROOT / "tools/install.sh")], capture_output=True, text=True,
                          env=env, timeout=60)


@pytest.mark.parametrize("missing,expected", [
    ({"cmake"}, "cmake is missing (builds raspv_msgs); install it: sudo apt-get install cmake"),
    ({"c++", "g++"}, "a C++ compiler is missing (builds raspv_msgs); install it: sudo apt-get install g++"),
    ({"python3"}, "needs Python 3.10, 3.11 or 3.12"),
])
def test_missing_prerequisite_is_named_with_its_fix(tmp_path, missing, expected):
    if shutil.which("python3") is None:
        pytest.skip("no python3 on PATH to build the fake environment from")
    res = run_with_path_lacking(missing, tmp_path)
    assert res.returncode != 0
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], res.stderr
    assert not (tmp_path / "venv").exists()


def test_a_failed_pip_install_stops_the_install_and_marks_nothing_installed(tmp_path):
    """pip's error reaches the user and the stamp is not written (the next `make install` tries
    again), instead of the old environment staying with the dev requirements' tests skipping."""
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    real = subprocess.check_output([shutil.which("python3") or "python3", "-c", "import sys; print(sys.executable)"],
                                   text=True).strip()
    fake = venv / "bin" / "python"            # the real interpreter, with a pip that cannot find a pin
    fake.write_text(f'#!/bin/sh\nif [ "$1" = "-m" ] && [ "$2" = "pip" ]; then\n'
                    f'  echo "ERROR: No matching distribution found for torch==99.0"; exit 1\nfi\nexec {real} "$@"\n')
    fake.chmod(0o755)
    res = subprocess.run(["bash", str(ROOT / "tools/install.sh")], capture_output=True, text=True, timeout=60,
                         env={**os.environ, "RASPV_VENV": str(venv)})
    assert res.returncode != 0
    assert "No matching distribution found for torch==99.0" in res.stdout + res.stderr
    assert "pip install failed" in res.stderr
    assert not (venv / ".raspv-install-stamp").exists()
