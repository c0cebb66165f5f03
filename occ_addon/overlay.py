"""Viewport overlay (GUI only): wireframes of the boxes that were culled, a small
inset of the occupancy map and the last pass's figures.  Installed on the first
pass in a window, never at registration or in background mode."""

from dataclasses import dataclass

import bpy
import numpy as np

from ..core.overlay import box_lines, occupancy_quads
from . import visibility
from .session import SESSION

MAX_BOXES = 4000            # wireframes drawn at most (the largest culled ones)
INSET = 160                 # occupancy inset width in pixels
_handles = []


@dataclass
class Drawn:
    """What the overlay draws of one pass (made once per pass, not per redraw): the
    culled boxes' wireframe lines ``(2m, 3) float32`` and the occupancy map ``(rows,
    cols) bool``; their GPU batches, made at the first redraw that draws them."""

    version: int                 # the session's pass (SESSION.version) it was made for
    lines: np.ndarray
    grid: np.ndarray
    batch: object = None         # the wireframes' batch
    inset: tuple | None = None   # the inset's (shader, backdrop, tiles or None, height)


_drawn: list[Drawn] = []         # the last pass's, once drawn


def _shader(kind):
    import gpu
    for name in ("UNIFORM_COLOR", f"{kind}_UNIFORM_COLOR"):     # Blender 4+, then 3.x
        try:
            return gpu.shader.from_builtin(name)
        except (ValueError, TypeError):
            continue
    raise RuntimeError("no uniform-colour shader")


def _geometry():
    last = SESSION.last
    if last is None:
        return None
    if not _drawn or _drawn[0].version != SESSION.version:
        boxes = last.hidden_bounds
        if len(boxes) > MAX_BOXES:
            size = np.prod(np.maximum(boxes[:, 1] - boxes[:, 0], 1e-9), axis=1)
            boxes = boxes[np.argsort(size)[-MAX_BOXES:]]
        grid = last.occupancy if last.occupancy is not None else np.zeros((0, 0), dtype=bool)
        _drawn[:] = [Drawn(SESSION.version, box_lines(boxes), grid)]
    return _drawn[0]


def _in_culled_view() -> bool:
    """Whether this redraw is of a view the add-on hides in (all, when it hides everywhere)."""
    view = visibility.hiding_view()
    space = bpy.context.space_data
    return view is None or (space is not None and space.as_pointer() == view)


def _draw_view():
    scene = bpy.context.scene
    geo = _geometry()
    if geo is None or not scene.occ.show_overlay or not len(geo.lines) or not _in_culled_view():
        return
    import gpu
    from gpu_extras.batch import batch_for_shader
    shader = _shader("3D")
    gpu.state.blend_set("ALPHA")
    if geo.batch is None:                           # one batch per pass, not per redraw
        geo.batch = batch_for_shader(shader, "LINES", {"pos": geo.lines})
    batch = geo.batch
    shader.bind()
    shader.uniform_float("color", (1.0, 0.35, 0.25, 0.5))
    batch.draw(shader)
    gpu.state.blend_set("NONE")


def _inset(grid):
    """The occupancy inset's batches (its backdrop, the occupied tiles or None) and
    height in pixels: made once per pass, not per redraw."""
    from gpu_extras.batch import batch_for_shader
    shader = _shader("2D")
    h = INSET * grid.shape[0] / max(grid.shape[1], 1)
    back = np.array([[20, 20], [20 + INSET, 20], [20 + INSET, 20 + h], [20, 20], [20 + INSET, 20 + h],
                     [20, 20 + h]], dtype=np.float32)
    quads = occupancy_quads(grid, 20, 20, INSET, h)
    return (shader, batch_for_shader(shader, "TRIS", {"pos": back}),
            batch_for_shader(shader, "TRIS", {"pos": quads}) if len(quads) else None, h)


def _draw_pixel():
    scene = bpy.context.scene
    geo = _geometry()
    if geo is None or not scene.occ.show_overlay or not _in_culled_view():
        return
    import blf
    import gpu
    grid = geo.grid
    top = 30
    if grid.size:
        if geo.inset is None:                       # one set of batches per pass, not per redraw
            geo.inset = _inset(grid)
        shader, back, tiles, h = geo.inset
        gpu.state.blend_set("ALPHA")
        shader.bind()
        shader.uniform_float("color", (0.0, 0.0, 0.0, 0.5))
        back.draw(shader)
        if tiles is not None:
            shader.uniform_float("color", (0.3, 0.9, 0.4, 0.6))
            tiles.draw(shader)
        gpu.state.blend_set("NONE")
        top = 30 + h
    blf.size(0, 13)
    blf.position(0, 20, top, 0)
    blf.draw(0, SESSION.last.summary())


def install():
    """Add the overlay's draw handlers once (GUI only; live mode's redraw guard is
    live's own: :func:`.live.install`)."""
    if bpy.app.background or _handles:
        return
    space = bpy.types.SpaceView3D
    _handles.append(space.draw_handler_add(_draw_view, (), "WINDOW", "POST_VIEW"))
    _handles.append(space.draw_handler_add(_draw_pixel, (), "WINDOW", "POST_PIXEL"))


def uninstall():
    space = bpy.types.SpaceView3D
    while _handles:
        space.draw_handler_remove(_handles.pop(), "WINDOW")
    _drawn.clear()
