"""``python -m core analyze`` and ``merge`` as a user runs them: a camera path analyzed whole,
in chunks merged, in processes (``--jobs``); bad input refused with one line and nothing
written.  The report module itself (core.analysis) on synthetic reports."""

import json
import os

import pytest

from core.analysis import build_report, frame_runs, merge_reports, read_report, source_block, write_report
from core.errors import OccError
from tests.cli_helpers import run

SCENE, RES = "city-small", "160x90"
PATH = ("--resolution", RES, "-q")


def analyze(out, *args):
    p = run("analyze", SCENE, *PATH, "--out", str(out), *args)
    assert p.returncode == 0, p.stderr[-2000:]
    return out


def files(folder):
    return (folder / "report.json").read_bytes(), (folder / "report.csv").read_bytes()


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Reports of the path's frames 0:9 of the small city: whole, and chunks 0:4 and 4:9."""
    d = tmp_path_factory.mktemp("analyze")
    return {"dir": d, "whole": analyze(d / "whole", "--frames", "0:9"),
            "c1": analyze(d / "c1", "--frames", ":4"), "c2": analyze(d / "c2", "--frames", "4:9")}


def test_chunks_merged_are_the_whole_run(runs):
    d = runs["dir"]
    p = run("merge", str(runs["c2"]), str(runs["c1"] / "report.json"), "--out", str(d / "merged"))
    assert p.returncode == 0, p.stderr
    assert files(d / "merged") == files(runs["whole"])
    report = json.loads((d / "merged" / "report.json").read_text())
    assert [f["frame"] for f in report["frames"]] == list(range(9)) and report["frames_analyzed"] == [[0, 8]]
    assert report["frame_count"] == 9 and report["rule"] == "seen"
    # the walk sees different things along the way: the merge has something to get wrong
    c1 = json.loads((runs["c1"] / "report.json").read_text())["objects"]
    assert any(o["frames_visible"] != c1[n]["frames_visible"] for n, o in report["objects"].items())
    never = [n for n, o in report["objects"].items() if o["frames_visible"] == 0]
    assert 0 < len(never) < len(report["objects"])
    header = (d / "merged" / "report.csv").read_text().splitlines()[0]
    assert header == "object,frames_visible,fraction,first_frame,last_frame"


def test_jobs_two_is_jobs_one(runs):
    out = analyze(runs["dir"] / "jobs2", "--frames", "0:9", "--jobs", "2")
    assert files(out) == files(runs["whole"])


def test_same_command_twice_same_report(runs):
    again = analyze(runs["dir"] / "again", "--frames", "0:9")
    assert files(again) == files(runs["whole"])


def test_report_on_stdout_without_out(wall_scene):
    path, cam, _ = wall_scene
    p = run("analyze", str(path), "--camera", str(cam), "-q")
    assert p.returncode == 0, p.stderr
    report = json.loads(p.stdout)
    assert report["frames"][0] == {"frame": 0, "visible": ["wall", "beside"]}      # "behind" is behind the wall
    assert "behind" in report["frames"][1]["visible"]                                # from the other side
    assert report["objects"]["back"] == {"frames_visible": 0, "first": None, "last": None}


def _bad(case, runs, wall_scene, tmp):
    """One bad command line -> (argv, words of its error)."""
    scene, cam, _ = wall_scene
    a_file = tmp / "a_file.txt"
    a_file.write_text("not a folder")
    broken = tmp / "broken.json"
    broken.write_text("{eye: ")
    out = str(tmp / "out")
    wall = ["analyze", str(scene), "--camera", str(cam), "--out", out]
    if case == "merge_other_scene":
        assert run("analyze", str(scene), "--camera", str(cam), "--frames", "1:2", "--resolution", RES,
                   "--out", str(tmp / "wall")).returncode == 0
    if case == "merge_other_settings":
        assert run("analyze", SCENE, "--frames", "4:9", "--resolution", "128x72", "-q",
                   "--out", str(tmp / "coarse")).returncode == 0
    if case == "merge_overlap":
        assert run("analyze", SCENE, "--frames", "3:6", *PATH, "--out", str(tmp / "late")).returncode == 0
    if case == "merge_not_a_report":
        (tmp / "chunks").mkdir()
        (tmp / "chunks" / "other.json").write_text('{"frames": []}')
    if case == "merge_empty_folder":
        (tmp / "chunks").mkdir()
    return {
        "unknown_scene": (["analyze", str(tmp / "nope.glb"), "--camera", str(cam), "--out", out],
                          "scene file not found"),
        "bad_camera_json": (["analyze", str(scene), "--camera", str(broken), "--out", out], "not valid JSON"),
        "frames_reversed": ([*wall, "--frames", "2:1"], "B must be greater than A"),
        "frames_words": ([*wall, "--frames", "a:b"], "--frames must look like A:B"),
        "frames_past_end": ([*wall, "--frames", "0:5"], "it has 2 frames (0:2)"),
        "jobs_zero": ([*wall, "--jobs", "0"], "--jobs: must be a whole number >= 1, got 0"),
        "display_below": ([*wall, "--display", "10x10"], "at least the query resolution"),
        "out_is_a_file": (["analyze", str(scene), "--camera", str(cam), "--out", str(a_file)], "is a file"),
        "merge_out_is_a_file": (["merge", str(runs["c1"]), "--out", str(a_file)], "is a file"),
        "merge_empty_folder": (["merge", str(tmp / "chunks"), "--out", out], "no report in"),
        "merge_missing": (["merge", str(tmp / "none"), "--out", out], "no report at"),
        "merge_not_a_report": (["merge", str(tmp / "chunks"), "--out", out], "not a mergeable report"),
        "merge_other_scene": (["merge", str(runs["c1"]), str(tmp / "wall"), "--out", out],
                              "chunks of different scenes"),
        "merge_other_settings": (["merge", str(runs["c1"]), str(tmp / "coarse"), "--out", out],
                                 "different settings: settings.resolution"),
        "merge_overlap": (["merge", str(runs["c1"]), str(tmp / "late"), "--out", out], "overlap"),
        "merge_twice": (["merge", str(runs["c1"]), str(runs["c1"]), "--out", out], "overlap"),
    }[case]


