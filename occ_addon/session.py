"""One culling session per Blender session: the extraction cache, the engine
(kept while only transforms change), the camera of a pass and its result.

A pass costs, on the Blender side, one ``visible_get`` per object, one
``foreach_get`` of every world matrix and one ``foreach_set`` of the hide
flags; the engine is rebuilt only when the set of objects, some geometry, the
query resolution or the strategy changed.
"""

import time

import bpy
import numpy as np
from bpy.app.handlers import persistent

from ..core import Camera, Culler, OccError, Visibility
from ..core.engine import MAX_RESOLUTION
from ..core.envelope import Envelope
from ..core.motion import LivePolicy
from ..core.settings import preset, query_resolution
from ..core.units import ChunkCache
from . import extract, shading, visibility
from .extract import Extractor
from .visibility import ident
from .worker import EngineThread, drive

# Meshes of 4 x this many triangles or more are cut into chunks of about this
# many (never a user's mesh: index ranges inside the engine's copy): a heavy
# object is then drawn and tested by its visible parts, not as one box.
CHUNK_TRIANGLES = 4096
POLICY = LivePolicy()       # how far a hidden set must hold while the view moves (live.py)


class Session:
    def __init__(self):
        self.extractor = Extractor()
        self.chunks = ChunkCache()  # chunkings outlive engines: a resized viewport re-cuts nothing
        self.worker = EngineThread()
        self.culler = None
        self.uids = None           # candidate session ids the engine was built for
        self.kept = None           # (k,) indices of the candidates the engine holds
        self.kept_uids = None      # (k,) their session ids
        self.kept_collection = None  # (k,) bool: collection instances
        self.resolution = None
        self.last = None           # the last applied pass, for the overlay (see :meth:`cull`)
        self.version = 0           # bumped by every applied pass
        self.applying = False      # the depsgraph updates now are our own hiding's
        self.warnings = []         # objects left out of the last pass, for the report
        self.bad_geometry = []     # of them, those left out for their vertices (known since the last build)
        self.layer = None          # (scene, view layer) of the last pass
        self.busy = None           # the label of a modal operator's work in steps (live passes wait)
        self.shown = None          # (Camera, Envelope): the view and motion the hidden set holds for

    def reset(self):
        """Forget everything (a file was loaded, an undo or redo, or the add-on goes away):
        Blender may hand back the same session ids with other contents."""
        self.release()
        self.extractor = Extractor()
        self.uids = self.kept = self.kept_uids = self.kept_collection = None
        self.bad_geometry = []
        self.last = None
        self.shown = None
        self.version += 1

    def release(self):
        if self.culler is not None:
            culler, self.culler = self.culler, None
            self.worker.run(culler.close)

    def shutdown(self):
        self.reset()
        self.chunks = ChunkCache()
        self.worker.shutdown()

    def candidates(self, context, verify=False):
        """The candidates of a pass; objects the add-on hid and must give back
        (hidden by the user too, not evaluated and able to change, or, with
        ``verify``, edited since they were read) are shown first and evaluated,
        so the pass sees them as Blender draws them."""
        layer = (context.scene.name, context.view_layer.name)
        if layer != self.layer:
            # Another view layer than the last pass's: an object moved while it was not in
            # the evaluated layer keeps a stale original matrix_world until this layer's
            # evaluation writes it back, and the candidates read originals in bulk.
            # Once per switch: tag every transform and evaluate.
            self.layer = layer
            for ob in context.scene.objects:
                ob.update_tag(refresh={"OBJECT"})
            context.view_layer.update()
        cand = self.extractor.candidates(context, verify)
        if len(cand.give_back):
            visibility.release(np.isin(visibility.uids(), cand.give_back))
            context.view_layer.update()
            cand = self.extractor.candidates(context)
        return cand

    def engine_steps(self, context, resolution, strategy, verify=False, display=None):
        """The engine for the current candidates, ``(culler, objects)``: rebuilt when
        objects or geometry changed, otherwise only the moved objects' matrices are
        sent.  A generator (see :func:`.worker.drive`): it yields progress while it
        reads geometry and the build's :class:`.worker.Job` while the engine thread
        builds.  Stopped early (Esc), the session keeps no half
        state: the engine is dropped (closed on its thread once built) and the next
        pass builds again; nothing in the scene was touched."""
        cand = self.candidates(context, verify)
        self.warnings = list(cand.bad)
        if not len(cand):
            raise OccError("nothing to cull: the view layer has no visible mesh objects")
        uids = tuple(cand.uids.tolist())
        # the engine is bound to its query and display resolutions (GL targets)
        size = (resolution, display)
        rebuild = (self.culler is None or uids != self.uids or size != self.resolution
                   or self.extractor.needs_geometry(cand))
        if rebuild:
            scene, kept, bad = yield from self.extractor.scene_steps(context, cand)
            self.warnings += bad
            old, self.culler, self.uids = self.culler, None, None      # no half state if stopped
            if old is not None and size == self.resolution:
                # same context; meshes read unchanged from the cache keep their chunks
                job = self.worker.submit(_replaced, old, scene, strategy)
            else:
                if old is not None:
                    self.worker.submit(old.close)
                job = self.worker.submit(Culler, scene, resolution, strategy=strategy,
                                         chunk_triangles=CHUNK_TRIANGLES, chunk_cache=self.chunks,
                                         display=display)
            try:
                yield job
            except GeneratorExit:                     # stopped: close what the build makes
                self.worker.submit(_close_built, job)
                raise
            self.culler = job.result()
            self.uids, self.kept, self.resolution = uids, kept, size
            self.kept_uids = cand.uids[kept]
            self.kept_collection = np.array([cand.kinds[i] == "collection" for i in kept], dtype=bool)
            self.bad_geometry = bad
        else:
            self.warnings += self.bad_geometry
            if strategy != self.culler.strategy_name:
                self.worker.run(self.culler.set_strategy, strategy)
            m = cand.matrices[self.kept]
            moved = np.flatnonzero(np.any(m != self.culler.scene.matrices, axis=(1, 2)))
            if len(moved):
                self.worker.run(self.culler.set_matrices, moved, m[moved])
        return self.culler, [cand.objects[i] for i in self.kept]

    def _sizes(self, context, display):
        """``(options, query resolution, display resolution or None)`` of a pass."""
        settings = context.scene.occ
        options = preset(settings.preset)
        res = query_resolution(fit(display, settings.max_resolution), options)
        # Below the display's own resolution (the fast preset, or a display larger than
        # the max query size), occluders are drawn at the display's resolution and each
        # query pixel keeps the farthest depth it stands for: a gap the display shows
        # stays open in the query (conservative by construction; core.gl, display=).
        shown = fit(display, MAX_RESOLUTION)
        return options, res, (shown if shown != res else None)

    def prepare_steps(self, context, display, fresh=True):
        """The slow part of a first pass (reading geometry, building the engine) in
        steps, hiding nothing: a modal operator runs it, then :meth:`cull` (which then
        finds the engine built, or rebuilds what changed in between)."""
        _, res, shown = self._sizes(context, display)
        yield from self.engine_steps(context, res, context.scene.occ.strategy, verify=fresh, display=shown)

    def compute(self, context, camera, display, fresh=True, progress=None, restart=False, envelope=None,
                lights=None):
        """Visibility from ``camera`` at ``display`` resolution, without hiding anything.
        ``fresh``: the strategy forgets what earlier passes taught it that would cost
        accuracy (a Cull click, a camera cut, analyze, a scene change); only a live
        pass right after a small view change keeps all of it.  ``restart``: the answer
        is a new engine's first pass, whatever came before (a Cull click, an analysis's
        first frame: the same click gives the same answer).  ``progress``: called with
        the steps' ``(label, fraction)``.  ``envelope``: hide only what stays hidden
        while the view moves that far (:mod:`..core.envelope`)."""
        return drive(self.compute_steps(context, camera, display, fresh, restart, envelope, lights), progress)

    def compute_steps(self, context, camera, display, fresh=True, restart=False, envelope=None, lights=None):
        """:meth:`compute` in steps (see :meth:`engine_steps`)."""
        options, res, shown = self._sizes(context, display)
        # a fresh pass (a click, analyze, a scene change) also checks what the add-on
        # hides against its data: edits to hidden objects are never reported
        culler, objects = yield from self.engine_steps(context, res, context.scene.occ.strategy,
                                                       verify=fresh or restart, display=shown)
        culler.options = options
        if envelope == "rest":
            envelope = POLICY.rest(culler.scene_size)
        lights = lights or None
        if restart:
            culler.strategy.reset()
        elif fresh:
            culler.strategy.forget()
        return self.worker.run(culler.cull, camera, envelope=envelope, lights=lights), objects

    def cull(self, context, camera, display, fresh=False, progress=None, restart=False, envelope=None,
             show_only=False):
        """One pass: cull from ``camera`` at ``display`` resolution and apply it.

        ``envelope``: the pass hides only what stays hidden for every view of it
        (:attr:`shown` then holds the view and the envelope the hidden set is good
        for: live mode checks every redraw against it).  ``show_only``: a pass
        during motion: it shows what it finds visible and hides nothing new (what
        stays hidden is hidden in this pass too, so it holds for its envelope)."""
        settings = context.scene.occ
        t = time.perf_counter()
        visibility.reconcile()                 # what the user showed is the user's
        context.view_layer.update()            # edits still pending reach the handler now, not below
        view_rule = shading.rule(context)
        result, objects = self.compute(context, camera, display, fresh, progress, restart, envelope,
                                       view_rule.lights)
        state = result.state
        culled = state != Visibility.VISIBLE
        protected = self.protected(context, objects, culled)
        protected |= self.drawn_beyond_depth(view_rule, state)
        settings.last_rule = view_rule.why
        hide = np.isin(visibility.uids(), self.kept_uids[culled & ~protected])
        self.applying = True
        try:
            if show_only:
                visibility.release(~hide)
            else:
                visibility.apply(hide)
            # Showing an object again makes the depsgraph report it, and every
            # object sharing its mesh, as changed geometry.  Nothing else can have
            # changed since the update above, so evaluate now and let the handler
            # ignore it all: hiding never costs an engine rebuild on the next pass.
            context.view_layer.update()
        finally:
            self.applying = False
        ms = 1e3 * (time.perf_counter() - t)
        tri = self.culler.scene.triangle_counts
        settings.last_tested = len(objects)
        settings.last_occluded = int((state == Visibility.OCCLUDED).sum())
        settings.last_outside = int((state == Visibility.VIEW_CULLED).sum())
        settings.last_triangles_hidden = int(tri[culled & ~protected].sum())
        settings.last_ms = ms
        self.last = {"state": state, "protected": protected, "bounds": self.culler.scene.bounds,
                     "occupancy": result.occupancy, "stats": result.stats, "ms": ms}
        used = result.stats.get("envelope_distance")
        self.shown = None if used is None else (camera, Envelope(used, result.stats["envelope_angle_deg"],
                                                                 result.stats.get("envelope_any_roll", True)))
        self.version += 1
        return result, objects

    def drawn_beyond_depth(self, view_rule, state):
        """``(k,) bool``: what the view shows of the engine's objects beyond their depth
        (:mod:`.shading`): everything under ray tracing (unless the user opted in),
        every occluded object under X-ray.  (Shadow casters under scene lights are
        the engine's: the pass was given the lights.)"""
        n = len(state)
        if view_rule.mode == "raytraced" and not bpy.context.scene.occ.cull_raytraced:
            return np.ones(n, dtype=bool)
        if view_rule.mode == "xray":
            return state == Visibility.OCCLUDED
        return np.zeros(n, dtype=bool)

    def protected(self, context, objects, culled):
        """``(k,) bool`` over the engine's objects: never hidden.  The user's
        "never cull" flag and exclusion collection, members of instanced
        collections, instances of collections with members that draw without
        occluding, and dynamic objects (Blender stops evaluating what is hidden:
        see :func:`.extract.is_dynamic`), judged only where the engine would hide."""
        settings = context.scene.occ
        out = np.zeros(len(objects), dtype=bool)
        flagged = visibility.uids()[visibility.flags("occ_never_cull")]
        coll = settings.exclude_collection
        if coll is not None:
            members = coll.all_objects if settings.exclude_children else coll.objects
            flagged = np.concatenate([flagged, visibility.uids(members)])
        # Collection instances: their members are drawn in them too, so hiding a member
        # would hide its instances; and an instance whose collection holds something
        # that draws but does not occlude (wire, "in front", point clouds, ...) is
        # larger than its box.
        colls = {}
        for k in np.flatnonzero(self.kept_collection):
            c = objects[k].instance_collection
            colls.setdefault(ident(c), (c, []))[1].append(k)
        for c, at in colls.values():
            members = c.all_objects
            flagged = np.concatenate([flagged, visibility.uids(members)])
            if culled[at].any() and extract.draws_beyond_geometry(c):
                out[at] = True
        # ... and so are those of instances the engine does not hold (drawn as wire or
        # bounds, in front): hiding a member would take it out of them too
        for o in extract.bystanders(context.view_layer, self.kept_uids):
            if extract.is_instancer(o) and ident(o.instance_collection) not in colls:
                flagged = np.concatenate([flagged, visibility.uids(o.instance_collection.all_objects)])
        out[np.isin(self.kept_uids, flagged)] = True
        extractor = self.extractor
        for k in np.flatnonzero(culled & ~out):        # O(hidden), cached: what Blender has no bulk form of
            out[k] = extractor.is_dynamic(objects[k], int(self.kept_uids[k]))
        return out


