"""Progress of the long commands: a bar on a terminal's stderr, short lines elsewhere, never on stdout.

The terminal is a real pseudo-terminal (``pty``) on stderr, stdout a pipe, as in
``python -m core bench ... --json > out.json`` typed at a shell.
"""

import fcntl
import json
import os
import pty
import re
import struct
import subprocess
import sys
import termios
import threading

import pytest

from core.lab.tradeoff import KNOBS
from core.settings import PRESETS
from tests.cli_helpers import ROOT, run

NO_TQDM = "import sys; sys.modules['tqdm'] = None; from core.lab.cli import main; sys.exit(main(sys.argv[1:]))"


def run_on_terminal(*args, tqdm=True):
    """``python -m core ARGS`` with stderr on a 100-column pty: (exit status, stdout, what the pty got)."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
    head = ["-m", "core"] if tqdm else ["-c", NO_TQDM]
    p = subprocess.Popen([sys.executable, *head, *args], cwd=ROOT, stdout=subprocess.PIPE, stderr=slave)
    os.close(slave)
    chunks = []

    def pump():                              # read as it comes: a full pty would stall the child
        while True:
            try:
                data = os.read(master, 4096)
            except OSError:                  # EIO: the child closed its end
                return
            if not data:
                return
            chunks.append(data)

    reader = threading.Thread(target=pump)
    reader.start()
    out = p.stdout.read()
    p.wait(timeout=300)
    reader.join(timeout=10)
    os.close(master)
    return p.returncode, out.decode(), b"".join(chunks).decode(errors="replace")


def bar_drawn(err, tqdm):
    """A bar redrawn in place: carriage returns, and tqdm's percent bar or the plain one."""
    return "\r" in err and (("%|" in err) if tqdm else re.search(r"\[#+-*\] \d+/\d+ (steps|frames)", err) is not None)


def progress_lines(err):
    return [ln for ln in err.splitlines() if ln.strip().startswith("[")]


@pytest.fixture(params=["tqdm", "plain"])
def with_tqdm(request):
    if request.param == "tqdm":
        pytest.importorskip("tqdm")
    return request.param == "tqdm"


def test_bench_bar_on_a_terminal_and_pure_json_on_stdout(wall_scene, with_tqdm):
    path, cam, _ = wall_scene
    rc, out, err = run_on_terminal("bench", str(path), "--camera", str(cam), "--strategies", "vfc,om_multi",
                                   "--resolution", "48x32", "--json", tqdm=with_tqdm)
    assert rc == 0, err
    assert set(json.loads(out)["strategies"]) == {"vfc", "om_multi"}
    assert bar_drawn(err, with_tqdm), repr(err)
    assert "bench wall" in err
    assert not progress_lines(err)          # a bar, not the lines meant for logs


def test_multi_frame_cull_bar_and_its_text_output(wall_scene, with_tqdm):
    path, cam, _ = wall_scene
    rc, out, err = run_on_terminal("cull", str(path), "--camera", str(cam), "--resolution", "48x32",
                                   tqdm=with_tqdm)
    assert rc == 0, err
    assert out.startswith("frame 0: 2 of 4 visible") and "\r" not in out
    assert bar_drawn(err, with_tqdm), repr(err)


def test_quiet_on_a_terminal_draws_nothing(wall_scene):
    path, cam, _ = wall_scene
    rc, out, err = run_on_terminal("bench", str(path), "--camera", str(cam), "--strategies", "vfc",
                                   "--resolution", "48x32", "--json", "--quiet")
    assert rc == 0, err
    assert json.loads(out)["frames"] == 2 and err == ""


def test_bench_without_terminal_prints_one_short_line_per_step(wall_scene):
    path, cam, _ = wall_scene
    p = run("bench", str(path), "--camera", str(cam), "--strategies", "vfc,stopwait,om_multi",
            "--resolution", "48x32", "--json")
    assert p.returncode == 0, p.stderr
    assert set(json.loads(p.stdout)["strategies"]) == {"vfc", "stopwait", "om_multi"}
    assert "\r" not in p.stderr and "\x1b" not in p.stderr
    lines = p.stderr.splitlines()
    assert progress_lines(p.stderr) == lines and len(lines) == 4, p.stderr   # loading, then each strategy
    assert lines[0].startswith("  [1/4] wall: loaded 4 objects") and "om_multi" in lines[3]
    assert max(len(ln) for ln in lines) <= 100
    text = run("bench", str(path), "--camera", str(cam), "--strategies", "vfc", "--resolution", "48x32")
    assert text.stdout.startswith("== wall ==") and len(progress_lines(text.stderr)) == 2   # progress off stdout


