"""The cameras of a pass, as Blender draws them: the active 3D viewport's view and
the scene camera as it renders (its scale ignored).  Each returns a
:class:`..core.Camera` and the display size it is drawn at, ``(W, H)`` pixels, or
raises an :class:`..core.OccError` the user can act on."""

import math

import bpy
import numpy as np

from ..core import Camera, OccError
from ..core.camera import perspective
from . import localview


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
        rv3d = area.spaces.active.region_3d
        if rv3d is None:
            continue
        # the region that draws the view's own region data (a Quad View has four)
        windows = [r for r in area.regions if r.type == "WINDOW"]
        region = next((r for r in windows if r.data is not None and r.data.as_pointer() == rv3d.as_pointer()),
                      windows[0] if windows else None)
        if region is not None:
            return area, region, rv3d
    return None


def pass_view(context):
    """The 3D view (``SpaceView3D``) a pass is made for: the one :func:`viewport_camera`
    culls for when the source is the viewport; None for the scene camera, in background
    mode or with no 3D viewport (then Blender's default: the context's own 3D view, if any).
    What it does not draw (local view, local collections, object-type filters) takes no part."""
    if context.scene.occ.source != "VIEWPORT" or bpy.app.background:
        return None
    found = find_viewport(context)
    return None if found is None else found[0].spaces.active


def hide_view(context):
    """``(window, area)`` of the 3D view a pass hides in (its local-view bits, see
    :mod:`.localview`), or None: everywhere (``hide_viewport``).  The culled view:
    the active 3D viewport (the one the scene camera is looked through, too), with
    the "Hide In" setting at This View, or at Auto in a window (not background mode)."""
    mode = context.scene.occ.hide_in
    if mode == "EVERYWHERE" or (mode == "AUTO" and bpy.app.background):
        return None
    found = find_viewport(context)
    if found is None:
        return None
    area = found[0]
    wm = context.window_manager
    win = context.window if context.window is not None and area in context.window.screen.areas[:] else None
    win = win or next((w for w in (wm.windows if wm else ()) if area in w.screen.areas[:]), None)
    return None if win is None else (win, area)


def view_state(space) -> tuple | None:
    """What of a 3D view, beside its camera, decides which objects it draws and what shows
    beyond depth: local view, local collections, every object-type filter, the shading
    that sets the pass's rule, the clipping region, Quad View, the Origins (All) overlay,
    where a camera view's frame sits (what a camera's set holds for) and the view's Local
    Camera; None without a view.  A
    pass's hidden set holds only while this stays as it was (a wall filtered out occludes
    nothing; X-ray shows what is behind)."""
    if space is None:
        return None
    if not _FILTERS:                          # read once: the redraw guard asks on every redraw
        _FILTERS.extend(p.identifier for p in space.bl_rna.properties
                        if p.identifier.startswith("show_object_viewport_"))
    filters = tuple(getattr(space, name) for name in _FILTERS)
    look = shading_look(space)
    clip = clip_region(space.region_3d)              # a region set after a pass uncovers what it cut
    # the add-on's own local view (its hiding) draws what the view drew: not the user's
    # through the camera: where the frame sits in the region (zoom, pan, the region's size
    # and the lens: its window matrix), which decides what it draws around the frame
    rv3d = space.region_3d
    through = None if rv3d is None or rv3d.view_perspective != "CAMERA" else tuple(map(tuple, rv3d.window_matrix))
    own = local_camera(space)
    return (localview.user_local(space), bool(getattr(space, "use_local_collections", False)), filters, look,
            None if clip is None else clip.tobytes(), len(space.region_quadviews), through, origins_all(space),
            None if own is None else own.name)


def origins_all(space) -> bool:
    """Whether 3D view ``space`` draws every object's origin (the Origins (All) overlay),
    over whatever stands before it."""
    overlay = space.overlay
    return bool(overlay.show_overlays and overlay.show_object_origins_all)


_FILTERS: list[str] = []                      # SpaceView3D's object-type filters (they vary by version)