def _replaced(culler, scene, strategy):
    """On the engine thread: ``culler`` rebuilt for ``scene`` (same GL context; meshes
    read unchanged keep their chunks), with ``strategy``."""
    try:
        culler.replace_scene(scene)
        if strategy != culler.strategy_name:
            culler.set_strategy(strategy)
    except BaseException:  # half replaced: the session dropped it, nothing else will close it
        culler.close()
        raise
    return culler


def _close_built(job):
    """On the engine thread, after the build ``job`` (jobs run in order): close what it built."""
    try:
        built = job.result()
    except Exception:  # noqa: BLE001 -- a build that failed built nothing to close
        return
    built.close()


SESSION = Session()


def fit(display, longest):
    """Scale ``display`` (W, H) down so its longest side is at most ``longest``."""
    w, h = display
    if w < 1 or h < 1:
        raise OccError(f"the view is {w}x{h} pixels: nothing to cull for")
    s = min(1.0, longest / max(w, h))
    return max(1, round(w * s)), max(1, round(h * s))


def find_viewport(context):
    """``(area, region, region_3d)`` of the active 3D viewport, else the first one of
    any window; None when there is none (timers have no area in their context)."""
    areas = []
    if context.area is not None and context.area.type == "VIEW_3D":
        areas.append(context.area)
    screens = [context.screen] if context.screen is not None else []
    screens += [w.screen for w in context.window_manager.windows] if context.window_manager else []
    areas += [a for s in screens for a in s.areas if a.type == "VIEW_3D"]
    for area in areas:
        region = next((r for r in area.regions if r.type == "WINDOW"), None)
        rv3d = area.spaces.active.region_3d
        if region is not None and rv3d is not None:
            return area, region, rv3d
    return None


