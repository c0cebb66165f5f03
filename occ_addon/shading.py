"""What the culled view draws beyond depth: shadows, rays, X-ray; and the rule it sets.

- Solid (Workbench), Wireframe, Material Preview without scene lights: only what
  is drawn shows; the depth rule alone.
- X-ray (Solid or Wireframe, or Workbench's own for the camera), Workbench's
  backface culling, or its Texture color where a material may show an image with alpha
  (:func:`.materials.images_with_alpha`): what is behind shows through, so nothing
  occluded is hidden (what is outside the view still is; with shadows on, their casters
  are kept as under lights).  A see-through material (glass, alpha, a material's
  own backface culling) makes its object no occluder in every mode (:mod:`.materials`);
  a see-through material override of the view layer, drawn on every object by EEVEE and
  Cycles (not by Workbench: measured), is X-ray there.
- Scene lights (Material Preview or Rendered with scene lights, EEVEE for the
  camera; Solid with shadows, whose light is ``scene.display.light_direction`` in
  view space):
  an object also shows through its shadow, so every object whose shadow volume
  may hold a point that is seen is kept (:mod:`..core.lights`).  A world that
  extracts a sun from an image (``world.use_sun_shadow`` with an image or sky
  texture; the scene's world or the view layer's override) shadows from a direction
  nobody can read here: nothing is hidden.  The lights are those the view layer drawn
  shows (the context's: the window's, the one rendered).
- Ray tracing (Cycles, any engine this add-on does not know, EEVEE with ray
  tracing on, with a light probe that captures the scene for reflections, or through
  the camera with depth of field and Jitter Camera, which draws from the whole lens):
  reflections and light from hidden objects reach the screen, so nothing is hidden
  unless the user opts in (``scene.occ.cull_raytraced``).
"""

import math
from dataclasses import dataclass, field

import bpy
import numpy as np

from ..core.lights import Light
from ..core.tolerance import tol
from . import identity
from .cameras import clip_region, find_viewport, origins_all, passepartout_shows, through_scene_camera
from .materials import images_with_alpha, material_see_through

EEVEE = ("BLENDER_EEVEE", "BLENDER_EEVEE_NEXT")
WORKBENCH = "BLENDER_WORKBENCH"
SUN_WIDEN = math.radians(2.0)   # shadow-map filtering blurs an edge: the sun's disc taken this much wider
RADIUS_WIDEN = 0.05             # and a light's emitter this much larger (of its distance scale, below)


@dataclass
class ViewRule:
    """``mode``: "depth", "xray", "lit", "raytraced" or "shown" (nothing hidden, whatever
    the settings); ``lights`` for "lit"; ``why`` says it in words (the panel, the report)."""

    mode: str
    why: str
    lights: list = field(default_factory=list)
    clip: np.ndarray | None = None     # the culled view's clipping region (:func:`.cameras.clip_region`)
    outside_shows: bool = False        # the view draws beyond the pass's frustum (a camera's passepartout)


def key(rule: ViewRule) -> tuple:
    """What of ``rule`` a hidden set holds under: its mode, its words, the clipping region
    and every light's place, reach and size.  A light shown again by its eye, or
    Workbench's light turned (``scene.display``), changes the shadows while the words
    stay as they were."""
    clip = None if rule.clip is None else rule.clip.tobytes()
    return (rule.mode, rule.why, clip, rule.outside_shows, tuple((light.kind, tuple(light.position.tolist()),
                                              tuple(light.direction.tolist()), light.radius, light.angle,
                                              light.reach, light.in_view) for light in rule.lights))