@pytest.mark.parametrize("case", [
    "unknown_scene", "bad_camera_json", "frames_reversed", "frames_words", "frames_past_end", "jobs_zero",
    "display_below", "out_is_a_file", "merge_out_is_a_file", "merge_empty_folder", "merge_missing",
    "merge_not_a_report", "merge_other_scene", "merge_other_settings", "merge_overlap", "merge_twice"])
def test_bad_input_is_one_line_and_writes_nothing(runs, wall_scene, tmp_path, case):
    argv, words = _bad(case, runs, wall_scene, tmp_path)
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    chunk = files(runs["c1"])
    p = run(*argv)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and lines[0].startswith("error: ") and words in lines[0], p.stderr
    assert "Traceback" not in p.stderr and p.stdout == ""
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before     # nothing written
    assert (tmp_path / "a_file.txt").read_text() == "not a folder" and files(runs["c1"]) == chunk


# --- the report module, on synthetic reports (no GL) -------------------------------------

NAMES = ["a", "b", "c", "d"]


def _report(frames, step=1, **settings):
    """A report of ``frames``: object k is seen in frame f when (f + k) % 3 == 0."""
    per_frame = [{"frame": f, "visible": [n for k, n in enumerate(NAMES) if (f + k) % 3 == 0]} for f in frames]
    return build_report(per_frame, NAMES, "seen", source_block("s", NAMES, {"frame_step": step, **settings}))


def test_any_split_of_a_range_merges_to_the_whole():
    whole = _report(range(1, 20, 2), step=2)
    for cut in range(1, 10):
        frames = list(range(1, 20, 2))
        parts = [_report(frames[:cut], step=2), _report(frames[cut:], step=2)]
        assert merge_reports(parts[::-1]) == whole
    assert whole["frames_analyzed"] == [[1, 19]] and whole["objects"]["d"]["first"] == 3


def test_a_gap_stays_a_gap():
    merged = merge_reports([_report(range(0, 3)), _report(range(5, 8))])
    assert merged["frames_analyzed"] == [[0, 2], [5, 7]] and merged["frame_count"] == 6


def test_frame_runs_follow_the_step():
    assert frame_runs([1, 3, 5, 10, 12], step=2) == [[1, 5], [10, 12]]
    assert frame_runs([4], step=3) == [[4, 4]]


@pytest.mark.parametrize("other, words", [
    (lambda: _report(range(3, 6)), "overlap"),
    (lambda: _report(range(5, 8), step=2), "different settings: settings.frame_step"),
    (lambda: {**_report(range(5, 8)), "source": source_block("t", NAMES, {"frame_step": 1})}, "different scenes"),
    (lambda: {**_report(range(5, 8)), "source": source_block("s", NAMES[:3], {"frame_step": 1})},
     "different objects"),
])
def test_merge_refuses_with_a_line_naming_both(other, words):
    with pytest.raises(OccError, match=words) as e:
        merge_reports([_report(range(0, 4)), other()], ["first.json", "second.json"])
    assert "first.json" in str(e.value) and "second.json" in str(e.value) and "\n" not in str(e.value)


