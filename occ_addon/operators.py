"""Operators: glue from settings to one engine call, errors mapped to reports."""

import time
import traceback

import bpy
from bpy.props import BoolProperty, EnumProperty, IntProperty, StringProperty

from ..core import OccError
from ..core.motion import AT_REST
from . import bake, bake_chunks, live, localview, render_keys, visibility
from .analysis import analysis_steps, link_collection, push_undo, report_path, write_report
from .cameras import camera_for
from .session import SESSION
from .worker import Job, Progress, drive, quiet

# "//" paths are blend-relative; Blender 4.5+ wants string properties to say they accept them
BLEND_RELATIVE = {"PATH_SUPPORTS_BLEND_RELATIVE"} if bpy.app.version >= (4, 5, 0) else set()


def progress_lines(what):
    """A progress callback for :func:`.worker.drive`: a line about every second, in
    background mode only."""
    t0 = last = time.perf_counter()

    def line(item):
        nonlocal last
        now = time.perf_counter()
        if bpy.app.background and now - last >= 1.0 and item.fraction is not None:
            last = now
            print(f"occlusion {what}: {item.label} {100 * item.fraction:.0f}% ({now - t0:.1f} s)", flush=True)
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
                    self._show(context, Progress("building the engine", None))
                else:
                    self._show(context, item)
        except StopIteration as stop:
            self._end(context)
            return self.finish(context, stop.value)
        except Exception as e:  # every failure is a report, never a traceback
            self._end(context)
            return failed(self, e)
        return {"RUNNING_MODAL"}

    def _show(self, context, item: Progress):
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


class SteppedJob(Stepped):
    """An operator whose whole work is one generator of steps (:meth:`steps`, named
    :attr:`WHAT` in progress lines): modal in a window, at once otherwise, and
    :meth:`finish` with the steps' value."""

    WHAT = ""

    def steps(self, context):
        raise NotImplementedError

    def invoke(self, context, event):
        if not self.windowed(context):
            return self.execute(context)
        try:
            steps = self.steps(context)
        except Exception as e:  # every failure is a report, never a traceback
            return failed(self, e)
        return self.start_steps(context, steps, self.WHAT)

    def execute(self, context):
        try:
            value = self.run_steps(self.steps(context), self.WHAT)
        except Exception as e:  # every failure is a report, never a traceback
            return failed(self, e)
        return self.finish(context, value)


def frame_range(op, scene) -> tuple[int, int]:
    """The operator's ``frame_start`` / ``frame_end`` (-1: the scene's), or an OccError."""
    start = scene.frame_start if op.frame_start < 0 else op.frame_start
    end = scene.frame_end if op.frame_end < 0 else op.frame_end
    if end < start:
        raise OccError(f"empty frame range {start}..{end}")
    return start, end


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
            envelope = AT_REST if s.source == "VIEWPORT" or s.live else None
            SESSION.reread_transforms()
            SESSION.cull(context, camera, display, fresh=True, progress=progress, restart=True, envelope=envelope)
            live.track(context)
            live.install()
        except Exception as e:  # every failure is a report, never a traceback
            return failed(self, e)
        warn(self)
        self.report({"INFO"}, SESSION.last.summary())
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


class OCC_OT_local_view(bpy.types.Operator):
    """Local view (Numpad /) in a view the occlusion culler hides in: its own local view
    ends, everything it hid is shown, and Blender's local view of the selection begins"""

    bl_idname = "occ.local_view"
    bl_label = "Local View"

    @classmethod
    def poll(cls, context):
        # elsewhere the key falls through to Blender's own local view
        return localview.is_own(context.space_data)

    def invoke(self, context, event):
        visibility.restore()             # live mode, if on, culls again inside the new local view
        SESSION.shown = None
        quiet()                          # no engine thread runs while an operator does
        return bpy.ops.view3d.localview("INVOKE_DEFAULT")


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


