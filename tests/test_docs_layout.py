"""The documentation stays true to the tree: the layout in docs/development.md names every
package and module that exists (and nothing that does not), and every relative link in the
README, the changelog and docs/*.md points to a file that exists, at a heading that exists."""

import glob
import os
import re

from tests.cli_helpers import ROOT

LAYOUT = os.path.join(ROOT, "docs", "development.md")
PAGES = sorted([os.path.join(ROOT, "README.md"), os.path.join(ROOT, "CHANGELOG.md")]
               + glob.glob(os.path.join(ROOT, "docs", "*.md")))
PACKAGES = ("core", "occ_addon", "sample_scenes")     # every module, however deep
TOP_LEVEL = ("tools", "tools/bench", "tools/checks", "tools/repro", "tests")   # every entry of each folder itself
SKIP = {"__pycache__"}


def _read(path):
    with open(path, encoding="utf-8") as f:
        return f.read()


def _modules():
    """Every ``.py`` under the packages, and every entry of tools/, of its sorted
    folders and of tests/, as a repository path (``core/cull/gpu.py``, ``tests/blender/``)."""
    found = []
    for package in PACKAGES:
        for folder, dirs, files in os.walk(os.path.join(ROOT, package)):
            dirs[:] = sorted(d for d in dirs if d not in SKIP and not d.startswith("."))
            rel = os.path.relpath(folder, ROOT).replace(os.sep, "/")
            found += [f"{rel}/{f}" for f in sorted(files) if f.endswith(".py")]
            found += [f"{rel}/{d}/" for d in dirs]
    for top in TOP_LEVEL:
        for name in sorted(os.listdir(os.path.join(ROOT, top))):
            if name in SKIP or name.startswith(".") or name.endswith(".pyc"):
                continue
            isdir = os.path.isdir(os.path.join(ROOT, top, name))
            found.append(f"{top}/{name}" + ("/" if isdir else ""))
    return found


def test_the_layout_names_every_package_and_module():
    layout = _read(LAYOUT)
    missing = [m for m in _modules() if f"`{m}`" not in layout and f"`{m.rstrip('/')}`" not in layout]
    assert not missing, f"docs/development.md's Layout does not name: {missing}"


def test_the_layout_names_nothing_that_is_gone():
    layout = _read(LAYOUT)
    section = layout[layout.index("\n## Layout\n"):]
    roots = "|".join(PACKAGES + TOP_LEVEL)
    named = re.findall(rf"`((?:{roots})/[\w./-]*)`", section)
    gone = [p for p in named if not os.path.exists(os.path.join(ROOT, p))]
    assert named and not gone, f"docs/development.md's Layout names what does not exist: {gone}"


def _slug(heading):
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[`*_]|\[([^\]]*)\]\([^)]*\)", r"\1", heading.strip()).lower()
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def _anchors(path):
    """Every anchor of a Markdown file's headings (``-1``, ``-2`` for repeats), fences skipped."""
    anchors, seen, fenced = set(), {}, False
    for line in _read(path).splitlines():
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and (m := re.match(r"#{1,6} (.+)", line)):
            slug = _slug(m.group(1))
            n = seen.get(slug, 0)
            seen[slug] = n + 1
            anchors.add(slug if n == 0 else f"{slug}-{n}")
    return anchors


def _links(text):
    """Every Markdown link target outside code fences and inline code."""
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    text = re.sub(r"`[^`\n]*`", "", text)
    return re.findall(r"\]\(([^)\s]+)\)", text)


def test_every_relative_link_resolves():
    broken = []
    for page in PAGES:
        for target in _links(_read(page)):
            if re.match(r"[a-z]+:", target):                 # http:, https:, mailto:
                continue
            path, _, anchor = target.partition("#")
            dest = os.path.normpath(os.path.join(os.path.dirname(page), path)) if path else page
            where = f"{os.path.relpath(page, ROOT)} -> {target}"
            if not os.path.exists(dest):
                broken.append(f"{where}: no such file")
            elif anchor and dest.endswith(".md") and anchor not in _anchors(dest):
                broken.append(f"{where}: no such heading")
    assert not broken, broken


def test_links_are_checked_at_all():
    """The link check finds the README's links into docs/ (a parser that finds none passes
    everything)."""
    links = _links(_read(os.path.join(ROOT, "README.md")))
    assert "docs/gui_city.png" in links
    assert any(link.startswith("docs/correctness.md#") for link in links)


def test_slugs_follow_github():
    assert _slug("What Blender shows: while the view moves, and under lights") == \
        "what-blender-shows-while-the-view-moves-and-under-lights"
    assert _slug("`core/cull/`: the strategies") == "corecull-the-strategies"
    assert _slug("On an NVIDIA H200") == "on-an-nvidia-h200"
