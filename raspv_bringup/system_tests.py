"""Tests that need a system package make CI fail instead of skipping (a pytest plugin; no rclpy).

The browser tests skip without Debian's chromium and the OpenNI2 camera tests without
libopenni2-0, which is right on a developer's machine but lets CI go green with them unrun.
With ``RASPV_REQUIRE_SYSTEM_TESTS=1`` (set by ``.ci/run``) such a skip is reported as a
failure naming the package; other skips (a missing Python extra, a test's own condition) stay
skips. ``tests/conftest.py`` imports the hook.
"""
from __future__ import annotations

import os

import pytest

REQUIRE_ENV = "RASPV_REQUIRE_SYSTEM_TESTS"
# words of the skip reasons of the tests that need a system package → that package
SYSTEM_PACKAGES = {"chromium": "chromium", "OpenNI2 library": "libopenni2-0"}


def required() -> bool:
    """Whether this run must not skip tests for a missing system package."""
    return os.environ.get(REQUIRE_ENV, "") not in ("", "0")


def missing_package(reason: str) -> str | None:
    """The system package a skip reason says is missing, or None."""
    return next((pkg for word, pkg in SYSTEM_PACKAGES.items() if word in reason), None)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if not report.skipped or not required() or not isinstance(report.longrepr, tuple):
        return
    reason = str(report.longrepr[2])
    package = missing_package(reason)
    if package is not None:
        report.outcome = "failed"
        report.longrepr = (f"{REQUIRE_ENV}=1 but this test was skipped: {reason} "
                           f"(install {package}, or unset {REQUIRE_ENV} to let it skip)")