class OCC_OT_analyze(SteppedJob, bpy.types.Operator):
    """Cull from the scene camera over a frame range and write what it sees (JSON and CSV)"""

    # Every frame is a new engine's first pass: reports of parts of a range (a farm's
    # chunks: frame_start/frame_end) join into the whole range's with `python -m core merge`.

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

    WHAT = "analyze"

    def steps(self, context):
        """The analysis's steps, or an OccError the user can act on (no frame, no path)."""
        start, end = frame_range(self, context.scene)
        frames = list(range(start, end + 1, self.frame_step))
        return analysis_steps(context, frames, report_path(self.filepath), self._rule(), self.frame_step)

    def _rule(self):
        if self.rule == "AUTO":
            return "render" if self.link_never_visible else "seen"
        return self.rule.lower()

    def finish(self, context, analysis):
        try:
            write_report(analysis)
        except OSError as e:
            return failed(self, OccError(f"cannot write the report {analysis.path}: {e.strerror or e}"))
        never = analysis.never_visible
        kept = ""
        if self.link_never_visible:
            _, users = link_collection(context.scene, "Never Visible", never)
            push_undo("Collect Never Visible")
            if users:       # seen, but the user's there (linked by them, or their only collection)
                kept = (f"; {len(users)} seen but left in 'Never Visible' (yours there, or their only "
                        f"collection): {', '.join(users[:5])}{' ...' if len(users) > 5 else ''}")
        warn(self)
        self.report({"INFO"}, f"{len(analysis.frames)} frames in {time.perf_counter() - analysis.started:.1f} s; "
                              f"{len(never)} of {len(analysis.seen)} objects never visible; "
                              f"report {analysis.path}{kept}")
        return {"FINISHED"}


class OCC_OT_bake_shot(SteppedJob, bpy.types.Operator):
    """Cull every frame of the range from the scene camera, within the frame's motion, and store
    each frame's hidden set in the file (Use Baked Shot applies it as the frame changes)"""

    bl_idname = "occ.bake_shot"
    bl_label = "Bake Shot"
    WHAT = "bake"

    frame_start: IntProperty(name="Start", default=-1, description="-1: the scene's start")
    frame_end: IntProperty(name="End", default=-1, description="-1: the scene's end")
    filepath: StringProperty(name="Chunk", subtype="FILE_PATH", default="", options={"SKIP_SAVE"},
                             description="Also write the bake to this file, a chunk that Merge Bake Chunks "
                                         "merges with the other chunks of the shot (a farm bakes a shot in chunks)")

    def steps(self, context):
        start, end = frame_range(self, context.scene)
        if context.scene.camera is None:
            raise OccError("the scene has no camera: a shot is baked for the scene camera")
        self._chunk = bake_chunks.prepare(self.filepath) if self.filepath else None
        return bake.bake_steps(context, start, end)

    def finish(self, context, result):
        if self._chunk:
            try:
                bake_chunks.write(context.scene, self._chunk, result.share)
            except OSError as e:
                return failed(self, OccError(f"cannot write the bake chunk {self._chunk}: {e.strerror or e}"))
        push_undo("Bake Shot")
        if context.scene.occ_bake.use:
            bake.apply_frame(context)
        warn(self)
        self.report({"INFO"}, f"baked {len(result.frames)} frames: {result.hidden_mean:,.0f} of "
                              f"{result.objects:,} objects hidden a frame (mean)")
        return {"FINISHED"}


class OCC_OT_render_baked(bpy.types.Operator):
    """Render the baked frames to the output path, each with its baked set hidden from the render
    (blocks until done; from the command line: blender -b FILE --python-expr
    "import bpy; bpy.ops.occ.render_baked()")"""

    bl_idname = "occ.render_baked"
    bl_label = "Render Baked Shot"

    frame_start: IntProperty(name="Start", default=-1, description="-1: the bake's first frame")
    frame_end: IntProperty(name="End", default=-1, description="-1: the bake's last frame")

    def execute(self, context):
        t = time.perf_counter()
        try:
            b = context.scene.occ_bake
            start = b.frame_start if self.frame_start < 0 else self.frame_start
            end = b.frame_end if self.frame_end < 0 else self.frame_end
            done = bake.render_shot(context, start, end)
        except Exception as e:  # every failure is a report, never a traceback
            return failed(self, e)
        self.report({"INFO"}, f"rendered {len(done.frames)} frames in {time.perf_counter() - t:.1f} s, "
                              f"{sum(done.hidden) / max(len(done.hidden), 1):,.0f} objects hidden a frame "
                              f"(mean); last {done.paths[-1] if done.paths else '-'}")
        return {"FINISHED"}


class OCC_OT_bake_merge(bpy.types.Operator):
    """Merge the chunks of a shot baked apart (occ.bake_shot with a chunk file, on a farm)
    into this scene's bake: exactly the bake of one run over all their frames"""

    bl_idname = "occ.bake_merge"
    bl_label = "Merge Bake Chunks"

    directory: StringProperty(name="Chunks", subtype="DIR_PATH", default="",
                              description="Folder of the chunk files (every .json in it)")

    def invoke(self, context, event):
        if self.directory or context.window is None:
            return self.execute(context)
        context.window_manager.fileselect_add(self)       # (F3 in a window: pick the folder)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        try:
            result = bake_chunks.merge(context, bake_chunks.chunk_files(self.directory))
        except Exception as e:  # every failure is a report, never a traceback
            return failed(self, e)
        push_undo("Merge Bake Chunks")
        if context.scene.occ_bake.use:
            bake.apply_frame(context)
        self.report({"INFO"}, f"merged frames {result.frames[0]}-{result.frames[-1]}: {result.hidden_mean:,.0f} "
                              f"of {result.objects:,} objects hidden a frame (mean)")
        return {"FINISHED"}


