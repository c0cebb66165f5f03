"""The analysis report: which objects a camera path sees, frame by frame; written, read
back and merged from chunks.

One module for every writer and reader of the report: ``python -m core analyze`` and
``merge`` (:mod:`core.lab.analyze`) and the add-on's ``occ.analyze``
(``occ_addon/analysis.py``).  Numpy only (no bpy, no GL), so the extension ships it.

A report is a JSON object (docs/scripting.md, "Report schema")::

    {"frames": [{"frame": f, "visible": [name, ...]}, ...],        # ascending frames
     "objects": {name: {"frames_visible": k, "first": f, "last": f}, ...},   # sorted by name
     "frame_count": n, "rule": "seen",
     "frames_analyzed": [[first, last], ...],    # runs of frames `frame_step` apart, inclusive
     "source": {"scene": ..., "objects": n, "names_sha1": ..., "settings": {...}, ...}}

and a CSV beside it (:data:`CSV_COLUMNS`).  Answers are per frame and history-free (a
frame's visible set does not depend on the frames analyzed before it), so a report of
several chunks merged (:func:`merge_reports`) is exactly the report of one run over all
their frames.  ``source`` is the chunks' identity: a merge refuses chunks whose sources
differ (another scene, other objects, other settings) or whose frames overlap.  Nothing
in a report depends on timing: the same input gives the same bytes.
"""

import csv
import hashlib
import io
import json
import os
import tempfile
from collections.abc import Iterable, Sequence

from .errors import OccError

KEYS = ("frames", "objects", "frame_count", "rule", "frames_analyzed", "source")
SOURCE_KEYS = ("scene", "objects", "names_sha1", "settings")
CSV_COLUMNS = ("object", "frames_visible", "fraction", "first_frame", "last_frame")
REPORT_NAME = "report.json"      # what `--out DIR` holds (the CSV beside it: report.csv)


def names_sha1(names: Iterable[str]) -> str:
    """A digest of the object names, in the order given (one name a line, UTF-8)."""
    return hashlib.sha1("\n".join(names).encode("utf-8")).hexdigest()


def source_block(scene: str, names: Sequence[str], settings: dict, **more) -> dict:
    """The identity of an analysis: the scene's name, its object count and names'
    digest, the settings that change an answer (strategy, resolutions, rule, frame step,
    ...) and anything else (``more``: e.g. the camera path's digest) two chunks of one
    analysis share."""
    return {"scene": str(scene), "objects": len(names), "names_sha1": names_sha1(names),
            "settings": dict(settings), **more}


def frame_runs(frames: Sequence[int], step: int = 1) -> list[list[int]]:
    """Ascending ``frames`` as inclusive runs ``[first, last]`` of frames ``step`` apart."""
    runs = []
    for f in frames:
        if runs and f == runs[-1][1] + step:
            runs[-1][1] = f
        else:
            runs.append([f, f])
    return runs


def build_report(per_frame: Sequence[dict], names: Iterable[str], rule: str, source: dict) -> dict:
    """The report of ``per_frame`` (``{"frame": f, "visible": [names]}``, in ascending
    frames): ``names`` are every object the analysis knows (the never-seen ones too;
    a name seen in a frame is added when missing)."""
    frames = [{"frame": int(fr["frame"]), "visible": list(fr["visible"])} for fr in per_frame]
    numbers = [fr["frame"] for fr in frames]
    if any(b <= a for a, b in zip(numbers, numbers[1:], strict=False)):
        raise OccError(f"report frames must ascend without repeats, got {numbers[:10]}...")
    count, first, last = dict.fromkeys(names, 0), {}, {}
    for fr in frames:
        for n in fr["visible"]:
            count[n] = count.get(n, 0) + 1
            first.setdefault(n, fr["frame"])
            last[n] = fr["frame"]
    objects = {n: {"frames_visible": count[n], "first": first.get(n), "last": last.get(n)} for n in sorted(count)}
    step = int(source.get("settings", {}).get("frame_step", 1))
    return {"frames": frames, "objects": objects, "frame_count": len(frames), "rule": rule,
            "frames_analyzed": frame_runs(numbers, step), "source": source}


def csv_text(report: dict) -> str:
    """The CSV of a report: a row per object, :data:`CSV_COLUMNS`."""
    out = io.StringIO()
    w = csv.writer(out)                      # csv's own dialect: lines end in CRLF (RFC 4180)
    w.writerow(CSV_COLUMNS)
    n = max(report["frame_count"], 1)
    for name, o in report["objects"].items():
        w.writerow([name, o["frames_visible"], f"{o['frames_visible'] / n:.4f}",
                    "" if o["first"] is None else o["first"], "" if o["last"] is None else o["last"]])
    return out.getvalue()


def csv_path(json_path: str) -> str:
    """Where the CSV of the report ``json_path`` goes: beside it, ``.csv`` for ``.json``."""
    return os.path.splitext(json_path)[0] + ".csv"


def write_report(report: dict, path: str) -> tuple[str, str]:
    """Write the report's JSON to ``path`` and its CSV beside it; each file goes to a
    temporary name first and is renamed into place (a reader never sees half a
    report).  Returns ``(json path, csv path)``.  OSError is the caller's to report."""
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    text = json.dumps(report, indent=1) + "\n"
    written = []
    for target, body in ((path, text), (csv_path(path), csv_text(report))):
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=".occ-", suffix=".tmp")
        try:
            with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
                f.write(body)
            os.replace(tmp, target)
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise
        written.append(target)
    return written[0], written[1]


