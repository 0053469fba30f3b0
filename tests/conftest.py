"""Fixtures shared by the whole suite (harness code in raspv_bringup/testing.py).

- ``ros_domain``: this session's private ROS_DOMAIN_ID (claimed before anything imports rclpy).
- ``probe``: an rclpy node spinning in the test process (wait_for_message, collect, publish,
  set_params).
- ``private_cache``: a per-session RASPV_CACHE_DIR (temporal tables, sprite banks; not ~/.cache),
  for the folders whose tests build them (their conftest makes it autouse).
- ``graph``: start a graph (dict or YAML path) with ``raspv launch`` in a subprocess; stopped with
  SIGINT at the end of the test, failing it if any process is left behind or, unless the test
  stopped it itself (and checked ``g.stop()``'s code), if the launcher's exit code is not 0.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from raspv_bringup.system_tests import pytest_runtest_makereport  # noqa: F401  (skips for chromium/OpenNI2 fail in CI)
from raspv_bringup.testing import Probe, RunningGraph, claim_private_domain

DOMAIN_ID = claim_private_domain()
DATA_DIR = Path(__file__).parent / "data"


@pytest.fixture(scope="session")
def ros_domain() -> int:
    return DOMAIN_ID


@pytest.fixture(scope="session")
def data_dir() -> Path:
    return DATA_DIR


@pytest.fixture(scope="session")
def private_cache(tmp_path_factory):
    """A per-session cache directory for temporal tables and sprite banks (built once per session)."""
    path = tmp_path_factory.mktemp("raspv-cache")
    mp = pytest.MonkeyPatch()
    mp.setenv("RASPV_CACHE_DIR", str(path))
    yield path
    mp.undo()


@pytest.fixture(scope="session")
def session_probe(ros_domain):
    p = Probe()
    yield p
    p.close()


@pytest.fixture
def probe(session_probe):
    """The session's probe node; what a test publishes or subscribes through it ends with the
    test (a latched message left by one test would reach the next test's nodes)."""
    yield session_probe
    session_probe.release()


@pytest.fixture
def graph(tmp_path, ros_domain):
    started: list[RunningGraph] = []

    def start(spec, overrides=None, env=None) -> RunningGraph:
        g = RunningGraph(spec, tmp_path, overrides, env)
        started.append(g)
        return g

    yield start
    errors = []
    for g in started:
        stopped_by_test = g.returncode is not None       # the test stopped it and had its exit code to check
        try:
            code = g.stop()
        except AssertionError as exc:
            errors.append(str(exc))
            continue
        if not stopped_by_test and code != 0:
            errors.append(f"graph {g.path.name} ended with exit code {code} (0 after a requested stop: a node died "
                          f"or the launcher failed):\n{g.output[-3000:]}")
    if errors:
        pytest.fail("\n".join(errors))