class OCC_OT_bake_use(bpy.types.Operator):
    """Apply the baked shot's hiding as the frame changes, in the view through the scene camera (toggle)"""

    bl_idname = "occ.bake_use"
    bl_label = "Use Baked Shot"

    def execute(self, context):
        scene = context.scene
        b = scene.occ_bake
        if not b.use and bake.stored(scene) is None:
            self.report({"ERROR"}, "no baked shot in this scene: bake one first (Bake Shot)")
            return {"CANCELLED"}
        b.use = not b.use
        if b.use:
            if scene.occ.live:                       # one owner of the hiding at a time
                live.stop(context)
                visibility.restore()
                SESSION.shown = None
            try:
                hidden = bake.apply_frame(context)
            except Exception as e:  # every failure is a report, never a traceback
                bake.release()
                return failed(self, e)
            why = bake.STATE.stale
            if why:
                self.report({"WARNING"}, f"the baked shot is stale ({why}): it hides nothing; bake again")
            elif not hidden and bake.camera_area(context) is None and not bpy.app.background:
                self.report({"INFO"}, "the baked shot hides in a 3D view that looks through the scene camera "
                                      "(Numpad 0), not in Quad View, with no clipping region (Alt+B), and "
                                      "whose shading shows no more than the render (no shadows or lights of "
                                      "its own)")
        else:
            bake.release()
        return {"FINISHED"}


class OCC_OT_bake_render(bpy.types.Operator):
    """Write the baked shot where every final render reads it (keys of hide_render on the objects it
    hides), for F12, Render Animation, blender -b -a and a farm; removed again when the bake stops
    holding (toggle)"""

    bl_idname = "occ.bake_render"
    bl_label = "Apply to Render"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        b = context.scene.occ_bake
        if b.render_keys:
            n = render_keys.remove()
            self.report({"INFO"}, f"render keys removed from {n:,} objects")
            return {"FINISHED"}
        try:
            done = render_keys.write(context)
        except Exception as e:  # every failure is a report, never a traceback
            render_keys.remove()
            return failed(self, e)
        skipped = (f"; {done.skipped:,} left whole (their own animation or render hide, or linked into "
                   "another scene)") if done.skipped else ""
        self.report({"INFO"}, f"render keys on {done.objects:,} objects ({done.keys:,} keys){skipped}")
        return {"FINISHED"}


class OCC_OT_bake_clear(bpy.types.Operator):
    """Delete the baked shot from the scene (what it hides is shown)"""

    bl_idname = "occ.bake_clear"
    bl_label = "Clear Bake"

    def execute(self, context):
        bake.clear(context.scene)
        push_undo("Clear Baked Shot")
        return {"FINISHED"}


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
    elif isinstance(error, ReferenceError):
        # a script or another add-on's timer removed an object the steps had read (a
        # window holds back only the user's own edits while the steps run)
        SESSION.reset()
        op.report({"ERROR"}, "the scene changed under the pass (an object it had read was removed by a "
                             f"script or another add-on): nothing new was hidden; run it again ({error})")
    else:
        traceback.print_exc()
        SESSION.reset()
        op.report({"ERROR"}, f"occlusion culling failed: {type(error).__name__}: {error} "
                             "(details in the system console)")
    return {"CANCELLED"}


CLASSES = (OCC_OT_cull, OCC_OT_restore, OCC_OT_local_view, OCC_OT_live, OCC_OT_analyze, OCC_OT_bake_shot,
           OCC_OT_bake_merge, OCC_OT_bake_use, OCC_OT_bake_clear, OCC_OT_render_baked, OCC_OT_bake_render)

_keymaps = []


def register_keys():
    """Numpad / and / in the 3D view: :class:`OCC_OT_local_view` first (it passes the key
    on to Blender's local view wherever the add-on has no local view of its own)."""
    kc = bpy.context.window_manager.keyconfigs.addon if bpy.context.window_manager else None
    if kc is None:                                   # background mode: no key configuration
        return
    km = kc.keymaps.new(name="3D View", space_type="VIEW_3D")
    for key in ("NUMPAD_SLASH", "SLASH"):
        _keymaps.append((km, km.keymap_items.new(OCC_OT_local_view.bl_idname, key, "PRESS")))


def unregister_keys():
    while _keymaps:
        km, item = _keymaps.pop()
        km.keymap_items.remove(item)
