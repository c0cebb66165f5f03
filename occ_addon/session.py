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
from ..core.settings import preset, query_resolution
from ..core.units import ChunkCache
from . import visibility
from .extract import Extractor
from .worker import EngineThread

# Meshes of 4 x this many triangles or more are cut into chunks of about this
# many (never a user's mesh: index ranges inside the engine's copy): a heavy
# object is then drawn and tested by its visible parts, not as one box.
CHUNK_TRIANGLES = 4096


class Session:
    def __init__(self):
        self.extractor = Extractor()
        self.chunks = ChunkCache()  # chunkings outlive engines: a resized viewport re-cuts nothing
        self.worker = EngineThread()
        self.culler = None
        self.names = None          # candidate names the engine was built for
        self.kept = None           # (k,) indices of the candidates the engine holds
        self.kept_names = None     # (k,) object array of their names
        self.resolution = None
        self.last = None           # the last applied pass, for the overlay (see :meth:`cull`)
        self.version = 0           # bumped by every applied pass
        self.applying = False      # the depsgraph updates now are our own hiding's

    def reset(self):
        """Forget everything (a file was loaded, or the add-on goes away)."""
        self.release()
        self.extractor = Extractor()
        self.chunks = ChunkCache()
        self.names = self.kept = self.kept_names = None
        self.last = None
        self.version += 1

    def release(self):
        if self.culler is not None:
            culler, self.culler = self.culler, None
            self.worker.run(culler.close)

    def shutdown(self):
        self.reset()
        self.worker.shutdown()

    def engine(self, context, resolution, strategy):
        """The engine for the current candidates: rebuilt when objects or geometry
        changed, otherwise only the moved objects' matrices are sent."""
        cand = self.extractor.candidates(context)
        if not len(cand):
            raise OccError("nothing to cull: the view layer has no visible mesh objects")
        rebuild = (self.culler is None or cand.names != self.names or resolution != self.resolution
                   or self.extractor.needs_geometry(cand))
        if rebuild:
            scene, kept = self.extractor.scene(context, cand)
            if self.culler is not None and resolution == self.resolution:
                # same context; meshes read unchanged from the cache keep their chunks
                self.worker.run(self.culler.replace_scene, scene)
                if strategy != self.culler.strategy_name:
                    self.worker.run(self.culler.set_strategy, strategy)
            else:
                self.release()
                self.culler = self.worker.run(Culler, scene, resolution, strategy=strategy,
                                              chunk_triangles=CHUNK_TRIANGLES, chunk_cache=self.chunks)
            self.names, self.kept, self.resolution = cand.names, kept, resolution
            self.kept_names = np.array(scene.names, dtype=object)
        else:
            if strategy != self.culler.strategy_name:
                self.worker.run(self.culler.set_strategy, strategy)
            m = self.extractor.matrices(cand, self.kept)
            moved = np.flatnonzero(np.any(m != self.culler.scene.matrices, axis=(1, 2)))
            if len(moved):
                self.worker.run(self.culler.set_matrices, moved, m[moved])
        return self.culler, [cand.objects[i] for i in self.kept]

    def compute(self, context, camera, display):
        """Visibility from ``camera`` at ``display`` resolution, without hiding anything."""
        settings = context.scene.occ
        options = preset(settings.preset)
        res = query_resolution(fit(display, settings.max_resolution), options)
        culler, objects = self.engine(context, res, settings.strategy)
        culler.options = options
        return self.worker.run(culler.cull, camera), objects

    def cull(self, context, camera, display):
        """One pass: cull from ``camera`` at ``display`` resolution and apply it."""
        settings = context.scene.occ
        t = time.perf_counter()
        context.view_layer.update()            # edits still pending reach the handler now, not below
        result, objects = self.compute(context, camera, display)
        state = result.state
        culled = state != Visibility.VISIBLE
        protected = visibility.protected(settings, self.kept_names)
        visibility.apply(self.kept_names[culled & ~protected])
        self.applying = True
        try:
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
        self.version += 1
        return result, objects


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


def scene_camera(context, scene=None):
    """Camera and render size of the scene camera."""
    scene = scene or context.scene
    cam = scene.camera
    if cam is None:
        raise OccError("the scene has no camera: add one or cull from the viewport")
    r = scene.render
    w = int(r.resolution_x * r.resolution_percentage / 100)
    h = int(r.resolution_y * r.resolution_percentage / 100)
    depsgraph = context.evaluated_depsgraph_get()
    proj = cam.calc_matrix_camera(depsgraph, x=max(w, 1), y=max(h, 1),
                                  scale_x=r.pixel_aspect_x, scale_y=r.pixel_aspect_y)
    view = np.array(cam.matrix_world.inverted())
    return Camera.from_matrices(view, np.array(proj)), (w, h)


def camera_for(context):
    if context.scene.occ.source == "CAMERA":
        return scene_camera(context)
    return viewport_camera(context)


@persistent          # kept across file loads, like the add-on itself
def on_depsgraph_update(scene, depsgraph):
    """Mark what changed: geometry -> re-extract those objects (and instances of
    collections holding them); transforms are read in bulk every pass anyway."""
    if SESSION.applying:
        return
    geometry, moved = [], []
    for update in depsgraph.updates:
        if isinstance(update.id, bpy.types.Object):
            if update.is_updated_geometry:
                geometry.append(update.id.original.name)
            elif update.is_updated_transform:
                moved.append(update.id.original.name)
    if geometry or moved:
        SESSION.extractor.mark(geometry, moved)
