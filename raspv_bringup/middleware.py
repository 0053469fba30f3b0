"""Middleware environment for RASPV processes (no rclpy).

Defaults: Fast DDS, discovery limited to this machine, and the shared-memory transport
profile ``config/fastdds_shm.xml`` for large images. Each default applies only when the
variable is not already set, so a user (or a graph file's ``launch.env``) can override it —
e.g. ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET`` and
``FASTRTPS_DEFAULT_PROFILES_FILE=config/fastdds_multihost.xml`` for several computers.
"""
from __future__ import annotations

from pathlib import Path
from typing import Mapping

from raspv_common import shipped

CONFIG_DIR = shipped.CONFIG_DIR
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "LP_NUM_THREADS")
SHM_PROFILE = CONFIG_DIR / "fastdds_shm.xml"
MULTIHOST_PROFILE = CONFIG_DIR / "fastdds_multihost.xml"


def middleware_env(base: Mapping[str, str], extra: Mapping[str, str] | None = None) -> dict[str, str]:
    """``base`` plus RASPV's middleware defaults (where unset) plus ``extra`` (always wins)."""
    env = dict(base)
    env.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    # One process per node already uses the cores; BLAS/OpenMP thread pools in every node
    # spin and fight over them (measured: a 35 ms numpy render took 130 % CPU with them).
    # LP_NUM_THREADS is Mesa llvmpipe's (the simulator's EGL renderer): spread over both cores
    # it delayed the spv display loop, 24 % dropped display frames in the demo vs 7 % with one.
    for var in THREAD_VARS:
        env.setdefault(var, "1")
    # Fast DDS 2.14 (Jazzy) reads FASTRTPS_DEFAULT_PROFILES_FILE; FASTDDS_… is the 3.x name.
    # Measured here, 640×480 rgb8 between two processes: p50 2.7 ms with the profile, 13 ms without.
    env.update(extra or {})
    profile = env.get("FASTRTPS_DEFAULT_PROFILES_FILE") or env.get("FASTDDS_DEFAULT_PROFILES_FILE") or str(SHM_PROFILE)
    env["FASTRTPS_DEFAULT_PROFILES_FILE"] = env["FASTDDS_DEFAULT_PROFILES_FILE"] = profile
    for key in ("FASTDDS_DEFAULT_PROFILES_FILE", "FASTRTPS_DEFAULT_PROFILES_FILE"):
        if key in env and env[key] and not Path(env[key]).is_absolute():
            candidate = CONFIG_DIR.parent / env[key]
            if candidate.exists():
                env[key] = str(candidate)
    return env


def apply_middleware_defaults() -> None:
    """Set the defaults in this process's environment (call before ``rclpy.init``)."""
    import os

    os.environ.update(middleware_env(os.environ))