def rule(context, source=None):
    """The rule for what ``source`` ("VIEWPORT" or "CAMERA") draws, in the context's view
    layer (the window's: its lights, its overrides).  Without ``source`` (the setting's: a
    pass that hides in the culled view, in a window), also for what that view draws
    besides: the regions of a Quad View draw the same objects from three more sides, the
    Origins (All) overlay every object's origin over walls, and a view that does not look
    through the scene camera shows what the camera's set hides, so nothing is hidden there;
    a clipping region's planes (:func:`.cameras.clip_region`)."""
    view = None if source is not None or bpy.app.background else find_viewport(context)
    if view is None:
        return _rule(context, source or context.scene.occ.source)
    space = view[0].spaces.active
    # the pass hides in this view: what it draws by its own shading, through the scene
    # camera too (measured: through the camera with Solid's shadows, hidden boxes' shadows
    # went, 25 px, under the render's rule, EEVEE with no lights)
    found = _view_rule(context.scene, context.view_layer, space, view[2])
    if len(space.region_quadviews):
        return ViewRule("shown", "Quad View draws this view's objects from three more sides", found.lights)
    if origins_all(space):
        # measured (Blender 3.4): a box's origin dot, 37 px, drawn through the wall before it
        return ViewRule("shown", "the Origins (All) overlay draws every object's origin through walls", found.lights)
    if context.scene.occ.source == "CAMERA" and not through_scene_camera(space, context.scene):
        # the camera's set, in a view that looks from elsewhere: what it hides, the view may show
        return ViewRule("shown", "Scene Camera: a 3D view hides only while it looks through the scene's "
                                 "camera (Numpad 0)", found.lights)
    found.clip = clip_region(view[2])
    # through the camera the view also draws around its frame (the passepartout darkens it,
    # measured: a box right of the frame, 5,709 px, was hidden as outside the camera's view)
    found.outside_shows = context.scene.occ.source == "CAMERA" and passepartout_shows(context.scene.camera)
    return found


def _rule(context, source):
    scene, layer = context.scene, context.view_layer
    engine = scene.render.engine
    found = None if source == "CAMERA" else find_viewport(context)
    if found is None:                          # the camera, or headless: what the camera renders
        if scene.render.use_multiview:
            return _stereo_rule()
        return _render_rule(scene, layer, engine, True, True, True)
    return _view_rule(scene, layer, found[0].spaces.active, found[2])


def view_rule(context, space) -> ViewRule:
    """The rule for what 3D view ``space`` draws by its own shading (through the scene
    camera too: Solid with shadows, Material Preview, not the render's), in the context's
    view layer."""
    return _view_rule(context.scene, context.view_layer, space, space.region_3d)


def _view_rule(scene, layer, space, rv3d):
    engine = scene.render.engine
    shading = space.shading
    through_camera = rv3d.view_perspective == "CAMERA"
    if through_camera and scene.render.use_multiview:
        return _stereo_rule()
    kind = shading.type
    if kind == "WIREFRAME":
        # Blender draws what is behind wherever X-ray is on below full opacity (its own
        # test, as for Solid): at Wireframe's default alpha of 0 every wire shows through
        if shading.show_xray_wireframe and shading.xray_alpha_wireframe < 1.0:
            return ViewRule("xray", "Wireframe with X-ray shows what is behind")
        return ViewRule("depth", "Wireframe")
    if kind == "SOLID":
        return _workbench_rule(scene, shading, "Solid")
    if kind == "MATERIAL":
        return _overridden(scene, layer, _eevee_rule(scene, layer, shading.use_scene_lights,
                                                     shading.use_scene_world, through_camera, "Material Preview"))
    return _render_rule(scene, layer, engine, shading.use_scene_lights_render, shading.use_scene_world_render,
                        through_camera)


def _render_rule(scene, layer, engine, scene_lights, scene_world, through_camera):
    if engine == WORKBENCH:                    # Workbench draws no material override (measured: 5.0, 4.2)
        return _workbench_rule(scene, scene.display.shading, "Workbench")
    if engine in EEVEE:
        return _overridden(scene, layer, _eevee_rule(scene, layer, scene_lights, scene_world, through_camera, "EEVEE"))
    name = "Cycles" if engine == "CYCLES" else engine
    return _overridden(scene, layer, ViewRule("raytraced",
                                              f"{name} traces rays: reflections and light from hidden objects show"))


