"""The packages' floors (docs/DEVELOPING.md): nothing imports a package above its own. The cores
and their nodes never import the launcher and test harness (raspv_bringup), the experiments or
the benchmarks (raspv_bench, the top floor); and no two packages import each other. Imports
inside functions count too (read from the source, nothing is imported)."""
from __future__ import annotations

import ast
from collections import defaultdict
from functools import lru_cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CORES = ["raspv_common", "raspv_spv", "raspv_perception", "raspv_nav", "raspv_sim", "raspv_camera", "raspv_bags",
         "raspv_hmd", "raspv_viz", "raspv_slam"]
ABOVE_THE_CORES = {"raspv_bringup", "raspv_experiments", "raspv_bench"}


@lru_cache(maxsize=None)
def imports_of(package: str) -> dict[str, set[str]]:
    """{module path: the raspv_* packages it imports}."""
    out: dict[str, set[str]] = defaultdict(set)
    for path in sorted((ROOT / package).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else []
            for name in names:
                top = name.split(".")[0]
                if top.startswith("raspv_") and top != package:
                    out[str(path.relative_to(ROOT))].add(top)
    return out


def test_the_cores_import_neither_the_launcher_nor_the_experiments_nor_the_benchmarks():
    wrong = {module: sorted(found & ABOVE_THE_CORES) for core in CORES
             for module, found in imports_of(core).items() if found & ABOVE_THE_CORES}
    assert not wrong, wrong


def test_only_the_benchmarks_import_the_benchmarks():
    packages = [p.name for p in ROOT.glob("raspv_*") if (p / "__init__.py").is_file() and p.name != "raspv_bench"]
    wrong = {module: "raspv_bench" for p in packages for module, found in imports_of(p).items() if "raspv_bench" in found}
    assert not wrong, wrong
    assert not any(found & {"raspv_experiments"} for found in imports_of("raspv_bringup").values())


def test_no_two_packages_import_each_other():
    packages = sorted(p.name for p in ROOT.glob("raspv_*") if (p / "__init__.py").is_file())
    uses = {p: set().union(*imports_of(p).values()) if imports_of(p) else set() for p in packages}
    both = sorted((a, b) for a in packages for b in uses[a] if b in uses and a in uses[b] and a < b)
    assert not both, both
