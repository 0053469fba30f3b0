"""Build a configuration's slow parts in another process, into the disk caches (no ROS).

Sprite banks of tissue models and temporal tables take seconds to build the first time. A node
that must keep its display at rate meanwhile should not build them in one of its own threads:
besides the CPU, numpy and scipy hold Python's GIL for part of the work, and every such moment
delays the display thread. :func:`prebuild_in_subprocess` runs :func:`prebuild` in a separate
Python process at a lower CPU priority; it writes the sprite bank and the temporal table to
their disk caches (:mod:`raspv_spv.sprite_models`, :mod:`raspv_spv.temporal_lut`), so building
the simulator in the node afterwards only reads them (milliseconds).

    python -m raspv_spv.prebuild < config.pickle     # what the subprocess runs
"""
from __future__ import annotations

import os
import pickle
import subprocess
import sys
from pathlib import Path

from raspv_spv.config import SpvConfig
from raspv_spv.phosphene_map import PhospheneMap
from raspv_spv.sprite_models import build_sprite_bank, cached_bank_path
from raspv_spv.temporal_lut import cached_table_path, load_table

PREBUILD_NICENESS = 10
PACKAGE_ROOT = str(Path(__file__).resolve().parent.parent)


class PrebuildError(RuntimeError):
    """The subprocess could not build the configuration (its last error line)."""


def missing_from_cache(config: SpvConfig, phosphene_map: PhospheneMap) -> list[str]:
    """What ``config`` would have to build: "sprites" (a tissue model's bank not in the disk
    cache) and/or "temporal table" (the look-up table's; the recursive model builds its own
    tables in ~0.3 s, in memory)."""
    out = []
    path = cached_bank_path(phosphene_map, config.sprite_spec())
    if path is not None and not path.exists():
        out.append("sprites")
    if config.temporal and config.temporal_update == "lut" and not cached_table_path(config.lut_config()).exists():
        out.append("temporal table")
    return out


def prebuild(config: SpvConfig) -> None:
    """Build ``config``'s sprite bank and temporal table into their disk caches."""
    phosphene_map = PhospheneMap.build(config.map_spec())
    build_sprite_bank(phosphene_map, config.sprite_spec())
    if config.temporal and config.temporal_update == "lut":
        load_table(config.lut_config())


def prebuild_in_subprocess(config: SpvConfig, timeout: float = 600.0) -> None:
    """Run :func:`prebuild` in a separate, lower-priority Python process and wait for it;
    raises :class:`PrebuildError` with the reason if it fails."""
    try:
        # run from the directory this package is in: ``-m`` puts the working directory first on
        # the path, and another checkout there must not be imported instead of this one
        proc = subprocess.run([sys.executable, "-m", "raspv_spv.prebuild"], input=pickle.dumps(config),
                              capture_output=True, timeout=timeout, env=dict(os.environ), cwd=PACKAGE_ROOT)
    except subprocess.TimeoutExpired:
        raise PrebuildError(f"building {config.device.name} took more than {timeout:.0f} s") from None
    if proc.returncode != 0:
        lines = proc.stderr.decode(errors="replace").strip().splitlines()
        raise PrebuildError(lines[-1] if lines else f"prebuild exited with code {proc.returncode}")


def main() -> int:
    try:
        os.setpriority(os.PRIO_PROCESS, 0, PREBUILD_NICENESS)
    except (AttributeError, OSError):
        pass
    try:
        config = pickle.loads(sys.stdin.buffer.read())
        if not isinstance(config, SpvConfig):
            raise TypeError(f"expected a pickled SpvConfig, got {type(config).__name__}")
        prebuild(config)
    except Exception as exc:                       # one line for the parent to report
        print(f"{type(exc).__name__}: {exc}".splitlines()[0], file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
