"""Whether an object may let what is behind it show through its materials: such an
object is no occluder (and, like wire display, takes no part: never hidden either).

An object is see-through where any material it draws with could be, in any shading
mode, since the rule must hold in every one and a mode switch re-reads nothing:

- Workbench: the material's viewport alpha (``diffuse_color``) or the object's color
  alpha below 1, or back faces culled (``use_backface_culling``: a single-sided wall seen
  from behind is not drawn);
- EEVEE and Cycles (Material Preview, Rendered, the camera's render): a surface shader
  that is not proved opaque.  Proved opaque: the active material output's surface is a
  tree of opaque closures (diffuse, glossy, emission, subsurface, sheen, toon, translucent,
  holdout, Principled with alpha 1 and no transmission, EEVEE's Specular without
  transparency, all of those through mix and add nodes), with nothing on its volume
  input.  Anything else (transparent, glass, refraction, a ray portal, a node group, an
  unlinked shader socket, an alpha driven by a texture) is taken as see-through.  An
  object camera rays do not see (``visible_camera`` off) is not drawn there at all.  A
  material with true displacement (a linked Displacement output, method other than bump
  only) may be drawn away from its mesh: it takes no part either.

Workbench's Texture color draws each material's image with the image's own alpha, whatever
its node tree does with it (measured: 4.2, 5.0): :func:`images_with_alpha` tells whether any
material may show such an image, and the view's rule (:mod:`.shading`) hides nothing
occluded then.

Materials are asked once each and remembered until a material or a node tree changes
(:func:`forget`, from the extractor's depsgraph marks; an image's update forgets nothing:
no answer kept here reads one, and a movie texture updates its image every frame) or the
session resets.
"""

from .identity import ident

OPAQUE_CLOSURES = {"BSDF_DIFFUSE", "BSDF_GLOSSY", "BSDF_ANISOTROPIC", "BSDF_METALLIC", "EMISSION",
                   "SUBSURFACE_SCATTERING", "BSDF_VELVET", "BSDF_SHEEN", "BSDF_TOON", "BSDF_TRANSLUCENT",
                   "HOLDOUT", "BSDF_PRINCIPLED", "EEVEE_SPECULAR", "BSDF_HAIR", "BSDF_HAIR_PRINCIPLED"}
MIXERS = {"MIX_SHADER", "ADD_SHADER"}
# inputs of an opaque closure that must stay at their value, unlinked: (name, opaque value)
HELD_INPUTS = {"BSDF_PRINCIPLED": (("Alpha", 1.0), ("Transmission Weight", 0.0), ("Transmission", 0.0)),
               "EEVEE_SPECULAR": (("Transparency", 0.0),)}
MAX_DEPTH = 64
# what forgets the answers (not an image: no answer kept here reads one; a movie texture
# updates its image every frame)
UPDATES = {"Material", "ShaderNodeTree", "NodeTree"}

# image depths (ImBuf planes) without an alpha channel: grey, RGB at 8, 16 and 32 bits
NO_ALPHA_DEPTHS = {8, 24, 48, 96}

_memo: dict = {}


def forget() -> None:
    _memo.clear()


def image_may_have_alpha(image) -> bool:
    """Whether ``image`` may carry an alpha below 1: not when its alpha is ignored
    (``alpha_mode`` NONE), a JPEG, or loaded without an alpha channel (read only when
    loaded: loading a file here would cost a pass its time)."""
    if image is None or image.alpha_mode == "NONE" or image.file_format == "JPEG":
        return False
    return not (image.has_data and image.depth in NO_ALPHA_DEPTHS)


def _tree_images_alpha(tree, depth: int = 0) -> bool:
    for node in tree.nodes:
        if node.type == "TEX_IMAGE" and image_may_have_alpha(node.image):
            return True
        sub = getattr(node, "node_tree", None) if node.type == "GROUP" else None
        if sub is not None and depth < MAX_DEPTH and _tree_images_alpha(sub, depth + 1):
            return True
    return False


