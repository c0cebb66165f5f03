"""One culling session per Blender session: the extraction cache, the engine
(kept while only transforms change) and the camera of a pass."""

import time
from concurrent.futures import ThreadPoolExecutor

import bpy
import numpy as np

from ..core import Camera, Culler, OccError, Visibility
from ..core.settings import preset, query_resolution
from . import visibility
from .extract import Extractor

# The engine's OpenGL context lives on its own thread: a context is current per
# thread, so Blender's own (on the main thread) is never switched away from.
_GL_THREAD = ThreadPoolExecutor(max_workers=1, thread_name_prefix="occ-gl")


def on_gl_thread(fn, *args, **kwargs):
    """Run ``fn`` on the engine's GL thread and wait for it (exceptions propagate)."""
    return _GL_THREAD.submit(fn, *args, **kwargs).result()


class Session:
    def __init__(self):
        self.extractor = Extractor()
        self.culler = None
        self.names = None
        self.resolution = None
        self.strategy = None
        self.last = None           # (state per object, names) of the last pass

    def invalidate(self, names=None):
        """Geometry changed (``names`` or everything): the engine is rebuilt next pass."""
        self.extractor.mark(names)
        self.release()

    def release(self):
        if self.culler is not None:
            on_gl_thread(self.culler.close)
        self.culler = None

    def engine(self, context, resolution, strategy):
        scene, objects = self.extractor.scene(context)
        same = (self.culler is not None and self.names == scene.names
                and self.resolution == resolution and self.strategy == strategy)
        if same:
            moved = np.flatnonzero(~np.all(np.isclose(self.culler.scene.matrices, scene.matrices,
                                                      rtol=0.0, atol=0.0), axis=(1, 2)))
            if len(moved):
                on_gl_thread(self.culler.set_matrices, moved, scene.matrices[moved])
        else:
            self.release()
            self.culler = on_gl_thread(Culler, scene, resolution, strategy=strategy)
            self.names, self.resolution, self.strategy = scene.names, resolution, strategy
        return self.culler, objects

    def compute(self, context, camera, display):
        """Visibility from ``camera`` at ``display`` resolution, without hiding anything."""
        settings = context.scene.occ
        options = preset(settings.preset)
        res = query_resolution(fit(display, settings.max_resolution), options)
        culler, objects = self.engine(context, res, settings.strategy)
        culler.options = options
        return on_gl_thread(culler.cull, camera), objects

    def cull(self, context, camera, display):
        """One pass: cull from ``camera`` at ``display`` resolution and apply it."""
        settings = context.scene.occ
        t = time.perf_counter()
        result, objects = self.compute(context, camera, display)
        culler = self.culler
        protected = visibility.excluded_names(settings)
        hide = [o.name for o, s in zip(objects, result.state, strict=True)
                if s != Visibility.VISIBLE and o.name not in protected]
        visibility.apply(hide)
        ms = 1e3 * (time.perf_counter() - t)
        tri = culler.scene.triangle_counts
        settings.last_tested = len(objects)
        settings.last_occluded = int((result.state == Visibility.OCCLUDED).sum())
        settings.last_outside = int((result.state == Visibility.VIEW_CULLED).sum())
        settings.last_triangles_hidden = int(tri[result.state != Visibility.VISIBLE].sum())
        settings.last_ms = ms
        self.last = (result, [o.name for o in objects])
        return result, objects


SESSION = Session()


def fit(display, longest):
    """Scale ``display`` (W, H) down so its longest side is at most ``longest``."""
    w, h = display
    if w < 1 or h < 1:
        raise OccError(f"the view is {w}x{h} pixels: nothing to cull for")
    s = min(1.0, longest / max(w, h))
    return max(1, round(w * s)), max(1, round(h * s))


def viewport_camera(context):
    """Camera and display size of the active 3D viewport (or the first one)."""
    if bpy.app.background:
        raise OccError("no 3D viewport in background mode: set the source to the scene camera")
    area = context.area if context.area and context.area.type == "VIEW_3D" else None
    if area is None and context.screen is not None:
        area = next((a for a in context.screen.areas if a.type == "VIEW_3D"), None)
    if area is None:
        raise OccError("no 3D viewport to cull for: use the scene camera as the source")
    region = next((r for r in area.regions if r.type == "WINDOW"), None)
    rv3d = area.spaces.active.region_3d
    if region is None or rv3d is None:
        raise OccError("the 3D viewport has no view region")
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


def on_depsgraph_update(scene, depsgraph):
    """Mark what changed: geometry -> re-extract those objects; transforms are
    picked up by comparing matrices on the next pass."""
    names = set()
    for update in depsgraph.updates:
        if isinstance(update.id, bpy.types.Object) and update.is_updated_geometry:
            names.add(update.id.original.name)
    if names:
        SESSION.invalidate(names)