def test_quiet_and_single_frame_cull_print_no_progress(wall_scene, tmp_path):
    path, cam, _ = wall_scene
    p = run("bench", str(path), "--camera", str(cam), "--strategies", "vfc", "--resolution", "48x32",
            "--json", "-q")
    assert p.returncode == 0 and p.stderr == "" and json.loads(p.stdout)["frames"] == 2
    one = tmp_path / "one.json"
    one.write_text(json.dumps(json.loads(cam.read_text())["frames"][0]))
    p = run("cull", str(path), "--camera", str(one), "--resolution", "48x32", "--json")
    assert p.returncode == 0 and p.stderr == "" and len(json.loads(p.stdout)["frames"]) == 1


def test_long_cull_without_terminal_prints_at_most_ten_lines(wall_scene, tmp_path):
    path, cam, _ = wall_scene
    many = tmp_path / "many.json"
    many.write_text(json.dumps({"frames": json.loads(cam.read_text())["frames"] * 20}))
    p = run("cull", str(path), "--camera", str(many), "--resolution", "32x24", "--json")
    assert p.returncode == 0, p.stderr
    assert len(json.loads(p.stdout)["frames"]) == 40
    lines = p.stderr.splitlines()
    assert progress_lines(p.stderr) == lines and 1 <= len(lines) <= 10, p.stderr
    assert lines[-1].startswith("  [40/40] frame 39")


def test_tradeoff_progress_json_and_text(wall_scene):
    path, cam, _ = wall_scene
    args = ("tradeoff", str(path), "--camera", str(cam), "--display", "48x32", "--frames", "2", "--repeats", "1",
            "--knobs", "bounds")
    steps = 1 + len(PRESETS) + len(KNOBS["bounds"])
    p = run(*args, "--json")
    assert p.returncode == 0, p.stderr
    assert set(json.loads(p.stdout)["knobs"]) == {"bounds"}
    assert len(progress_lines(p.stderr)) == steps, p.stderr            # and the header line
    assert progress_lines(p.stderr)[-1].startswith(f"  [{steps}/{steps}] bounds=exact")
    # text: the row of each setting on stdout is its line; no second line for it on stderr
    t = run(*args)
    assert t.returncode == 0 and t.stderr == "", t.stderr
    assert "bounds" in t.stdout and t.stdout.rstrip().splitlines()[-1].startswith("Pareto front:")
    rc, out, err = run_on_terminal(*args, "--json")
    assert rc == 0 and json.loads(out)["repeats"] == 1
    assert "tradeoff wall" in err and "\r" in err


def test_demo_on_a_terminal(tmp_path):
    """``make demo``'s command (two frames, small resolution): a bar on stderr, the table on stdout."""
    pytest.importorskip("matplotlib")
    rc, out, err = run_on_terminal("demo", "--frames", "2", "--resolution", "48x32", "--out", str(tmp_path))
    assert rc == 0, err
    assert out.startswith("== city ==") and "report written to" in out and "\r" not in out
    assert "demo" in err and "\r" in err
    assert (tmp_path / "README.txt").exists()


def test_core_imports_without_tqdm():
    """The Blender extension bundles no tqdm: nothing in core may import it up front."""
    code = ("import sys; sys.modules['tqdm'] = None\n"
            "import core, core.lab.cli, core.lab.jobs, core.lab.reports, core.lab.tradeoff, core.lab.bench\n"
            "from core.lab.jobs import Progress\n"
            "import io; s = io.StringIO(); p = Progress(2, 't', stream=s); p.step('a'); p.step('b'); p.close()\n"
            "print(s.getvalue(), end='')")
    p = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stdout == "  [1/2] a\n  [2/2] b\n"
    p = subprocess.run([sys.executable, "-c", "import sys, core.lab.cli, core.lab.reports, core.lab.tradeoff; "
                        "print('tqdm' in sys.modules)"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.stdout.strip() == "False", p.stderr
