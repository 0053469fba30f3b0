"""The front page and the documentation site (issue 34): README ≤ 150 lines whose links all
resolve (files and anchors), and the MkDocs site built in strict mode (a broken link, anchor or
API reference fails the build)."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from raspv_bringup.testing import dev_requirement

ROOT = Path(__file__).resolve().parents[2]
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
FENCE = re.compile(r"^```.*?^```", re.S | re.M)


def _anchors(md: Path) -> set[str]:
    """Heading ids MkDocs gives a page (the toc extension's slugs, duplicates numbered)."""
    slugify = dev_requirement("markdown.extensions.toc", "markdown").slugify
    seen: dict[str, int] = {}
    out = set()
    for line in FENCE.sub("", md.read_text(encoding="utf-8")).splitlines():
        m = re.match(r"#{1,6}\s+(.*?)\s*#*$", line)
        if not m:
            continue
        text = re.sub(r"[`*]", "", re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", m.group(1)))
        slug = slugify(text, "-")
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f"{slug}_{n}")
    return out


def test_readme_is_a_short_front_page_whose_links_resolve():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 150, "the README is the front page: at most 150 lines; move details to docs/"
    broken = []
    for target in LINK.findall(FENCE.sub("", text)):
        if re.match(r"[a-z]+:", target):
            continue
        path, _, anchor = target.partition("#")
        file = ROOT / path if path else ROOT / "README.md"
        if not file.exists():
            broken.append(f"{target}: no such file")
        elif anchor and file.suffix == ".md" and anchor not in _anchors(file):
            broken.append(f"{target}: no heading with that anchor")
    assert not broken, broken


def test_every_docs_page_is_in_the_site_nav():
    yaml = dev_requirement("yaml", "pyyaml")
    nav = yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))["nav"]

    def pages(item):
        if isinstance(item, str):
            yield item
        elif isinstance(item, list):
            for x in item:
                yield from pages(x)
        elif isinstance(item, dict):
            for x in item.values():
                yield from pages(x)

    listed = set(pages(nav))
    on_disk = {p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs").rglob("*.md")}
    assert on_disk - listed == set(), "docs pages missing from mkdocs.yml's nav"
    generated = {"reference/parameters.md"}          # tools/docs/parameters.py writes it at build time
    assert listed - on_disk == generated, "nav entries without a page"


def test_site_builds_in_strict_mode(tmp_path):
    dev_requirement("mkdocs")
    dev_requirement("material", "mkdocs-material")
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    out = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-d", str(tmp_path / "site")],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    assert (tmp_path / "site" / "index.html").exists()
    assert (tmp_path / "site" / "speed" / "index.html").exists()
    # every parameter of every node kind is in the generated reference, in its kind's section
    from raspv_bringup.registry import NODES, schema_for

    html = (tmp_path / "site" / "reference" / "parameters" / "index.html").read_text(encoding="utf-8")
    sections = re.split(r'<h2 id="', html)[1:]
    by_kind = {sec.split('"', 1)[0]: sec for sec in sections}
    assert set(by_kind) == set(NODES)
    missing = [f"{kind}.{p.name}" for kind in NODES for p in schema_for(kind)
               if f"<code>{p.name}</code>" not in by_kind[kind]]
    assert not missing, f"parameters missing from the reference: {missing}"
    # the API reference is rendered from the docstrings (mkdocstrings), not left as directives
    api = (tmp_path / "site" / "reference" / "api" / "spv" / "index.html").read_text(encoding="utf-8")
    assert "::: raspv_spv" not in api and "PhospheneSimulator" in api