def _stereo_rule():
    """Stereoscopy (``render.use_multiview``): the camera's view is drawn from two eyes
    beside it (or from other cameras, by suffix), in any engine: seen from one, an object
    hidden from the camera's centre shows."""
    return ViewRule("raytraced", "Stereoscopy: the camera's view is drawn from more than one eye")


def _jittered_lens(scene) -> bool:
    """Whether EEVEE draws the scene camera from every point of its lens: depth of field
    with **Jitter Camera** (measured: an object hidden behind a thin pillar near the camera
    shows in 121 pixels of EEVEE's render at f/0.2, bpy 5.0.1: ``policy.jittered_lens``;
    Workbench's depth of field, and EEVEE's without the jitter, blur the image drawn from
    the lens's centre)."""
    cam = scene.camera
    return (cam is not None and cam.type == "CAMERA" and cam.data.dof.use_dof
            and bool(getattr(scene.eevee, "use_bokeh_jittered", False)))


def _overridden(scene, layer, base):
    """``base``, or X-ray where the view layer draws every object with one material
    (``ViewLayer.material_override``, drawn by EEVEE and Cycles) that may show what is
    behind it (:func:`.materials.material_see_through`).  Under ray tracing nothing is
    hidden anyway, unless the user opted in to culling there."""
    over = getattr(layer, "material_override", None)
    if over is None or not material_see_through(over):
        return base
    if base.mode == "raytraced" and not scene.occ.cull_raytraced:
        return base
    return ViewRule("xray", "The view layer's material override may show what is behind", base.lights)


def _workbench_rule(scene, shading, label):
    if shading.show_xray and shading.xray_alpha < 1.0:
        return ViewRule("xray", f"{label} with X-ray shows what is behind")
    if getattr(shading, "show_backface_culling", False):
        return ViewRule("xray", f"{label} with backface culling shows what is behind a wall seen from behind")
    lights = []
    if shading.show_shadows:
        # Workbench's light turns with the view (measured: its direction is in view
        # space); which way it points is not read here: both ways
        d = np.array(scene.display.light_direction, dtype=np.float64)
        lights = [Light("sun", direction=d, angle=SUN_WIDEN, in_view=True),
                  Light("sun", direction=-d, angle=SUN_WIDEN, in_view=True)]
    if shading.color_type == "TEXTURE" and images_with_alpha(bpy.data.materials):
        # the image's alpha shows what is behind, whatever the material's nodes do; its
        # shadows (the lights) still count for what is outside the view
        return ViewRule("xray", f"{label} in Texture color shows what is behind an image's alpha", lights)
    if lights:
        return ViewRule("lit", f"{label} with shadows: shadow casters kept", lights)
    return ViewRule("depth", label)


def _eevee_rule(scene, layer, scene_lights, scene_world, through_camera, label):
    if getattr(scene.eevee, "use_raytracing", False) or getattr(scene.eevee, "use_ssr", False):
        return ViewRule("raytraced", f"{label} with ray tracing: reflections of hidden objects show")
    if through_camera and _jittered_lens(scene):
        return ViewRule("raytraced", f"{label} with Jitter Camera depth of field: the lens sees around what is near")
    if _reflection_probe(scene):
        return ViewRule("raytraced", f"{label} with a reflection probe: reflections of hidden objects show")
    lights = []
    # the view layer's world (``world_override``, 4.2+) in place of the scene's: either
    if scene_world and (_world_sun(scene.world) or _world_sun(getattr(layer, "world_override", None))):
        return ViewRule("lit", f"{label}: the world casts sun shadows from its image", [Light("everywhere")])
    if scene_lights:
        lights = scene_lights_of(scene, layer)
    if lights:
        return ViewRule("lit", f"{label} with scene lights: shadow casters kept", lights)
    return ViewRule("depth", label)