def test_written_report_reads_back_and_an_edit_is_refused(tmp_path):
    r = _report(range(0, 6))
    path, csv = write_report(r, str(tmp_path / "r.json"))
    assert read_report(path) == r and os.path.basename(csv) == "r.csv"
    assert sorted(os.listdir(tmp_path)) == ["r.csv", "r.json"]          # no temporary left
    edited = json.loads(open(path).read())
    edited["objects"]["a"]["frames_visible"] += 1
    (tmp_path / "r.json").write_text(json.dumps(edited))
    with pytest.raises(OccError, match="'objects' does not match its frames"):
        read_report(path)


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    """``--bake`` reports of frames 0:6 of the small city: whole, and chunks 0:3 and 3:6."""
    d = tmp_path_factory.mktemp("bake")
    return {"dir": d, "whole": analyze(d / "whole", "--frames", "0:6", "--bake"),
            "c1": analyze(d / "c1", "--frames", ":3", "--bake"), "c2": analyze(d / "c2", "--frames", "3:6", "--bake"),
            "display": analyze(d / "display", "--frames", "0:6", "--bake", "--display", "640x360")}


def test_baked_chunks_merge_to_the_whole_bake_and_never_to_a_point_report(baked, runs):
    d = baked["dir"]
    p = run("merge", str(baked["c1"]), str(baked["c2"]), "--out", str(d / "merged"))
    assert p.returncode == 0, p.stderr
    assert files(d / "merged") == files(baked["whole"])
    report = json.loads((d / "merged" / "report.json").read_text())
    assert report["source"]["settings"]["within_frame"] is True
    p = run("merge", str(baked["c1"]), str(runs["c2"]), "--out", str(d / "mixed"))
    assert p.returncode == 2 and "within_frame" in p.stderr and not (d / "mixed").exists()


@pytest.mark.parametrize("report,truth", [("whole", (160, 90)), ("display", (640, 360))])
def test_a_baked_frame_keeps_everything_seen_on_the_way_to_the_next_frame(baked, runs, report, truth):
    """Every view between two path frames (the eye on the segment, the frame turned part of
    the way) sees only what the baked frame keeps, at the query's resolution and, baked
    with ``--display``, at the display's; a point pass of the frame's own view keeps less
    (the check can fail)."""
    import numpy as np

    import sample_scenes
    from core import Camera, Culler, load_scene
    from core.camera import cameras_from_json
    from core.lab.analyze import frame_envelope
    scene = load_scene(str(sample_scenes.scene_path("city", small=True)))
    cams = cameras_from_json(sample_scenes.default_camera_path("city", small=True))
    frames = json.loads((baked[report] / "report.json").read_text())["frames"]
    point = json.loads((runs["whole"] / "report.json").read_text())["frames"]
    names = list(scene.names)
    missed, point_missed = [], 0
    with Culler(scene, truth) as culler:
        for i in range(5):
            a, b = cams[i], cams[i + 1]
            env = frame_envelope(cams, i)
            kept = set(frames[i]["visible"])
            ra, rb = a.view[:3, :3].T, b.view[:3, :3].T    # camera-to-world axes
            rel = rb @ ra.T                                 # the turn from one frame to the next
            angle = np.arccos(np.clip((np.trace(rel) - 1.0) / 2.0, -1.0, 1.0))
            axis = np.array([rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]])
            axis = axis / max(np.linalg.norm(axis), 1e-300)
            k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
            for t in np.linspace(0.0, 1.0, 6):
                eye = (1.0 - t) * a.eye + t * b.eye
                rot = (np.eye(3) + np.sin(t * angle) * k + (1.0 - np.cos(t * angle)) * (k @ k)) @ ra
                view = np.eye(4)
                view[:3, :3] = rot.T
                view[:3, 3] = -rot.T @ eye
                between = Camera.from_matrices(view, a.projection)
                assert env is None or env.holds(a, between)
                seen = {names[k] for k in np.flatnonzero(culler.truth(between))}
                missed += sorted(seen - kept)
                point_missed += len(seen - set(point[i]["visible"]))
    assert missed == []
    assert point_missed > 0


def test_a_frame_envelope_holds_for_no_lens_change_and_no_wide_turn():
    import numpy as np

    from core import Camera
    from core.lab.analyze import frame_envelope
    a = Camera.look_at((0, 0, 0), (1, 0, 0), (0, 0, 1), 60.0)
    assert frame_envelope([a], 0) is None                           # the last frame: its own view
    assert frame_envelope([a, a], 0) is None                        # no motion: its own view
    assert frame_envelope([a, Camera.look_at((0, 0, 0), (1, 0, 0), (0, 0, 1), 50.0)], 0) is False
    assert frame_envelope([a, Camera.look_at((0, 0, 0), (-1, 0.1, 0), (0, 0, 1), 60.0)], 0) is False
    env = frame_envelope([a, Camera.look_at((1, 0, 0), (2, 1, 0), (0, 0, 1), 60.0)], 0)
    assert np.isclose(env.distance, 1.0) and np.isclose(env.angle_deg, 45.0) and not env.any_roll
