"""Shared fixtures of the raspv_learn tests: a private cache for temporal tables and sprite banks."""
from __future__ import annotations

import pytest

pytest.importorskip("torch", reason="torch (requirements/learn.txt) is missing")


@pytest.fixture(autouse=True, scope="session")
def learn_cache(tmp_path_factory):
    """Temporal tables and sprite banks go to a per-session directory (not ~/.cache)."""
    path = tmp_path_factory.mktemp("raspv-learn-cache")
    mp = pytest.MonkeyPatch()
    mp.setenv("RASPV_CACHE_DIR", str(path))
    yield path
    mp.undo()
