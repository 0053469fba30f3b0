"""Shared fixtures of the raspv_learn tests: the session's private cache for temporal tables and
sprite banks."""
from __future__ import annotations

import pytest

pytest.importorskip("torch", reason="torch (requirements/learn.txt) is missing")


@pytest.fixture(autouse=True, scope="session")
def learn_cache(private_cache):
    """Temporal tables and sprite banks go to the session's private cache (not ~/.cache)."""
    return private_cache
