"""The scene camera at any frame from its own keys, where a frame change moves the camera
alone: an analysis then evaluates the scene once, not once a frame.

A frame change (``scene.frame_set``) evaluates the whole dependency graph however little
moves: 148 ms a frame at 28,845 objects (``tools/bench/analyze_throughput.py``'s breakdown;
``perf`` puts it in Blender's ``schedule_node`` over every node).  A camera path over a static
scene needs none of it: every other object is where it was, and the camera at frame
``f`` is its F-curves at ``f``, composed as Blender composes a transform.

:func:`probe` decides, after one ordinary frame change, from what that change evaluated
(the depsgraph's updates: everything that depends on time, whatever drives it: keys,
drivers, constraints, modifiers, physics, geometry nodes).  The keys stand in for frame
changes only where nothing but the camera's own transform moves (other cameras, empties
that instance nothing and are no ancestor of the camera, and, where lights do not count,
lights may animate too); its keys are plain transform channels (no drivers, NLA,
constraints, muted curves, layered actions); its parents are static; no marker switches
cameras; no other script reacts to frame changes.  The composed matrix is checked
against Blender's at every frame the analysis evaluates in full (its first and last);
any doubt: frames as before.  Conservative by construction: a wrong "yes" here would
analyze a moving scene as static, so every test is one that can only say "no" more.
"""

import bpy
import numpy as np
from mathutils import Euler, Matrix, Quaternion

from .kinds import action_curves, is_dynamic, render_keys_only

# transform channels the keys may animate (anything else keyed on the camera: frames)
CHANNELS = {"location": 3, "rotation_euler": 3, "rotation_quaternion": 4, "rotation_axis_angle": 4,
            "scale": 3, "delta_location": 3, "delta_rotation_euler": 3, "delta_rotation_quaternion": 4,
            "delta_scale": 3}
# object types whose own animation changes nothing a pass sees (cameras but the scene's,
# empties that instance nothing); lights count only where lights count
INERT_TYPES = {"CAMERA", "EMPTY", "SPEAKER", "LIGHT_PROBE"}
# the composed matrix against Blender's evaluated one: float32 rounding, nothing more
TOLERANCE = 1e-5


def evaluate_frame(scene, frame: int) -> list:
    """``scene.frame_set(frame)``; returns the datablocks (originals) that frame change
    evaluated: everything in the view layer that depends on time."""
    got = []

    def note(_scene, depsgraph):
        if depsgraph is not None:
            got.extend(u.id.original for u in depsgraph.updates)
    bpy.app.handlers.frame_change_post.append(note)
    try:
        scene.frame_set(frame)
    finally:
        bpy.app.handlers.frame_change_post.remove(note)
    return got


def _fcurves(idblock):
    """The F-curves of ``idblock``'s active action, or None where its animation is more
    than one action's keys (drivers, NLA, layers, blending, influence)."""
    ad = idblock.animation_data
    if ad is None:
        return []
    if len(ad.drivers) or len(ad.nla_tracks) or getattr(ad, "use_tweak_mode", False) \
            or getattr(ad, "action_influence", 1.0) != 1.0 \
            or getattr(ad, "action_blend_type", "REPLACE") != "REPLACE":
        return None
    action = ad.action
    if action is None:
        return []
    return action_curves(action, getattr(ad, "action_slot", None))


