"""A shot baked in chunks (a farm): each chunk's bake written to a file, the chunks merged
into the scene's bake.

Every frame of a bake is culled as a new engine's first pass (:func:`.bake.bake_steps`),
so a frame's set does not depend on the frames baked before it, and chunks of a range
baked apart, in processes that opened the same file, merge into exactly the bake of one
run over the whole range: the same sets, cameras, envelopes, objects and fingerprint.
A chunk holds what :func:`.bake.store` stores, and the share of triangles each frame
hides (for the summary).  The merge refuses chunks that overlap, leave frames out, were
baked from another scene or before an edit of this one (each chunk's fingerprint is
checked against the scene it is merged into) or for another camera path.
"""

import json
import os
import zlib

import numpy as np

from ..core import OccError
from . import bake

KIND = "occlusion-bake-chunk"
VERSION = 1


def prepare(path: str) -> str:
    """The chunk's absolute path, its folder made and writable (before any work)."""
    from .analysis import report_path
    path = report_path(path)
    folder = os.path.dirname(path) or "."
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as e:
        raise OccError(f"cannot make the folder of the bake chunk {path}: {e.strerror or e}") from e
    if os.path.isdir(path) or not os.access(folder, os.W_OK):
        raise OccError(f"cannot write the bake chunk {path}: not a writable file path")
    return path


def write(scene, path: str, share: list) -> None:
    """Write the scene's bake (just made) as a chunk file."""
    b = scene.occ_bake
    record = {"kind": KIND, "version": VERSION, "scene": scene.name_full,
              "frame_start": b.frame_start, "frame_end": b.frame_end, "width": b.width,
              "hidden": b.hidden, "cameras": b.cameras, "envelopes": b.envelopes, "held": b.held,
              "fingerprint": b.fingerprint, "camera_digest": b.camera_digest, "share": [float(x) for x in share]}
    tmp = path + ".part"
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(record, f)
    os.replace(tmp, path)                  # a chunk is whole or absent


def _read(path: str) -> dict:
    name = os.path.basename(path)
    try:
        with open(path, encoding="utf-8") as f:
            d = json.load(f)
    except (OSError, ValueError) as e:
        raise OccError(f"cannot read the bake chunk {name}: {e}") from e
    if not isinstance(d, dict) or d.get("kind") != KIND:
        raise OccError(f"{name} is not a bake chunk (occ.bake_shot(filepath=...) writes them)")
    if d.get("version") != VERSION:
        raise OccError(f"{name} was written by another version of the add-on: bake it again")
    try:
        n = int(d["frame_end"]) - int(d["frame_start"]) + 1
        width = int(d["width"])
        d["_hidden"] = bake.decode_frames(d["hidden"], n, width)
        d["_cameras"] = np.frombuffer(bake._unpack(d["cameras"]), dtype="<f8").reshape(n, 2, 4, 4)
        d["_envelopes"] = np.frombuffer(bake._unpack(d["envelopes"]), dtype="<f8").reshape(n, 2)
        d["_held"] = np.unpackbits(np.frombuffer(bake._unpack(d["held"]), np.uint8), count=width).astype(bool)
        d["_share"] = np.asarray(d["share"], dtype=np.float64).reshape(n)
    except (KeyError, TypeError, ValueError, zlib.error) as e:
        raise OccError(f"{name} is damaged ({e}): bake it again") from e
    d["_name"] = name
    return d


def chunk_files(directory: str) -> list:
    """The ``.json`` files of a folder (sorted), or an OccError."""
    from .analysis import report_path
    folder = report_path(directory)
    if not os.path.isdir(folder):
        raise OccError(f"no folder {folder}: give the folder the bake's chunks were written to")
    files = sorted(os.path.join(folder, f) for f in os.listdir(folder) if f.endswith(".json"))
    if not files:
        raise OccError(f"no bake chunks (.json) in {folder}")
    return files


def merge(context, paths: list) -> bake.BakeResult:
    """Merge chunk files into the scene's bake; every check before anything is written."""
    chunks = sorted((_read(p) for p in paths), key=lambda d: (d["frame_start"], d["frame_end"]))
    for a, b in zip(chunks, chunks[1:], strict=False):
        if b["frame_start"] <= a["frame_end"]:
            raise OccError(f"the bake chunks {a['_name']} and {b['_name']} overlap (frames {a['frame_start']}-"
                           f"{a['frame_end']} and {b['frame_start']}-{b['frame_end']}): one job's chunks per folder")
        if b["frame_start"] > a["frame_end"] + 1:
            raise OccError(f"frames {a['frame_end'] + 1}-{b['frame_start'] - 1} are in no bake chunk (between "
                           f"{a['_name']} and {b['_name']}): bake them too")
    scene = context.scene
    if scene.camera is None:
        raise OccError("the scene has no camera: a shot is baked for the scene camera")
    from . import render_keys
    bake.number_objects()                   # as each chunk's bake numbered the same file's objects
    digest = render_keys.shot_digest(context)
    for d in chunks:
        if bake.fingerprint(context, d["_held"]) != d["fingerprint"]:
            raise OccError(f"{d['_name']} was baked from another scene, or before an edit of this one: "
                           "bake it again")
        if d["camera_digest"] != digest:
            raise OccError(f"{d['_name']} was baked for another camera path or render setup: bake it again")
    width = max(d["_held"].shape[0] for d in chunks)

    def wide(a: np.ndarray) -> np.ndarray:
        out = np.zeros(a.shape[:-1] + (width,), dtype=bool)
        out[..., :a.shape[-1]] = a
        return out

    render_keys.remove("removed: the shot is baked again; apply again")
    bake.release()
    return bake.store(context, chunks[0]["frame_start"], chunks[-1]["frame_end"],
                      np.concatenate([wide(d["_hidden"]) for d in chunks]),
                      np.concatenate([d["_cameras"] for d in chunks]),
                      np.concatenate([d["_envelopes"] for d in chunks]),
                      np.logical_or.reduce([wide(d["_held"]) for d in chunks]),
                      np.concatenate([d["_share"] for d in chunks]))
