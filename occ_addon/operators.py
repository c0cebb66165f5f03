"""Operators: glue from settings to one engine call, errors mapped to reports."""

import csv
import json
import os
import time
import traceback

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, IntProperty, StringProperty

from ..core import OccError, Visibility
from . import live, overlay, visibility
from .extract import bystanders, draws_beyond_geometry, is_instancer
from .session import SESSION, camera_for, scene_camera
from .shading import rule as rule_of
from .worker import Job, drive

# "//" paths are blend-relative; Blender 4.5+ wants string properties to say they accept them
BLEND_RELATIVE = {"PATH_SUPPORTS_BLEND_RELATIVE"} if bpy.app.version >= (4, 5, 0) else set()


def progress_lines(what):
    """A progress callback for :func:`.worker.drive`: a line about every second, in
    background mode only."""
    t0 = last = time.perf_counter()

    def line(item):
        nonlocal last
        now = time.perf_counter()
        if bpy.app.background and now - last >= 1.0 and item[1] is not None:
            last = now
            print(f"occlusion {what}: {item[0]} {100 * item[1]:.0f}% ({now - t0:.1f} s)", flush=True)
    return line


# Events a modal operator lets through while it works: navigating the view changes no data.
NAVIGATION = {"MIDDLEMOUSE", "WHEELUPMOUSE", "WHEELDOWNMOUSE", "TRACKPADPAN", "TRACKPADZOOM",
              "NDOF_MOTION", "MOUSEMOVE", "INBETWEEN_MOUSEMOVE"}