def _world_sun(world):
    if world is None or not getattr(world, "use_sun_shadow", False) or not world.use_nodes:
        return False
    return any(n.type in ("TEX_ENVIRONMENT", "TEX_SKY") for n in world.node_tree.nodes)


# light probes that capture the scene for reflections (4.1+ names, and before): a sphere
# probe's capture is drawn again with what is shown (measured: an object outside the
# camera's view changes 3,648 pixels of EEVEE's render through one, bpy 5.0.1:
# ``policy.reflection_probe``); a plane probe is a live mirror.  Volume probes hold baked
# light: what is hidden later stays in it.
REFLECTION_PROBES = {"SPHERE", "PLANE", "CUBEMAP", "PLANAR"}
_TYPES = bpy.types.Object.bl_rna.properties["type"].enum_items
LIGHT_TYPE = _TYPES["LIGHT"].value
PROBE_TYPE = _TYPES["LIGHT_PROBE"].value
# Blender 4.2+ reads an enum in bulk as its items' values (checked in 4.2, 5.0, 5.2);
# Blender 3.4's foreach_get of an enum fills the array with garbage
BULK_ENUMS = bpy.app.version >= (4, 2, 0)


def _objects_of_type(scene, value: int) -> list:
    """The objects of one type (``value``: its enum value), from one bulk read of every
    object's type where Blender reads enums in bulk (no attribute read per object), else
    the scene's objects (the caller checks each object's type and visibility)."""
    if not BULK_ENUMS:
        return list(scene.objects)
    objects = bpy.data.objects
    types = np.zeros(identity.count(), dtype=np.int32)
    objects.foreach_get("type", types)
    at = np.flatnonzero(types == value).tolist()
    items = objects.values() if at else []       # one list; indexing the collection is O(i)
    return [items[i] for i in at]


def _reflection_probe(scene) -> bool:
    """Whether ``scene`` holds a light probe that reflects what it captures (hidden by its
    eye or not: read conservatively)."""
    if not any(p.type in REFLECTION_PROBES for p in bpy.data.lightprobes):
        return False
    return any(o.type == "LIGHT_PROBE" and o.data.type in REFLECTION_PROBES and scene in o.users_scene
               for o in _objects_of_type(scene, PROBE_TYPE))


def scene_lights_of(scene, layer):
    """Every light object drawn in ``layer`` (a view layer of ``scene``: the window's, whose
    lights the view draws, or the one rendered) that casts shadows, as
    :class:`..core.lights.Light` (world space)."""
    out = []
    if not any(light.use_shadow for light in bpy.data.lights):    # no light data that casts shadows
        return out
    # every light object (the view layer's visibility below keeps the scene's)
    for o in _objects_of_type(scene, LIGHT_TYPE):
        if o.type != "LIGHT" or not o.data.use_shadow:
            continue
        if layer is not None and not o.visible_get(view_layer=layer):
            continue
        light = o.data
        m = np.array(o.matrix_world, dtype=np.float64)
        pos = m[:3, 3]
        axis = -m[:3, 2] / max(np.linalg.norm(m[:3, 2]), tol.tiny)   # lights shine down their -Z
        scale = float(np.abs(np.linalg.norm(m[:3, :3], axis=0)).max())
        reach = light.cutoff_distance if getattr(light, "use_custom_distance", False) else math.inf
        if light.type == "SUN":
            out.append(Light("sun", direction=axis, angle=light.angle + SUN_WIDEN))
            continue
        radius = float(light.shadow_soft_size) * scale
        if light.type == "AREA":
            sx = light.size * scale
            sy = (light.size_y if light.shape in ("RECTANGLE", "ELLIPSE") else light.size) * scale
            radius = max(radius, 0.5 * math.hypot(sx, sy))
        radius = radius * (1.0 + RADIUS_WIDEN) + RADIUS_WIDEN * max(scale, 1e-3)
        kind = {"POINT": "point", "SPOT": "spot", "AREA": "area"}.get(light.type, "point")
        out.append(Light(kind, position=pos, radius=radius, reach=reach))
    return out