def shading_look(space) -> tuple:
    """What of 3D view ``space``'s shading sets a pass's rule (:func:`.shading.rule`):
    X-ray, a Texture color that shows an image's alpha, scene lights hide less than depth
    alone."""
    shading = space.shading
    return tuple(getattr(shading, name, None) for name in SHADING_RULE)


SHADING_RULE = ("type", "show_xray", "xray_alpha", "show_xray_wireframe", "xray_alpha_wireframe",
                "show_backface_culling", "show_shadows", "color_type", "use_scene_lights", "use_scene_world",
                "use_scene_lights_render", "use_scene_world_render")


def clip_region(rv3d) -> np.ndarray | None:
    """The planes ``(6, 4)`` of a 3D view's clipping region (Alt+B), inside where
    ``a x + b y + c z + d > 0`` for each (a quad view's box clip leaves rows of zeros);
    None when the view has none."""
    if rv3d is None or not getattr(rv3d, "use_clip_planes", False):
        return None
    return np.array([tuple(p) for p in rv3d.clip_planes], dtype=np.float64).reshape(-1, 4)


def region_camera(rv3d) -> Camera:
    """The camera of a 3D view's region data (its view and window matrices)."""
    return Camera.from_matrices(np.array(rv3d.view_matrix), np.array(rv3d.window_matrix))


def viewport_camera(context) -> tuple[Camera, tuple[int, int]]:
    """Camera and display size of the active 3D viewport (or the first one)."""
    if bpy.app.background:
        raise OccError("no 3D viewport in background mode: set the source to the scene camera")
    found = find_viewport(context)
    if found is None:
        raise OccError("no 3D viewport to cull for: use the scene camera as the source")
    _, region, rv3d = found
    return region_camera(rv3d), (region.width, region.height)


# Blender's viewport lens: 36 mm of sensor at a zoom of 2 across the region's longer side
VIEWPORT_SENSOR_MM = 72.0
TWIN_SLACK = 1.01            # the twin's lens a hair wider than Blender's (a wider one is conservative)


def perspective_twin(context) -> Camera | None:
    """The perspective camera an orthographic 3D view turns into without a redraw between
    (the add-on acts only at a redraw): at the start of an orbit from a view aligned to an
    axis (Front, Top, ...) under the Auto Perspective preference, and at Numpad 5.  The
    same pivot, rotation and distance (its eye stands the view's distance behind the
    pivot; an orthographic view's matrix has its eye at the pivot), the view's lens and
    clipping, a hair wider.  None where the pass is not of such a view (the scene camera's
    source, a view through a camera, a perspective view, background mode)."""
    if bpy.app.background or context.scene.occ.source != "VIEWPORT":
        return None
    found = find_viewport(context)
    if found is None:
        return None
    area, region, rv3d = found
    if rv3d.view_perspective != "ORTHO":
        return None
    space = area.spaces.active
    w, h = max(region.width, 1), max(region.height, 1)
    tan = VIEWPORT_SENSOR_MM / 2.0 / space.lens * TWIN_SLACK       # half the longer side, in tangent
    tx, ty = (tan, tan * h / w) if w >= h else (tan * w / h, tan)
    proj = perspective(math.degrees(2.0 * math.atan(ty)), tx / ty, space.clip_start, space.clip_end)
    world = np.eye(4)
    world[:3, :3] = np.array(rv3d.view_rotation.to_matrix(), dtype=np.float64)
    world[:3, 3] = np.array(rv3d.view_location, dtype=np.float64) + world[:3, 2] * rv3d.view_distance
    return Camera(np.linalg.inv(world), proj)


def camera_view(cam, matrix: np.ndarray | None = None) -> np.ndarray:
    """``(4, 4)`` view matrix of a camera object as Blender renders it: from the rotation
    and position of its world matrix (``matrix``: that matrix at another frame, see
    :mod:`.keyed_camera`), its scale ignored (a mirroring scale keeps its sign: Blender
    renders a mirrored camera mirrored)."""
    m = np.array(cam.matrix_world if matrix is None else matrix, dtype=np.float64)
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