def viewport_camera(context):
    """Camera and display size of the active 3D viewport (or the first one)."""
    if bpy.app.background:
        raise OccError("no 3D viewport in background mode: set the source to the scene camera")
    found = find_viewport(context)
    if found is None:
        raise OccError("no 3D viewport to cull for: use the scene camera as the source")
    _, region, rv3d = found
    camera = Camera.from_matrices(np.array(rv3d.view_matrix), np.array(rv3d.window_matrix))
    return camera, (region.width, region.height)


def camera_view(cam):
    """View matrix of a camera object as Blender renders it: from the rotation and
    position of its world matrix, its scale ignored (a mirroring scale keeps its
    sign: Blender renders a mirrored camera mirrored)."""
    m = np.array(cam.matrix_world, dtype=np.float64)
    axes = m[:3, :3]
    length = np.linalg.norm(axes, axis=0)
    if not np.all(np.isfinite(m)) or np.any(length < 1e-12 * max(1.0, float(np.abs(m[:3, 3]).max()))):
        raise OccError(f"the camera '{cam.name}' has a scale of 0 or a NaN in its transform: "
                       "its view direction is undefined; reset its scale (Alt+S)")
    world = np.eye(4)
    world[:3, :3] = axes / length
    world[:3, 3] = m[:3, 3]
    if abs(np.linalg.det(world[:3, :3])) < 0.5:        # sheared beyond recognition
        raise OccError(f"the camera '{cam.name}' has a sheared transform: apply or clear its parent's scale")
    return np.linalg.inv(world)