class Stepped:
    """Long work (a first build, an analysis) in a window runs in timer steps of the
    same generators the synchronous path drives (:func:`.worker.drive`): the
    interface redraws between steps, progress shows in the status bar and on the
    cursor, the view can still be navigated, and Esc cancels, leaving the scene as
    it was.  Every other event is held back while it runs, so the scene cannot be
    edited under it.  Scripts (``execute``) and background mode run the steps at
    once, printing a progress line a second in background mode."""

    SLICE_S = 0.05       # work per timer tick
    TICK_S = 0.01

    def start_steps(self, context, steps, what):
        wm = context.window_manager
        self._steps, self._job, self._what = steps, None, what
        self._timer = wm.event_timer_add(self.TICK_S, window=context.window)
        wm.modal_handler_add(self)
        wm.progress_begin(0, 100)
        SESSION.busy = what
        self._show(context, ("starting", 0.0))
        return {"RUNNING_MODAL"}

    def run_steps(self, steps, what):
        """The steps at once (a script, or background mode)."""
        return drive(steps, progress_lines(what))

    def modal(self, context, event):
        if event.type == "ESC" and event.value == "PRESS":
            self._end(context)
            self._steps.close()                       # the steps undo what they began
            self.report({"WARNING"}, f"{self._what} cancelled; nothing was changed")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"} if event.type in NAVIGATION else {"RUNNING_MODAL"}
        end = time.perf_counter() + self.SLICE_S
        try:
            while time.perf_counter() < end:
                if self._job is not None:
                    if not self._job.done():
                        break
                    self._job = None
                item = next(self._steps)
                if isinstance(item, Job):
                    self._job = item
                    self._show(context, ("building the engine", None))
                else:
                    self._show(context, item)
        except StopIteration as stop:
            self._end(context)
            return self.finish(context, stop.value)
        except Exception as e:  # every failure is a report, never a traceback
            self._end(context)
            return failed(self, e)
        return {"RUNNING_MODAL"}

    def _show(self, context, item):
        label, fraction = item
        if fraction is not None:
            context.window_manager.progress_update(int(100 * fraction))
        pct = "" if fraction is None else f" {100 * fraction:.0f}%"
        if context.workspace is not None:
            context.workspace.status_text_set(f"Occlusion culling: {self._what}: {label}{pct} (Esc to cancel)")

    def _end(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        SESSION.busy = None

    def windowed(self, context):
        """Whether this call can run modal (a window; not background mode)."""
        return not bpy.app.background and context.window is not None


class OCC_OT_cull(Stepped, bpy.types.Operator):
    """Hide the objects the active viewport (or the scene camera) cannot see"""

    bl_idname = "occ.cull"
    bl_label = "Cull"
    bl_options = {"REGISTER"}

    def invoke(self, context, event):
        if not self.windowed(context):
            return self.execute(context)
        try:
            _, display = camera_for(context)
            steps = SESSION.prepare_steps(context, display)
        except Exception as e:  # every failure is a report, never a traceback
            return failed(self, e)
        return self.start_steps(context, steps, "cull")

    def execute(self, context):
        return self.finish(context, None, progress_lines("cull"))

    def finish(self, context, _, progress=None):
        """The pass (after a modal build, it finds the engine built, or rebuilds what
        changed meanwhile)."""
        try:
            camera, display = camera_for(context)
            # the hidden set holds for a small motion of the view (of the scene camera
            # too while live: playback and edits move it); live mode (or, without it,
            # showing everything) takes over when the view leaves it
            s = context.scene.occ
            envelope = "rest" if s.source == "VIEWPORT" or s.live else None
            SESSION.cull(context, camera, display, fresh=True, progress=progress, restart=True, envelope=envelope)
            live.track(context)
            overlay.install()
        except Exception as e:  # every failure is a report, never a traceback
            return failed(self, e)
        s = context.scene.occ
        warn(self)
        self.report({"INFO"}, f"{s.last_occluded} occluded, {s.last_outside} outside the view, "
                              f"of {s.last_tested} ({s.last_ms:.0f} ms)")
        return {"FINISHED"}


class OCC_OT_restore(bpy.types.Operator):
    """Show again exactly the objects the occlusion culler hid"""

    bl_idname = "occ.restore"
    bl_label = "Restore"
    bl_options = {"REGISTER"}

    def execute(self, context):
        if context.scene.occ.live:
            live.stop(context)
        n = visibility.restore()
        SESSION.shown = None
        self.report({"INFO"}, f"restored {n} objects")
        return {"FINISHED"}


class OCC_OT_live(Stepped, bpy.types.Operator):
    """Re-cull whenever the view changes (toggle)"""

    bl_idname = "occ.live"
    bl_label = "Live"

    def invoke(self, context, event):
        if context.scene.occ.live or not self.windowed(context):
            return self.execute(context)
        try:                                         # the first build in steps, then live
            _, display = camera_for(context)
            steps = SESSION.prepare_steps(context, display)
        except Exception as e:  # every failure is a report, never a traceback
            return failed(self, e)
        return self.start_steps(context, steps, "live start")

    def finish(self, context, _):
        live.start(context)
        return {"FINISHED"}

    def execute(self, context):
        if bpy.app.background:
            self.report({"ERROR"}, "live culling needs a window (Blender is running in background mode)")
            return {"CANCELLED"}
        if context.scene.occ.live:
            live.stop(context)
            visibility.restore()
            SESSION.shown = None
        else:
            live.start(context)
        return {"FINISHED"}


class OCC_OT_analyze(Stepped, bpy.types.Operator):
    """Cull from the scene camera over a frame range and write what it sees (JSON and CSV)"""

    bl_idname = "occ.analyze"
    bl_label = "Analyze Camera Path"

    frame_start: IntProperty(name="Start", default=-1, description="-1: the scene's start")
    frame_end: IntProperty(name="End", default=-1, description="-1: the scene's end")
    frame_step: IntProperty(name="Step", default=1, min=1)
    filepath: StringProperty(name="Report", subtype="FILE_PATH", default="//occlusion_report.json",
                             options=BLEND_RELATIVE)
    link_never_visible: BoolProperty(name="Collect Never Visible", default=False,
                                     description="Link never-visible objects into a collection")
    rule: EnumProperty(
        name="Rule", default="AUTO",
        items=[("AUTO", "Auto", "Needed for the render when collecting never-visible objects, else seen"),
               ("SEEN", "Seen", "An object counts where a pixel of it is seen"),
               ("RENDER", "Needed for the Render", "Seen, or shadowing what is seen under the render "
                          "engine's lights (everything under ray tracing, unless Cull Under Ray Tracing)")])

    def _plan(self, context):
        """``(frames, report path)``, or an OccError the user can act on."""
        scene = context.scene
        start = scene.frame_start if self.frame_start < 0 else self.frame_start
        end = scene.frame_end if self.frame_end < 0 else self.frame_end
        if end < start:
            raise OccError(f"empty frame range {start}..{end}")
        return list(range(start, end + 1, self.frame_step)), report_path(self.filepath)

    def invoke(self, context, event):
        if not self.windowed(context):
            return self.execute(context)
        try:
            frames, path = self._plan(context)
        except Exception as e:  # every failure is a report, never a traceback
            return failed(self, e)
        return self.start_steps(context, analysis(context, frames, path, self._rule()), "analyze")

    def _rule(self):
        if self.rule == "AUTO":
            return "render" if self.link_never_visible else "seen"
        return self.rule.lower()

    def execute(self, context):
        try:
            frames, path = self._plan(context)
            value = self.run_steps(analysis(context, frames, path, self._rule()), "analyze")
        except Exception as e:  # every failure is a report, never a traceback
            return failed(self, e)
        return self.finish(context, value)

    def finish(self, context, value):
        frames, path, per_frame, seen, t, rule = value
        try:
            write_report(path, frames, per_frame, seen, rule)
        except OSError as e:
            return failed(self, OccError(f"cannot write the report {path}: {e.strerror or e}"))
        never = sorted(n for n, c in seen.items() if c == 0)
        if self.link_never_visible:
            link_collection(context.scene, "Never Visible", never)
            push_undo("Collect Never Visible")
        warn(self)
        self.report({"INFO"}, f"{len(frames)} frames in {time.perf_counter() - t:.1f} s; "
                              f"{len(never)} of {len(seen)} objects never visible; report {path}")
        return {"FINISHED"}


def analysis(context, frames, path, rule="seen"):
    """Analyze in steps (a generator, see :func:`.worker.drive`): one a frame, and a
    first build's own; returns what :meth:`OCC_OT_analyze.finish` writes.  Stopped
    early (Esc), the scene goes back to its frame and nothing is written.  ``rule``:
    "seen" (a pixel of it seen) or "render" (seen, or shown beyond its pixels under
    the render engine: shadows, rays; :mod:`.shading`)."""
    scene = context.scene
    previous = scene.frame_current
    per_frame, seen = [], {}
    held = held_names = collections = None
    t = time.perf_counter()
    step = max(1, len(frames) // 10)          # background mode: about ten progress lines
    try:
        for k, f in enumerate(frames):
            scene.frame_set(f)
            camera, display = scene_camera(context)
            # nothing is hidden
            # the first frame a new engine's answer, later ones from what it taught
            view_rule = rule_of(context, "CAMERA") if rule == "render" else None
            result, objects = yield from SESSION.compute_steps(context, camera, display, restart=k == 0,
                                                               lights=view_rule.lights if view_rule else None)
            if SESSION.kept_uids is not held:   # the engine's objects changed: their names, once
                held = SESSION.kept_uids
                held_names = [o.name for o in objects]
                collections = [i for i, o in enumerate(objects) if is_instancer(o)]
                for n in held_names:
                    seen.setdefault(n, 0)
            vis = result.state == Visibility.VISIBLE          # one array compare, no per-object enum
            if view_rule is not None:          # shadow casters are the engine's (given the lights)
                vis |= SESSION.drawn_beyond_depth(view_rule, result.state)
            # an instance with members drawn beside its geometry (wire, bounds, ...) is seen
            # wherever it is drawn: the engine knows only its solid part (conservative by construction)
            wide = {}                                         # collection name -> the answer, once a frame
            for i in (i for i in collections if not vis[i]):
                c = objects[i].instance_collection
                if c.name_full not in wide:
                    wide[c.name_full] = draws_beyond_geometry(c)
                vis[i] = wide[c.name_full]
            shown = [held_names[i] for i in np.flatnonzero(vis)]
            extra = bystanders(context.view_layer, held)       # drawn, never culled: visible
            # an object is seen where a visible collection instance draws it, too
            members = [m for i in collections if vis[i] for m in objects[i].instance_collection.all_objects]
            others = [o.name for o in extra + members]
            names = list(dict.fromkeys(shown + others))
            per_frame.append({"frame": f, "visible": names})
            for n in others:
                seen.setdefault(n, 0)
            for n in names:
                seen[n] += 1
            if bpy.app.background and ((k + 1) % step == 0 or k + 1 == len(frames)):
                print(f"occlusion analyze: {k + 1}/{len(frames)} frames "
                      f"({time.perf_counter() - t:.1f} s)", flush=True)
            yield f"frame {k + 1}/{len(frames)}", (k + 1) / len(frames)
    finally:
        scene.frame_set(previous)
    return frames, path, per_frame, seen, t, rule


def report_path(filepath):
    """Absolute report path.  ``//`` is the blend file's folder; in a file never saved
    it is the working directory (sub-folders kept), never Blender's temporary folder,
    which is deleted at exit."""
    if filepath.startswith("//") and not bpy.data.filepath:
        return os.path.normpath(os.path.join(os.getcwd(), filepath[2:]))
    return os.path.normpath(bpy.path.abspath(filepath))


def warn(op):
    """Name the objects the last pass left out (kept visible, not occluders)."""
    bad = SESSION.warnings
    if bad:
        shown = ", ".join(bad[:10]) + (f" and {len(bad) - 10} more" if len(bad) > 10 else "")
        op.report({"WARNING"}, f"left visible and not used as occluders, for NaN or infinite "
                               f"values in their transform or vertices: {shown}")


def failed(op, error):
    """Report ``error`` to the user and cancel.  An OccError is the user's to act on;
    anything else is our bug: its traceback goes to the console, the engine is
    dropped (the next pass rebuilds it) and the report says where to look."""
    if isinstance(error, OccError):
        op.report({"ERROR"}, str(error))
    else:
        traceback.print_exc()
        SESSION.reset()
        op.report({"ERROR"}, f"occlusion culling failed: {type(error).__name__}: {error} "
                             "(details in the system console)")
    return {"CANCELLED"}


def write_report(path, frames, per_frame, seen, rule="seen"):
    """JSON: per frame the visible objects, per object the frames it is visible in, and
    the rule that says what "visible" means ("seen" or "render"); CSV beside it."""
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    first, last = {}, {}
    for fr in per_frame:
        for n in fr["visible"]:
            first.setdefault(n, fr["frame"])
            last[n] = fr["frame"]
    objects = {n: {"frames_visible": c, "first": first.get(n), "last": last.get(n)}
               for n, c in sorted(seen.items())}
    with open(path, "w", encoding="utf-8") as f:
        json.dump({"frames": per_frame, "objects": objects, "frame_count": len(frames), "rule": rule}, f, indent=1)
    with open(os.path.splitext(path)[0] + ".csv", "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["object", "frames_visible", "fraction", "first_frame", "last_frame"])
        for n, o in objects.items():
            w.writerow([n, o["frames_visible"], f"{o['frames_visible'] / max(len(frames), 1):.4f}",
                        o["first"] if o["first"] is not None else "", o["last"] if o["last"] is not None else ""])


def push_undo(message):
    """Make what an operator just changed an undo step of its own, as every edit is.

    Needed after any change that creates a datablock and links it to existing ones
    (the "Never Visible" collection in the scene's children): Blender's memfile undo
    keeps in place every datablock whose saved state did not change between the two
    undo steps it moves across, and knows nothing of changes made after the last
    push.  Undo without this step restores the scene as it is now, still pointing at
    the new collection, which the undo frees: a view layer then holds a freed
    collection (a crash, or Python reading it as a bare ``ID``).  With the step, the
    scene differs between the steps and is read back, the collection with it.

    The operators carry no UNDO flag (Cull and Restore must not add steps, and a
    script's ``bpy.ops`` call pushes nothing for it anyway), so the push is explicit.
    Headless without an undo history (the common script) nothing is pushed: nothing
    can be undone there, and a first push would copy the whole file into memory."""
    if not bpy.app.background or bpy.ops.ed.undo_history.poll():
        bpy.ops.ed.undo_push(message=message)


def link_collection(scene, name, object_names):
    """Make collection ``name`` hold exactly ``object_names`` (an earlier analysis's
    objects that this one saw are unlinked: deleting the collection's contents
    must never delete what the camera sees).  The collection is excluded in every
    view layer of every scene that links it: it gives its objects no way into a view
    layer, so linking changes nothing anyone sees (an object whose own collection is
    excluded stays out)."""
    coll = bpy.data.collections.get(name) or bpy.data.collections.new(name)
    if coll.name not in scene.collection.children:
        # excluded before its objects are linked: they never get a base through it
        scene.collection.children.link(coll)
    exclude_everywhere(coll)
    wanted = set(object_names)
    for obj in [o for o in coll.objects if o.name not in wanted]:
        coll.objects.unlink(obj)
    for n in object_names:
        obj = bpy.data.objects.get(n)
        if obj is not None and obj.name not in coll.objects:
            coll.objects.link(obj)


def exclude_everywhere(coll):
    """Exclude ``coll`` in every view layer where it appears (any depth)."""
    for scene in bpy.data.scenes:
        for layer in scene.view_layers:
            stack = [layer.layer_collection]
            while stack:
                lc = stack.pop()
                if lc.collection == coll:
                    if not lc.exclude:
                        lc.exclude = True
                    continue
                stack.extend(lc.children)


CLASSES = (OCC_OT_cull, OCC_OT_restore, OCC_OT_live, OCC_OT_analyze)
