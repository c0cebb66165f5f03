"""The layer rules, relative imports included (ruff's banned imports, in core/ruff.toml,
core/gl/ruff.toml, core/lab/ruff.toml and occ_addon/ruff.toml, see only absolute ones):
no Blender in core/, OpenGL only in core/gl/, the lab in no shipped module."""

import ast
import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BLENDER = {"bpy", "mathutils", "bmesh", "gpu", "bpy_extras"}
GL = {"moderngl", "glcontext"}


def modules(package):
    """``(dotted name, path)`` of every module under ``package`` (a folder of ROOT)."""
    for folder, _, files in os.walk(os.path.join(ROOT, package)):
        for f in sorted(files):
            if f.endswith(".py"):
                path = os.path.join(folder, f)
                rel = os.path.relpath(path, ROOT)[:-3].replace(os.sep, ".")
                yield (rel[: -len(".__init__")] if rel.endswith(".__init__") else rel), path


def imported(name, path):
    """Every module ``path`` (module ``name``) imports, relative imports resolved."""
    with open(path, encoding="utf-8") as f:
        tree = ast.parse(f.read(), path)
    package = name if path.endswith("__init__.py") else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module
            out.add(mod)
            out.update(f"{mod}.{a.name}" for a in node.names)
    return out


def top(names):
    return {n.split(".")[0] for n in names}


@pytest.mark.parametrize("package", ["core", "occ_addon"])
def test_layer_rules_hold(package):
    broken = []
    for name, path in modules(package):
        got = imported(name, path)
        lab = {g for g in got if g == "core.lab" or g.startswith("core.lab.")}
        if name.startswith("core") and top(got) & BLENDER:
            broken.append((name, "Blender", sorted(top(got) & BLENDER)))
        if not name.startswith("core.gl") and top(got) & GL:
            broken.append((name, "OpenGL outside core/gl", sorted(top(got) & GL)))
        if lab and not (name.startswith("core.lab") or name == "core.__main__"):
            broken.append((name, "the lab", sorted(lab)))
    assert not broken


def test_relative_imports_resolve():
    """The resolver the rules rely on: core/__main__.py's ``from .lab.cli import main``."""
    assert "core.lab.cli" in imported("core.__main__", os.path.join(ROOT, "core", "__main__.py"))
    assert "occ_addon.identity" in imported("occ_addon.session", os.path.join(ROOT, "occ_addon", "session.py"))