def scene_camera(context, scene=None):
    """Camera and render size of the scene camera, as Blender renders it (scale
    ignored; lens, shift, sensor fit, clipping and orthographic from
    ``calc_matrix_camera``).  Panoramic cameras are refused."""
    scene = scene or context.scene
    cam = scene.camera
    if cam is None:
        raise OccError("the scene has no camera: add one or cull from the viewport")
    if cam.type != "CAMERA":
        raise OccError(f"the scene camera '{cam.name}' is a {cam.type.lower()}, not a camera")
    if cam.data.type == "PANO":
        raise OccError(f"the camera '{cam.name}' is panoramic: only perspective and orthographic "
                       "cameras can be culled for; cull from the viewport instead")
    r = scene.render
    w = int(r.resolution_x * r.resolution_percentage / 100)
    h = int(r.resolution_y * r.resolution_percentage / 100)
    depsgraph = context.evaluated_depsgraph_get()
    proj = np.array(cam.calc_matrix_camera(depsgraph, x=max(w, 1), y=max(h, 1),
                                           scale_x=r.pixel_aspect_x, scale_y=r.pixel_aspect_y))
    view = camera_view(cam)
    if np.linalg.det(view[:3, :3]) < 0:
        # A mirrored camera sees what the camera mirrored back (its x axis turned
        # and its x shift negated) sees, in a mirrored image: the same objects,
        # with the ordinary winding.
        flip = np.diag([-1.0, 1.0, 1.0, 1.0])
        view, proj = flip @ view, flip @ proj @ flip
    return Camera.from_matrices(view, proj), (w, h)


