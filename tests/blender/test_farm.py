"""The farm recipe, run for real: the Flamenco job type (tools/flamenco/occlusion_analyze.js)
compiled offline as Flamenco Manager would (node, tools/flamenco/compile_job.js), and every
command of every task it authors run as a worker would, in dependency order: the chunks'
``blender -b ... occ.analyze(frame_start, frame_end)`` with bpy as a module
(blender_cli.py, with the extension installed from its zip in the worker's user folder) and
the ``python -m core merge``.  The merged report is byte for byte the one of a single
``occ.analyze`` over the whole range; with ``job`` BAKE_RENDER the merged bake is field for
field one Bake Shot's over the whole range."""

import json
import os
import shlex
import shutil
import subprocess

import pytest

from .harness import PYTHON, ROOT, build_zip, needs_bpy

pytestmark = [*needs_bpy, pytest.mark.skipif(shutil.which("node") is None, reason="node runs the job compiler")]

HERE = os.path.dirname(os.path.abspath(__file__))
JOB_TYPE = os.path.join(ROOT, "tools", "flamenco", "occlusion_analyze.js")
COMPILER = os.path.join(ROOT, "tools", "flamenco", "compile_job.js")
# the Manager's variables, as a worker gets them
VARIABLES = {"{blender}": [PYTHON, os.path.join(HERE, "blender_cli.py")], "{blenderArgs}": "-b -y"}


def compile_job(**settings):
    p = subprocess.run(["node", COMPILER, JOB_TYPE, json.dumps(settings)], capture_output=True, text=True,
                       timeout=60)
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout)["tasks"]


def argv(command):
    """A task's command as the worker runs it: ``{exe} {exeArgs} {argsBefore} {blendfile} {args}``
    for blender-render, ``{exe} {args}`` for exec."""
    p = command["parameters"]
    if command["name"] == "blender-render":
        assert p["exe"] == "{blender}" and p["exeArgs"] == "{blenderArgs}", p
        return [*VARIABLES["{blender}"], *shlex.split(VARIABLES["{blenderArgs}"]), *p["argsBefore"],
                p["blendfile"], *p["args"]]
    assert command["name"] == "exec", command
    return [p["exe"], *p["args"]]


def run_job(tasks, cwd, env):
    """Every command of every task, each task after its dependencies; -> {task: [rc, ...]}."""
    done, codes = set(), {}
    pending = list(tasks)
    while pending:
        task = next(t for t in pending if set(t["dependencies"]) <= done)
        pending.remove(task)
        codes[task["name"]] = []
        for command in task["commands"]:
            p = subprocess.run(argv(command), cwd=cwd, env=env, capture_output=True, text=True, timeout=300)
            assert p.returncode == 0, (task["name"], argv(command), p.stdout[-2000:], p.stderr[-2000:])
            codes[task["name"]].append(p.returncode)
        done.add(task["name"])
    return codes