class KeyedCamera:
    """The scene camera's world matrix at any frame, from its keys (see :func:`probe`)."""

    def __init__(self, cam, curves: list, framelen: float):
        self.cam = cam
        self.curves = curves                # (data_path, index, FCurve)
        self.framelen = framelen            # scene frame -> action time (time remapping)
        self.parent = None
        if cam.parent is not None:          # static: read once
            self.parent = (np.array(cam.parent.matrix_world, dtype=np.float64)
                           @ np.array(cam.matrix_parent_inverse, dtype=np.float64))

    def matrix_world(self, frame: int) -> np.ndarray:
        """``(4, 4) float64``: the camera's world matrix at ``frame``, as Blender's
        ``BKE_object_to_mat4`` and parenting make it (scale, then rotation, delta
        rotation before it; location plus delta location)."""
        cam = self.cam
        values = {p: list(getattr(cam, p)) for p in CHANNELS}
        t = frame * self.framelen
        for path, index, fc in self.curves:
            values[path][index] = fc.evaluate(t)
        mode = cam.rotation_mode
        if mode == "QUATERNION":
            rot = Quaternion(values["rotation_quaternion"]).normalized().to_matrix()
            delta = Quaternion(values["delta_rotation_quaternion"]).normalized().to_matrix()
        elif mode == "AXIS_ANGLE":
            angle, *axis = values["rotation_axis_angle"]
            axis = np.array(axis, dtype=np.float64)
            n = np.linalg.norm(axis)
            rot = Matrix.Rotation(angle, 3, tuple(axis / n)) if n > 0 else Matrix.Identity(3)
            delta = Matrix.Identity(3)      # no delta axis-angle in the Python API (checked below)
        else:
            rot = Euler(values["rotation_euler"], mode).to_matrix()
            delta = Euler(values["delta_rotation_euler"], mode).to_matrix()
        m = np.eye(4)
        m[:3, :3] = (np.array(delta, dtype=np.float64) @ np.array(rot, dtype=np.float64)
                     * (np.array(values["scale"]) * np.array(values["delta_scale"]))[None, :])
        m[:3, 3] = np.array(values["location"]) + np.array(values["delta_location"])
        return m if self.parent is None else self.parent @ m

    def agrees(self, frame: int) -> bool:
        """Whether the keys give Blender's own matrix at ``frame``, the current frame
        just evaluated in full."""
        ours, blender = self.matrix_world(frame), np.array(self.cam.matrix_world, dtype=np.float64)
        return bool(np.all(np.isfinite(ours))
                    and np.abs(ours - blender).max() <= TOLERANCE * max(1.0, float(np.abs(blender).max())))


def probe(scene, moving: list, lights_count: bool) -> KeyedCamera | None:
    """The scene camera from its keys, or None: every frame must be evaluated in full.
    ``moving``: what a frame change just evaluated (:func:`evaluate_frame`), at the
    frame now current; ``lights_count``: whether lights change the answer (shadows)."""
    cam = scene.camera
    if cam is None or cam.type != "CAMERA" or len(bpy.app.handlers.frame_change_pre) \
            or any(not (getattr(h, "__module__", None) or "").startswith(__package__)
                   for h in bpy.app.handlers.frame_change_post):    # another script reacts to frames
        return None
    if any(m.camera is not None for m in scene.timeline_markers):   # cameras switched by markers
        return None
    moved = set(moving)
    ancestors = set()
    p = cam.parent
    while p is not None and len(ancestors) < 64:
        ancestors.add(p)
        p = p.parent
    for idb in moved:
        if idb == cam or isinstance(idb, bpy.types.Action):
            continue
        if isinstance(idb, bpy.types.Object) and idb not in ancestors and (
                (idb.type in INERT_TYPES and idb.instance_type == "NONE")
                or (idb.type == "LIGHT" and not lights_count)):
            continue
        if isinstance(idb, bpy.types.Object) and idb not in ancestors and idb.animation_data is not None \
                and render_keys_only(idb.animation_data) and not is_dynamic(idb):
            continue                         # its render keys (Apply to Render): nothing a pass sees
        if isinstance(idb, bpy.types.Camera) and idb != cam.data:
            continue
        if isinstance(idb, bpy.types.Light) and not lights_count:
            continue
        return None                          # anything else moves with time: frames
    # parents: to an object's origin, none moving with time nor able to (kinds.is_dynamic)
    if len(cam.constraints) or cam.data.animation_data is not None or (cam.parent is not None and (
            cam.parent_type != "OBJECT" or is_dynamic(cam.parent) or not ancestors.isdisjoint(moved))):
        return None
    curves = _fcurves(cam)
    if curves is None:
        return None
    keyed = []
    for fc in curves:
        size = CHANNELS.get(fc.data_path)
        if fc.mute or not fc.is_valid or size is None or not 0 <= fc.array_index < size \
                or (fc.group is not None and getattr(fc.group, "mute", False)):
            return None
        keyed.append((fc.data_path, fc.array_index, fc))
    r = scene.render
    # time remapping: frame f is time f * old / new (``frame_current_final``)
    keys = KeyedCamera(cam, keyed, r.frame_map_old / r.frame_map_new)
    return keys if keys.agrees(scene.frame_current) else None