def camera_for(context):
    if context.scene.occ.source == "CAMERA":
        return scene_camera(context)
    return viewport_camera(context)


LISTENERS = []          # called with no argument after every change not our own (live mode)


@persistent          # kept across file loads, like the add-on itself
def on_depsgraph_update(scene, depsgraph):
    """Mark what changed: geometry -> re-extract those objects (and instances of
    collections holding them); transforms are read in bulk every pass anyway.
    An object the user showed leaves the add-on's record here (every show is
    evaluated, so reported), before the user can hide it again."""
    if SESSION.applying:
        return
    visibility.reconcile()
    _mark(depsgraph)
    _guard_camera(scene)            # the scene camera moved by an edit: as for a new frame
    for f in LISTENERS:
        f()


@persistent
def on_frame_change(scene, depsgraph):
    """Animation moved things: the same marks as an edit (the frame's depsgraph reports them).
    Animation changes values, not what objects are; but it can change hide flags
    (keyframed collection visibility): the user-shown answers are asked again."""
    SESSION.extractor.visibility_changed()
    if depsgraph is not None:
        _mark(depsgraph, edits=False)
    _guard_camera(scene)
    for f in LISTENERS:
        f()


_camera_motion = {"view": None, "step": (0.0, 0.0)}


def _guard_camera(scene):
    """Live from the scene camera, a new frame (playback, scrubbing) or an edit moves
    it: where it is about to leave the hidden set's envelope, everything is shown
    before the frame is drawn (the live pass that follows hides again)."""
    if SESSION.shown is None or SESSION.busy or not scene.occ.live or scene.occ.source != "CAMERA":
        return
    try:
        camera, _ = scene_camera(bpy.context, scene)
    except OccError:
        camera = None
    prev = _camera_motion["view"]
    if camera is not None and prev is not None and np.array_equal(prev.projection, camera.projection):
        from ..core.motion import view_change
        _camera_motion["step"] = view_change(prev, camera)
    _camera_motion["view"] = camera
    centre, envelope = SESSION.shown
    if camera is None or not POLICY.safe(centre, envelope, camera, *_camera_motion["step"]):
        SESSION.shown = None
        visibility.restore()


def _mark(depsgraph, edits=True):
    geometry, moved = [], []
    extractor = SESSION.extractor
    for update in depsgraph.updates:
        if edits:
            extractor.saw(update)
        if isinstance(update.id, bpy.types.Object):
            if update.is_updated_geometry:
                geometry.append(ident(update.id.original))
            else:
                # moved, or any other change (display, in front, ...): what instances it
                # (a collection, a particle system, a vertex parent) may draw it otherwise
                moved.append(ident(update.id.original))
    if geometry or moved:
        SESSION.extractor.mark(geometry, moved)
