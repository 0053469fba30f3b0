"""`raspv doctor` (issue 34): one screen of what this machine can do, within 3 s, every gap with
the command that fixes it; the checks on their own (cameras by USB vendor id, extras, shared
memory)."""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

from raspv_bringup import doctor
from raspv_common import extras

RASPV = [sys.executable, "-m", "raspv_bringup.cli"]


def test_doctor_answers_within_3_s_naming_each_check_and_a_fix_for_each_gap():
    t0 = time.perf_counter()
    out = subprocess.run([*RASPV, "doctor"], capture_output=True, text=True, timeout=60)
    elapsed = time.perf_counter() - t0
    assert out.returncode == 0, out.stdout + out.stderr          # this environment can run graphs
    assert "Traceback" not in out.stderr
    lines = out.stdout.splitlines()
    for name in ("Python", "environment", "ROS 2", "shared memory", "browser", "camera SDKs", "cameras",
                 "extras", "disk", "CPU"):
        assert any(line[5:].startswith(name) for line in lines), f"no {name!r} line:\n{out.stdout}"
    for i, line in enumerate(lines):                          # every gap is followed by its fix
        if line.startswith("  -- ") or line.startswith("  !! "):
            assert "fix: " in lines[i + 1], f"a gap without its fix: {line}\n{out.stdout}"
    print(out.stdout, f"({elapsed:.2f} s with the interpreter's start)")
    assert elapsed < 3.0 * 2, "raspv doctor must answer in about 3 s (x2 for a loaded machine)"


def test_cameras_are_found_by_usb_vendor_id(tmp_path):
    for name, vendor, product in (("1-1", "8086", "Intel(R) RealSense(TM) Depth Camera 435i"),
                                  ("1-2", "046d", "a webcam"), ("2-1", "03e7", None)):
        (tmp_path / name).mkdir()
        (tmp_path / name / "idVendor").write_text(vendor + "\n")
        if product:
            (tmp_path / name / "product").write_text(product + "\n")
    found = doctor.connected_cameras(tmp_path)
    assert found == ["Intel(R) RealSense(TM) Depth Camera 435i (1-1)", "Luxonis OAK (DepthAI) (2-1)"]


def test_a_missing_extra_is_a_gap_with_its_install_command(monkeypatch):
    real = doctor._found
    monkeypatch.setattr(doctor, "_found", lambda m: False if m == "ray" else real(m))
    check = doctor.check_extras()
    assert check.status == "gap" and "cluster" in check.detail
    assert extras.install_command("cluster") in check.fix


def test_a_missing_optional_module_raises_one_line_naming_the_extra(monkeypatch):
    monkeypatch.setitem(extras.OPTIONAL_MODULES, "raspv_no_such_module", ("cluster", "no-such-dist"))
    try:
        extras.require("raspv_no_such_module", "a sweep on a cluster")
    except extras.MissingExtra as exc:
        message = str(exc)
    else:
        raise AssertionError("require() imported a module that does not exist")
    assert "\n" not in message and "'cluster' extra" in message and extras.install_command("cluster") in message


def test_install_command_outside_a_checkout_takes_torch_from_the_cpu_index(monkeypatch):
    monkeypatch.setattr(extras, "in_checkout", lambda: False)
    assert "--index-url https://download.pytorch.org/whl/cpu" in extras.install_command("learn")
    assert extras.install_command("cameras").endswith("'raspv[cameras]'")


def test_the_stamp_lists_the_extras_make_install_put_in(tmp_path):
    assert extras.installed_extras(tmp_path) is None                          # not made by the script
    (tmp_path / extras.INSTALL_STAMP).write_text("abc123\n")
    assert extras.installed_extras(tmp_path) == set(extras.EXTRAS)            # the old all-in install
    (tmp_path / extras.INSTALL_STAMP).write_text("abc123\nlearn cluster\n")
    assert extras.installed_extras(tmp_path) == {"learn", "cluster"}
    (tmp_path / extras.INSTALL_STAMP).write_text("abc123\n-\n")
    assert extras.installed_extras(tmp_path) == set()


def test_shipped_folders_come_from_the_checkout_here_and_from_the_package_when_installed(monkeypatch, tmp_path):
    from raspv_common import shipped

    assert shipped.shipped_dir("config") == Path(shipped.__file__).resolve().parents[1] / "config"
    monkeypatch.setattr(shipped, "CHECKOUT_ROOT", tmp_path)                  # no checkout around
    assert shipped.shipped_dir("experiments") == shipped.PACKAGED / "experiments"