def report_files(spec: str) -> list[str]:
    """The report files a ``merge`` argument names: a report JSON itself; a folder's
    ``report.json``; or, in a folder without one, every ``.json`` in it (the chunks
    ``occ.analyze`` wrote there), in name order."""
    if os.path.isfile(spec):
        return [spec]
    if not os.path.isdir(spec):
        raise OccError(f"no report at {spec}: give a report folder (with {REPORT_NAME}) or a report JSON")
    own = os.path.join(spec, REPORT_NAME)
    if os.path.isfile(own):
        return [own]
    found = sorted(os.path.join(spec, n) for n in os.listdir(spec)
                   if n.endswith(".json") and os.path.isfile(os.path.join(spec, n)))
    if not found:
        raise OccError(f"no report in {spec}: no {REPORT_NAME} and no .json file (run analyze --out {spec}, "
                       "or occ.analyze with a filepath there, first)")
    return found


def read_report(path: str) -> dict:
    """A report read back and checked: every key of :data:`KEYS` there with its type,
    frames ascending, and ``objects``, ``frame_count`` and ``frames_analyzed`` those
    its frames give.  Anything else is an OccError naming the file."""
    try:
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
    except OSError as e:
        raise OccError(f"cannot read report {path}: {e.strerror}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise OccError(f"{path} is not a report (not JSON: {e})") from None
    if not isinstance(data, dict):
        raise OccError(f"{path} is not a report: a JSON object with {', '.join(KEYS)} was expected")
    missing = [k for k in KEYS if k not in data]
    if missing:
        hint = (" (a report from before chunked analysis: run it again to merge it)"
                if "frames" in data and "objects" in data else "")
        raise OccError(f"{path} is not a mergeable report: no {', '.join(missing)}{hint}")
    source = data["source"]
    if not isinstance(source, dict) or any(k not in source for k in SOURCE_KEYS):
        raise OccError(f"{path}: 'source' must hold {', '.join(SOURCE_KEYS)}")
    frames = data["frames"]
    if not isinstance(frames, list) or not frames or not all(
            isinstance(fr, dict) and isinstance(fr.get("frame"), int) and isinstance(fr.get("visible"), list)
            and all(isinstance(n, str) for n in fr["visible"]) for fr in frames):
        raise OccError(f"{path}: 'frames' must be a non-empty list of {{\"frame\": int, \"visible\": [names]}}")
    if not isinstance(data["objects"], dict) or not isinstance(data["rule"], str):
        raise OccError(f"{path}: 'objects' must be an object and 'rule' a string")
    try:
        again = build_report(frames, data["objects"], data["rule"], source)
    except OccError as e:
        raise OccError(f"{path}: {e}") from None
    for key in ("objects", "frame_count", "frames_analyzed"):
        if again[key] != data[key]:
            raise OccError(f"{path}: '{key}' does not match its frames (edited by hand?); analyze again")
    return data


def _differ(a: dict, b: dict, prefix: str = "") -> str:
    """The first key whose values differ between two sources, as ``settings.strategy``."""
    for k in sorted(set(a) | set(b)):
        if a.get(k) != b.get(k):
            if isinstance(a.get(k), dict) and isinstance(b.get(k), dict):
                return _differ(a[k], b[k], f"{prefix}{k}.")
            return f"{prefix}{k} ({a.get(k)!r} / {b.get(k)!r})"
    return ""


def merge_reports(reports: Sequence[dict], labels: Sequence[str] | None = None) -> dict:
    """One report from the chunk reports of one analysis: exactly the report of one run
    over all their frames.  Frames are sorted, objects recomputed from them (every
    object any chunk knows), ``frame_count`` summed.  Refused (OccError, naming the two
    chunks): chunks of another scene, other objects or other settings (their
    ``source`` differs), and chunks whose frame ranges overlap."""
    labels = list(labels) if labels is not None else [f"chunk {i + 1}" for i in range(len(reports))]
    if not reports:
        raise OccError("nothing to merge: give at least one report")
    first = reports[0]
    for r, label in zip(reports[1:], labels[1:], strict=True):
        if r["source"] != first["source"]:
            what = ("scenes" if r["source"].get("scene") != first["source"].get("scene") else
                    "objects" if r["source"].get("names_sha1") != first["source"].get("names_sha1") else "settings")
            raise OccError(f"{labels[0]} and {label} are chunks of different {what}: "
                           f"{_differ(first['source'], r['source'])}; merge only chunks of one analysis")
        if r["rule"] != first["rule"]:
            raise OccError(f"{labels[0]} and {label} use different rules ({first['rule']} / {r['rule']})")
    spans = sorted((run[0], run[1], label) for r, label in zip(reports, labels, strict=True)
                   for run in r["frames_analyzed"])
    for (a0, a1, la), (b0, b1, lb) in zip(spans, spans[1:], strict=False):
        if b0 <= a1:
            raise OccError(f"{la} (frames {a0}-{a1}) and {lb} (frames {b0}-{b1}) overlap; "
                           "merge chunks of disjoint frame ranges")
    frames = sorted((fr for r in reports for fr in r["frames"]), key=lambda fr: fr["frame"])
    names = dict.fromkeys(n for r in reports for n in r["objects"])
    merged = build_report(frames, names, first["rule"], first["source"])
    assert merged["frame_count"] == sum(r["frame_count"] for r in reports)
    return merged
