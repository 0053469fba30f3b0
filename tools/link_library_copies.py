"""Turn the copies of a shared library that wheels install into symlinks, as a system install
has them: ``lib/libX.so`` and ``lib/libX.so.2`` beside ``lib/libX.so.2.14.5``, byte-identical
(a wheel cannot carry symlinks). The ROS wheels put Fast DDS in the venv's ``lib/`` three times
(3 × 15.7 MB). Only files with the same stem, size and bytes are linked, each to the one with the
longest version; anything else is left alone. Usage: python tools/link_library_copies.py DIR"""
from __future__ import annotations

import filecmp
import re
import sys
from collections import defaultdict
from pathlib import Path

SONAME = re.compile(r"^(lib.+\.so)((?:\.\d+)*)$")


def link_copies(folder: Path) -> int:
    """Replace identical versioned copies in ``folder`` by relative symlinks; returns bytes saved."""
    chains: dict[str, list[Path]] = defaultdict(list)
    for path in folder.iterdir():
        m = SONAME.match(path.name)
        if m and path.is_file() and not path.is_symlink():
            chains[m.group(1)].append(path)
    saved = 0
    for paths in chains.values():
        target = max(paths, key=lambda p: (p.name.count("."), p.name))
        for path in paths:
            if path != target and path.stat().st_size == target.stat().st_size \
                    and filecmp.cmp(path, target, shallow=False):
                saved += path.stat().st_size
                path.unlink()
                path.symlink_to(target.name)
    return saved


if __name__ == "__main__":
    if len(sys.argv) != 2 or not Path(sys.argv[1]).is_dir():
        sys.exit("usage: python tools/link_library_copies.py DIR")
    print(f"{link_copies(Path(sys.argv[1])) / 1e6:.1f} MB of library copies linked")