def material_image_alpha(mat) -> bool:
    """Whether Workbench's Texture color may draw ``mat`` with an image's alpha below 1
    (any image texture of its tree, in groups too: Workbench draws the active one).  Read
    each time: an image's alpha mode, file or pixels change without a depsgraph update
    (measured, bpy 5.0: none reported), so no answer is kept."""
    if mat is None or not getattr(mat, "use_nodes", True) or mat.node_tree is None:
        return False
    return _tree_images_alpha(mat.node_tree)


def images_with_alpha(materials) -> bool:
    """Whether any of ``materials`` (used ones) may show an image's alpha in Texture color
    (asked only for a view in Texture color)."""
    return any(m.users and material_image_alpha(m) for m in materials)


def _follow(socket, seen: int) -> bool:
    """Whether the shader reaching ``socket`` (an input) is proved opaque."""
    if not socket.is_linked or seen > MAX_DEPTH:
        return False
    link = socket.links[0]
    if not link.is_valid or link.is_muted:
        return False
    node = link.from_node
    while node.type == "REROUTE" and seen <= MAX_DEPTH:
        if not node.inputs[0].is_linked:
            return False
        link = node.inputs[0].links[0]
        if not link.is_valid or link.is_muted:
            return False
        node, seen = link.from_node, seen + 1
    if node.mute:
        return False
    if node.type in MIXERS:
        shaders = [s for s in node.inputs if s.type == "SHADER"]
        return len(shaders) == 2 and all(_follow(s, seen + 1) for s in shaders)
    if node.type not in OPAQUE_CLOSURES:
        return False
    for name, value in HELD_INPUTS.get(node.type, ()):
        s = node.inputs.get(name)
        if s is not None and (s.is_linked or abs(float(s.default_value) - value) > 1e-6):
            return False
    return True


def _tree_opaque(tree) -> bool:
    outputs = [n for n in tree.nodes if n.type == "OUTPUT_MATERIAL"]
    if not outputs:
        return False
    for out in outputs:
        volume = out.inputs.get("Volume")
        if volume is not None and volume.is_linked:
            return False
        surface = out.inputs.get("Surface")
        if surface is None or not _follow(surface, 0):
            return False
    return True


def material_see_through(mat) -> bool:
    """Whether ``mat`` may show what is behind it (in any mode), or be drawn elsewhere than
    its mesh (true displacement); None material: opaque."""
    if mat is None:
        return False
    key = ident(mat)
    hit = _memo.get(key)
    if hit is None:
        hit = bool(mat.diffuse_color[3] < 1.0 or mat.use_backface_culling)
        if not hit and getattr(mat, "use_nodes", True) and mat.node_tree is not None:
            hit = not _tree_opaque(mat.node_tree) or _displaced(mat)
        _memo[key] = hit
    return hit


def _displaced(mat) -> bool:
    """Whether EEVEE (from 4.2) or Cycles may draw ``mat``'s surface away from its mesh: a
    material output's Displacement linked with a method that moves the surface (not bump
    only).  Where it is drawn, the add-on cannot tell: such an object takes no part."""
    method = getattr(mat, "displacement_method", None)          # 4.2 on; before, Cycles's own
    if method is None:
        method = getattr(getattr(mat, "cycles", None), "displacement_method", "BUMP")
    if method == "BUMP":
        return False
    return any(n.type == "OUTPUT_MATERIAL" and n.inputs.get("Displacement") is not None
               and n.inputs["Displacement"].is_linked for n in mat.node_tree.nodes)


def see_through(obj) -> bool:
    """Whether ``obj`` may let what is behind it show: its object color, its materials, or
    camera rays that pass through it (``visible_camera`` off: EEVEE from 4.2 and Cycles draw
    nothing of it, in the render and in the Rendered view; measured in EEVEE's render, bpy
    4.2 and 5.0)."""
    if obj.color[3] < 1.0 or not getattr(obj, "visible_camera", True):
        return True
    return any(material_see_through(s.material) for s in obj.material_slots)