@pytest.fixture(scope="module")
def farm(tmp_path_factory):
    """A worker's user folder with the extension installed, and the shot (frames 1-7)."""
    work = tmp_path_factory.mktemp("farm")
    env = {**os.environ, "BLENDER_USER_RESOURCES": str(work / "user")}
    blend = work / "shot.blend"
    p = subprocess.run([PYTHON, os.path.join(HERE, "farm_scene.py"), str(build_zip(work)), str(blend)],
                       cwd=str(work), env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0 and blend.exists(), (p.stdout[-2000:], p.stderr[-2000:])
    return work, env, blend


def test_flamenco_job_chunks_merge_to_the_whole_analysis(farm):
    work, env, blend = farm
    common = {"blendfile": str(blend), "frame_start": 1, "frame_end": 7, "checkout": ROOT, "python": PYTHON}
    chunked = compile_job(**common, chunk_size=2, output_dir=str(work / "chunked"))
    whole = compile_job(**common, chunk_size=100, output_dir=str(work / "whole"))
    assert [t["name"] for t in chunked] == ["analyze-1-2", "analyze-3-4", "analyze-5-6", "analyze-7-7", "merge"]
    assert chunked[-1]["dependencies"] == ["analyze-1-2", "analyze-3-4", "analyze-5-6", "analyze-7-7"]
    assert [t["name"] for t in whole] == ["analyze-1-7", "merge"]
    cwd = str(work / "worker")                     # a worker's own folder: not the checkout
    os.makedirs(cwd)
    run_job(chunked, cwd, env)
    run_job(whole, cwd, env)

    one_run = work / "whole" / "chunks" / "chunk_1_7"             # a single occ.analyze over 1-7
    for out in (work / "chunked", work / "whole"):
        assert (out / "report.json").read_bytes() == one_run.with_suffix(".json").read_bytes()
        assert (out / "report.csv").read_bytes() == one_run.with_suffix(".csv").read_bytes()
    report = json.loads((work / "chunked" / "report.json").read_text())
    assert [f["frame"] for f in report["frames"]] == list(range(1, 8)) and report["frames_analyzed"] == [[1, 7]]
    # the camera walks: what it sees changes along the range, so chunks differ from each other
    assert len({tuple(f["visible"]) for f in report["frames"]}) > 2, report["frames"]
    assert 0 < sum(o["frames_visible"] == 0 for o in report["objects"].values()) < len(report["objects"])


def test_flamenco_merge_refuses_a_stale_overlapping_chunk(farm):
    """A chunk left from another job in the chunks folder: one line, exit 2, nothing written."""
    work, env, blend = farm
    tasks = compile_job(blendfile=str(blend), frame_start=1, frame_end=4, chunk_size=2, checkout=ROOT,
                        python=PYTHON, output_dir=str(work / "stale"))
    run_job(tasks[:-1], str(work), env)
    chunks = work / "stale" / "chunks"
    shutil.copy(chunks / "chunk_3_4.json", chunks / "chunk_3_4_again.json")
    p = subprocess.run(argv(tasks[-1]["commands"][0]), cwd=str(work), env=env, capture_output=True, text=True,
                       timeout=120)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and "overlap" in lines[0], p.stderr
    assert not (work / "stale" / "report.json").exists()


def test_a_failed_chunk_fails_its_task(farm):
    """occ.analyze refusing (an empty frame range) makes the chunk's Blender exit non-zero:
    the farm sees the task fail instead of a merge of missing chunks."""
    work, env, blend = farm
    tasks = compile_job(blendfile=str(blend), frame_start=1, frame_end=2, checkout=ROOT, python=PYTHON,
                        output_dir=str(work / "failing"))
    cmd = argv(tasks[0]["commands"][0])
    cmd[-1] = cmd[-1].replace("frame_start=1, frame_end=2", "frame_start=5, frame_end=2")
    p = subprocess.run(cmd, cwd=str(work), env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 1 and "empty frame range" in p.stderr + p.stdout, (p.stdout[-2000:], p.stderr[-2000:])
    assert not (work / "failing" / "chunks").exists()


BAKE_FIELDS = ("frame_start", "frame_end", "width", "hidden", "cameras", "envelopes", "held", "fingerprint",
               "camera_digest", "summary", "shares")


def blender_expr(blend, expr, env, cwd):
    """``blender -b FILE --python-expr EXPR`` as a worker runs it; -> (rc, stdout + stderr)."""
    cmd = [*VARIABLES["{blender}"], "-b", "--addons", "bl_ext.user_default.occlusion_culled_viewport", str(blend),
           "--python-exit-code", "1", "--python-expr", expr]
    p = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=300)
    return p.returncode, p.stdout + p.stderr


def bake_of(blend, env, cwd, before=""):
    """The file's bake (``scene.occ_bake``), after ``before`` ran on it (not saved)."""
    rc, out = blender_expr(blend, before + "import bpy, json; b = bpy.context.scene.occ_bake; print('OCC_BAKE', "
                           f"json.dumps({{k: getattr(b, k) for k in {BAKE_FIELDS!r} + ('render_keys',)}}))",
                           env, cwd)
    assert rc == 0, out[-3000:]
    return json.loads(next(line for line in out.splitlines() if line.startswith("OCC_BAKE "))[9:])


def test_flamenco_bake_chunks_merge_to_the_whole_bake(farm):
    """job BAKE_RENDER: the shot baked in chunks on workers, merged into the file and applied
    to the render; the file's bake is exactly one Bake Shot's over the whole range."""
    work, env, blend = farm
    cwd = str(work / "worker_bake")
    os.makedirs(cwd)
    files = {}
    for name, size in (("chunked", 2), ("whole", 100)):
        files[name] = work / f"bake_{name}.blend"
        shutil.copy(blend, files[name])
        tasks = compile_job(blendfile=str(files[name]), frame_start=1, frame_end=7, chunk_size=size, checkout=ROOT,
                            python=PYTHON, output_dir=str(work / f"bake_{name}"), job="BAKE_RENDER")
        assert [t["name"] for t in tasks][-1] == "merge" and tasks[-1]["type"] == "blender"
        assert len(tasks) == (5 if size == 2 else 2), [t["name"] for t in tasks]
        run_job(tasks, cwd, env)
    one = bake_of(blend, env, cwd, "import bpy; assert bpy.ops.occ.bake_shot(frame_start=1, frame_end=7) == "
                                   "{'FINISHED'}; ")
    chunked, whole = bake_of(files["chunked"], env, cwd), bake_of(files["whole"], env, cwd)
    for f in BAKE_FIELDS:
        assert chunked[f] == one[f] and whole[f] == one[f], f
    assert chunked["render_keys"] and chunked["render_keys"] == whole["render_keys"]     # applied to the render
    assert one["summary"].startswith("frames 1-7: ") and one["hidden"], one

    # what the render reads: the keys hide per frame exactly what the bake hides
    rc, out = blender_expr(files["chunked"], (
        "import bpy, json; s = bpy.context.scene; rows = []\n"
        "for f in range(1, 8):\n"
        "    s.frame_set(f); rows.append(sorted(o.name for o in s.objects if o.hide_render))\n"
        "print('OCC_ROWS', json.dumps(rows))"), env, cwd)
    assert rc == 0, out[-3000:]
    rows = json.loads(next(line for line in out.splitlines() if line.startswith("OCC_ROWS "))[9:])
    assert any(rows) and len({tuple(r) for r in rows}) > 1, rows


def test_bake_merge_refuses_chunks_that_do_not_make_the_shot(farm):
    """A gap, an overlap, a chunk of an edited scene: one error each, exit 1, the file's bake untouched."""
    work, env, blend = farm
    cwd = str(work / "worker_refuse")
    os.makedirs(cwd)
    chunks = work / "refuse" / "chunks"
    tasks = compile_job(blendfile=str(blend), frame_start=1, frame_end=6, chunk_size=2, checkout=ROOT,
                        python=PYTHON, output_dir=str(work / "refuse"), job="BAKE")
    run_job(tasks[:-1], cwd, env)                          # the chunks, not the merge
    merge = f"import bpy; assert bpy.ops.occ.bake_merge(directory={str(chunks)!r}) == {{'FINISHED'}}"
    rc, out = blender_expr(blend, merge, env, cwd)       # (not saved)
    assert rc == 0, out[-3000:]
    cases = {
        "in no bake chunk": lambda: os.replace(chunks / "bake_3_4.json", work / "refuse" / "aside.json"),
        "overlap": lambda: (os.replace(work / "refuse" / "aside.json", chunks / "bake_3_4.json"),
                            shutil.copy(chunks / "bake_3_4.json", chunks / "bake_3_4_again.json")),
    }
    for why, make in cases.items():
        make()
        rc, out = blender_expr(blend, merge, env, cwd)
        assert rc == 1 and why in out, (why, out[-3000:])
    os.remove(chunks / "bake_3_4_again.json")
    edit = "import bpy; bpy.data.objects['wall'].location.z += 0.5; bpy.context.view_layer.update(); "
    rc, out = blender_expr(blend, edit + merge.split("; ", 1)[1], env, cwd)
    assert rc == 1 and "before an edit of this one" in out, out[-3000:]
    # in the same process, the refused merge leaves the scene's bake as it was (none)
    caught = (f"\ntry:\n    bpy.ops.occ.bake_merge(directory={str(chunks)!r})\nexcept RuntimeError as e:\n"
              "    print('OCC_REFUSED', e)\n")
    after = bake_of(blend, env, cwd, edit + caught)
    assert after["hidden"] == "" and after["fingerprint"] == "" and after["frame_end"] < after["frame_start"], after
