"""The README as a user reads it: its Python example runs, its commands exist (there and in
docs/), and it stays short, with install, the Blender quick start and the example first."""

import glob
import os
import re
import shlex
import subprocess
import sys

from core.lab.cli import build_parser
from tests.cli_helpers import ROOT

with open(os.path.join(ROOT, "README.md"), encoding="utf-8") as _f:
    README = _f.read()
DOCS = {os.path.relpath(p, ROOT): open(p, encoding="utf-8").read()
        for p in sorted(glob.glob(os.path.join(ROOT, "docs", "*.md")))}


def _section(title):
    start = README.index(f"\n## {title}\n")
    end = README.find("\n## ", start + 1)
    return README[start:end if end >= 0 else None]


def test_scripted_analysis_example_runs():
    blocks = re.findall(r"```python\n(.*?)```", _section("Scripted analysis"), flags=re.S)
    assert len(blocks) == 1
    p = subprocess.run([sys.executable, "-"], input=blocks[0], cwd=ROOT, capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, p.stderr
    last = p.stdout.strip().splitlines()[-1]
    assert re.match(r"\d+ of \d+ objects are never visible on this walk", last), p.stdout


def test_command_lines_name_real_options():
    """Every ``python -m core COMMAND ... --option`` the README or a docs/ page shows at the
    start of a line is an option of COMMAND."""
    sub = next(a for a in build_parser()._actions if a.dest == "command").choices
    seen = 0
    for page, text in {"README.md": README, **DOCS}.items():
        for command, rest in re.findall(r"^python -m core (\w+)(.*)$", text, flags=re.M):
            options = {o for a in sub[command]._actions for o in a.option_strings}
            for flag in re.findall(r"(--[a-z-]+)", rest):
                assert flag in options, (page, command, flag)
                seen += 1
    assert seen > 10


def test_the_readme_is_short_and_starts_with_what_a_user_needs():
    """At most 250 lines; install, the Blender quick start and the script example within
    its first two screens (about 120 lines)."""
    lines = README.splitlines()
    assert len(lines) <= 250, len(lines)
    head = "\n".join(lines[:120])
    for marker in ("\n## Quick start in Blender\n", "\n## Install\n", "\n## Scripted analysis\n", "```python\n"):
        assert marker in head, marker


def test_headless_blender_command_enables_the_extension():
    cmd = re.search(r"```sh\n(blender -b .*?)```", _section("Headless use"), flags=re.S).group(1)
    args = shlex.split(cmd.replace("\\\n", " "))
    assert args[args.index("--addons") + 1] == "bl_ext.user_default.occlusion_culled_viewport"
    assert args.index("--addons") < args.index("--python-expr")


def test_the_two_developer_commands_exist():
    with open(os.path.join(ROOT, "Makefile"), encoding="utf-8") as f:
        make = f.read()
    for target in ("demo", "test", "extension"):
        assert re.search(rf"^{target}:", make, flags=re.M), target
        assert f"make {target}" in README
    assert "$(VPY)" not in make.split("\nextension:")[1].split("\n\n")[0]     # no test venv for the zips
