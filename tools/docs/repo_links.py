"""MkDocs hook: links from docs pages to repository files (``../raspv_spv/renderer.py``).

Such a link points outside ``docs/``, so MkDocs cannot resolve it. This hook checks that the
file exists (a missing one fails the build: the link is broken) and publishes it with the site
under ``repo/<path>``, rewriting the link to it. A link to the README points at the home page.
"""
from __future__ import annotations

import re
from pathlib import Path

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File, InclusionLevel

# [text](target) and ![alt](target) with a relative target (no scheme, not an anchor alone)
LINK = re.compile(r"(!?\[[^\]]*\]\()(?!https?:|mailto:|#)([^)\s]+)(\))")
PREFIX = "repo/"

_repo_files: set[str] = set()


def _outside_target(page_src: Path, target: str, docs_dir: Path, root: Path) -> str | None:
    """The repository path a link escaping docs/ names, or None for an ordinary link."""
    path, _, _anchor = target.partition("#")
    if not path:
        return None
    resolved = (page_src.parent / path).resolve()
    if resolved.is_relative_to(docs_dir):
        return None
    if not resolved.is_relative_to(root):
        raise PluginError(f"{page_src.relative_to(root)}: link '{target}' leaves the repository")
    return resolved.relative_to(root).as_posix()


def on_files(files, config):
    """Add every repository file a page links to as a static file under repo/."""
    docs_dir = Path(config["docs_dir"]).resolve()
    root = docs_dir.parent
    site_dir = config["site_dir"]
    _repo_files.clear()
    for md in sorted(docs_dir.rglob("*.md")):
        for _, target, _ in LINK.findall(md.read_text(encoding="utf-8")):
            rel = _outside_target(md, target, docs_dir, root)
            if rel is None or rel == "README.md":
                continue
            if not (root / rel).is_file():
                raise PluginError(f"{md.relative_to(root)}: link '{target}' names a missing file {rel}")
            if rel not in _repo_files:
                _repo_files.add(rel)
                files.append(File(PREFIX + rel, src_dir=str(root / "__repo_links__"), dest_dir=site_dir,
                                  use_directory_urls=False))
                published = files.get_file_from_path(PREFIX + rel)
                published.abs_src_path = str(root / rel)
                published.inclusion = InclusionLevel.NOT_IN_NAV
    return files


def on_page_markdown(markdown, page, config, files):
    """Point links to repository files at their published copies."""
    if page.file.abs_src_path is None:      # a generated page (the parameter reference)
        return markdown
    docs_dir = Path(config["docs_dir"]).resolve()
    root = docs_dir.parent
    page_src = Path(page.file.abs_src_path)
    depth = len(Path(page.file.src_uri).parts) - 1

    def rewrite(match: re.Match) -> str:
        opening, target, closing = match.groups()
        rel = _outside_target(page_src, target, docs_dir, root)
        if rel is None:
            return match.group(0)
        _, hash_, anchor = target.partition("#")
        new = "index.md" if rel == "README.md" else PREFIX + rel
        return f"{opening}{'../' * depth}{new}{hash_}{anchor}{closing}"

    return LINK.sub(rewrite, markdown)