def scene_camera(context, scene=None, matrix: np.ndarray | None = None) -> tuple[Camera, tuple[int, int]]:
    """Camera and render size of the scene camera, as Blender renders it (scale
    ignored; lens, shift, sensor fit, clipping and orthographic from
    ``calc_matrix_camera``).  Panoramic cameras are refused.  ``matrix``: the camera's
    world matrix at another frame than the one evaluated (:mod:`.keyed_camera`)."""
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
    view = camera_view(cam, matrix)
    if np.linalg.det(view[:3, :3]) < 0:
        # A mirrored camera sees what the camera mirrored back (its x axis turned
        # and its x shift negated) sees, in a mirrored image: the same objects,
        # with the ordinary winding.
        flip = np.diag([-1.0, 1.0, 1.0, 1.0])
        view, proj = flip @ view, flip @ proj @ flip
    return Camera.from_matrices(view, proj), (w, h)


def camera_for(context, scene=None) -> tuple[Camera, tuple[int, int]]:
    """The camera of the ``scene.occ.source`` setting and its display size (the scene
    camera's as the culled view draws it, :func:`around_the_frame`)."""
    scene = scene or context.scene
    if scene.occ.source == "CAMERA":
        return around_the_frame(context, scene, *scene_camera(context, scene))
    return viewport_camera(context)


def through_scene_camera(space, scene) -> bool:
    """Whether 3D view ``space`` looks through ``scene``'s camera (Numpad 0): in camera
    view, and not through a camera of its own (the view's Local Camera)."""
    rv3d = space.region_3d
    if rv3d is None or rv3d.view_perspective != "CAMERA":
        return False
    own = local_camera(space)
    return own is None or own == scene.camera


def local_camera(space):
    """The camera object 3D view ``space`` looks through of its own (View > Local Camera),
    or None: it looks through the scene's."""
    return space.camera if getattr(space, "use_local_camera", False) else None


def passepartout_shows(cam) -> bool:
    """Whether a view through camera object ``cam`` draws what lies around the camera's
    frame: always, but under an opaque passepartout (it only darkens below alpha 1)."""
    return not (cam is not None and cam.type == "CAMERA" and cam.data.show_passepartout
                and cam.data.passepartout_alpha >= 1.0)


def around_the_frame(context, scene, camera: Camera, display: tuple[int, int]) -> tuple[Camera, tuple[int, int]]:
    """The scene camera (``camera``, ``display``: as it renders) as a window's culled view
    that looks through it draws it: the frame sits inside the view's region, and around it
    the region draws on (darkened by a passepartout below alpha 1), so an object occluded
    inside the frame can show beyond it (measured: a bar's far end, 9,311 px, was hidden).
    There the camera keeps its view and its projection is mapped from the frame to the
    whole region (the region's own window matrix against the render's, x and y rows; zoomed
    in, the region may show less than the frame), at the region's size; elsewhere
    (background, no view through the camera, an opaque passepartout) it is returned as
    given."""
    found = None if bpy.app.background else find_viewport(context)
    if found is None or not through_scene_camera(found[0].spaces.active, scene) or not passepartout_shows(scene.camera):
        return camera, display
    _, region, rv3d = found
    proj, drawn = camera.projection, np.array(rv3d.window_matrix, dtype=np.float64)
    w_row = proj[3]                      # (0, 0, -1, 0) perspective, (0, 0, 0, 1) orthographic
    mapped = proj.copy()
    for axis in (0, 1):
        scale = drawn[axis, axis] / proj[axis, axis]
        shift = float(np.dot(drawn[axis] - scale * proj[axis], w_row))
        if not (np.isfinite(scale) and scale > 0.0 and np.isfinite(shift)):
            return camera, display       # (a region not drawn yet)
        mapped[axis] = scale * proj[axis] + shift * w_row
    return Camera(camera.view, mapped), (max(region.width, 1), max(region.height, 1))
