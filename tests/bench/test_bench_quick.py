"""Every `raspv bench NAME` runs in its quick mode (a smoke run in seconds): it completes and
prints its figures. Figures are not asserted here (no timing assertions in tests; the ratios
against peers are gated by tests/bench/test_bench_ratios.py); a bench that breaks is found here,
not by a user. `sim`, `qoe`, `twin` and `learned` have their own tests (they also check what their
quick runs print); `spv`, `scene`, `nav`, `budget` and `slam` run in full in the ratio gate."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from raspv_bench.bench_cli import BENCHES
from raspv_bringup.cli import main as cli_main

pytestmark = [pytest.mark.integration, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
OWN_TESTS = {"sim": "tests/sim/test_sim_bench_quick.py", "qoe": "tests/hmd/test_qoe_bench_quick.py",
             "twin": "tests/learn/test_benches.py", "learned": "tests/learn/test_benches.py",
             # run in full, their ratios gated, by the ratio gate (which `bench ratios` runs too)
             "spv": "tests/bench/test_bench_ratios.py", "scene": "tests/bench/test_bench_ratios.py",
             "nav": "tests/bench/test_bench_ratios.py", "budget": "tests/bench/test_bench_ratios.py",
             "slam": "tests/bench/test_bench_ratios.py",
             "ratios": "tests/bench/test_bench_ratios.py",
             "spv-kills": "tests/hardening/test_spv_kills.py"}
# what each bench prints when it measured something (a figure with its unit)
FIGURE = re.compile(r"\d+(\.\d+)?\s*(ms|s|Hz|x|MB|%|fps|frames/s)\b")


def test_every_bench_has_a_quick_mode_run_by_a_test(capsys):
    for name, test in OWN_TESTS.items():
        assert (ROOT / test).is_file(), f"bench {name}: {test} is gone"
    for name in BENCHES:      # `raspv bench NAME --help` in this process (the CLI's main; each bench's quick
        with pytest.raises(SystemExit) as exit_:      # run below starts it as a program)
            cli_main(["bench", name, "--help"])
        help_text = capsys.readouterr().out
        assert exit_.value.code == 0 and "--quick" in help_text, f"raspv bench {name} has no --quick"


@pytest.mark.parametrize("name", sorted(set(BENCHES) - set(OWN_TESTS)))
def test_bench_quick_mode_completes_and_prints_its_figures(name, ros_domain, tmp_path):
    env = {**os.environ, "ROS_DOMAIN_ID": str(ros_domain), "ROS_LOG_DIR": str(tmp_path / "ros_log")}
    res = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "bench", name, "--quick"], capture_output=True,
                         text=True, timeout=300, env=env, cwd=tmp_path)
    out = res.stdout + res.stderr
    print(out[-4000:])
    assert res.returncode == 0 and "Traceback" not in out, out[-4000:]
    assert len(FIGURE.findall(res.stdout)) >= 2, res.stdout[-3000:]
