"""Hiding in one 3D view (occ_addon/localview.py, the view channel of visibility.py):
what a cull hides there, every other view still draws; the view is never moved and the
selection never changed; new objects, undo, save and reload, and the user's own local
view all keep every visible object drawn."""

import os

import bpy
import numpy as np

from .common import WORK, addon, box, check, cull, new_scene, promise, update


def _view():
    """(window, area, space) of the window's 3D view, and another screen's 3D view (a view
    the cull was not made for)."""
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    other = next(a.spaces.active for s in bpy.data.screens if s != win.screen
                 for a in s.areas if a.type == "VIEW_3D")
    return win, area, area.spaces.active, other


def _drawn_in(name, space):
    update()
    return bpy.data.objects[name].visible_get(viewport=space)


def _rv3d(area):
    return area.spaces.active.region_3d


def _view_of(area):
    r = _rv3d(area)
    return (tuple(round(x, 5) for x in r.view_location), tuple(round(x, 5) for x in r.view_rotation),
            round(r.view_distance, 5), r.view_perspective)


def _scene():
    new_scene()
    bpy.context.scene.occ.hide_in = "VIEW"
    box("target", (3, -1, 0), (4, 1, 1))
    box("front", (-3, 1, 0), (-2, 2, 1))            # before the wall: in plain sight
    update()


def hides_in_one_view():
    """A cull hides in its view only; the view is where the user left it, the selection as it was."""
    _scene()
    win, area, space, other = _view()
    bpy.data.objects["front"].select_set(True)
    before_view, sel = _view_of(area), [o.name for o in bpy.context.view_layer.objects.selected]
    cull()
    t = bpy.data.objects["target"]
    check("view_hides_in_its_view", t.occ_view_culled and not _drawn_in("target", space)
          and not t.hide_viewport, (t.occ_view_culled, _drawn_in("target", space), t.hide_viewport))
    check("view_other_view_draws_everything", all(_drawn_in(n, other) for n in ("target", "front", "wall")), "")
    check("view_visible_still_drawn", _drawn_in("front", space) and _drawn_in("wall", space), "")
    check("view_entering_moves_nothing", _view_of(area) == before_view
          and [o.name for o in bpy.context.view_layer.objects.selected] == sel,
          (_view_of(area), before_view))
    promise("view_truth")
    # the user orbits, then Restore: the view stays where the user put it, no local view
    r = _rv3d(area)
    r.view_location = (1.0, 2.0, 3.0)
    r.view_distance = 7.5
    moved = _view_of(area)
    bpy.ops.occ.restore()
    check("view_restore_leaves_view_unmoved", _view_of(area) == moved and space.local_view is None
          and _drawn_in("target", space) and not t.occ_view_culled, (_view_of(area), moved))
    # nothing selected: entering takes no selection of the user's
    for o in bpy.context.view_layer.objects.selected:
        o.select_set(False)
    cull()
    check("view_selection_untouched", not len(bpy.context.view_layer.objects.selected)
          and t.occ_view_culled, [o.name for o in bpy.context.view_layer.objects.selected])
    # the same cull hides in every view with "Every View"
    bpy.context.scene.occ.hide_in = "EVERYWHERE"
    cull()
    check("view_everywhere_is_monitor", t.hide_viewport and t.occ_culled and not t.occ_view_culled
          and space.local_view is None, (t.hide_viewport, t.occ_culled, t.occ_view_culled))
    bpy.ops.occ.restore()


def new_objects_drawn():
    """Objects that join the view layer while the add-on's local view is in force are drawn."""
    _scene()
    _, _, space, _ = _view()
    coll = bpy.data.collections.new("later")
    bpy.context.scene.collection.children.link(coll)
    box("in_later", (-2, 3, 0), (-1, 4, 1), coll)
    bpy.context.view_layer.layer_collection.children["later"].exclude = True
    update()
    cull()
    box("linked", (-2, -4, 0), (-1, -3, 1))         # a script links a new object
    update()
    check("view_new_object_drawn", _drawn_in("linked", space), "")
    bpy.context.view_layer.layer_collection.children["later"].exclude = False
    update()
    check("view_included_collection_drawn", _drawn_in("in_later", space), "")
    promise("view_new_truth")
    # the window shows another scene whose view layer has the same name and that links
    # objects of this one (a linked copy): they are drawn there, the culled one too (the
    # add-on's layer key is the layer's name; Blender's bits of such objects read set there)
    bpy.ops.occ.restore()
    win, _, space, _ = _view()
    first = win.scene
    other = bpy.data.scenes.new("Other")
    for name in ("front", "wall", "target"):
        other.collection.objects.link(bpy.data.objects[name])
    update()
    cull()                                          # the bits are set in the first scene's layer only
    win.scene = other
    update()
    addon("localview").on_window_change()          # the message bus's call, as a window's event loop makes it
    same_name = other.view_layers[0].name == first.view_layers[0].name
    check("view_other_scene_shared_drawn", same_name and space.local_view is not None
          and all(_drawn_in(n, space) for n in ("front", "wall", "target")),
          (same_name, {n: _drawn_in(n, space) for n in ("front", "wall", "target")}))
    win.scene = first
    update()
    addon("localview").on_window_change()
    bpy.ops.occ.restore()


def undo_and_files():
    """Undo brings the record back, not the views: the add-on's local view follows the
    record; files are saved without it and open with everything drawn."""
    _scene()
    _, _, space, _ = _view()
    bpy.ops.ed.undo_push(message="before cull")
    cull()
    bpy.data.objects["front"].location.z += 0.1      # an edit after the cull
    bpy.ops.ed.undo_push(message="edit")
    bpy.ops.ed.undo()                               # before the cull: no record, the view still local
    update()
    check("view_undo_keeps_visible_drawn", all(_drawn_in(n, space) for n in ("target", "front", "wall")),
          [(n, _drawn_in(n, space)) for n in ("target", "front", "wall")])
    bpy.ops.occ.restore()
    cull()
    path = os.path.join(WORK, "view_culled.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    t = bpy.data.objects["target"]
    check("view_save_keeps_culled", t.occ_view_culled and not _drawn_in("target", space), "")
    bpy.ops.wm.open_mainfile(filepath=path)
    _, _, space, _ = _view()
    t = bpy.data.objects["target"]
    check("view_saved_file_opens_drawn", space.local_view is None and not t.occ_view_culled
          and _drawn_in("target", space), (space.local_view, t.occ_view_culled))
    # The add-on's local view hiding nothing (the wall moved away) is not saved either: a
    # file opened with it would hold a local view the add-on does not know, which an undo
    # to bits of before would then empty.
    cull()
    bpy.data.objects["wall"].location.x += 40.0
    cull()
    in_local = space.local_view is not None and addon("localview").is_own(space)
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    _, _, space, _ = _view()
    check("view_saved_file_without_hiding_opens_plain", in_local and space.local_view is None,
          (in_local, space.local_view))


def users_local_view():
    """In the user's own local view the add-on hides only what it culls there and gives
    it back; the user's local view stays; leaving it ends the record."""
    _scene()
    win, area, space, _ = _view()
    for n in ("wall", "target"):
        bpy.data.objects[n].select_set(True)
    with bpy.context.temp_override(window=win, area=area, region=next(r for r in area.regions
                                                                      if r.type == "WINDOW")):
        bpy.ops.view3d.localview(frame_selected=False)
    for n in ("wall", "target"):
        bpy.data.objects[n].select_set(False)
    update()
    cull()
    t = bpy.data.objects["target"]
    check("view_user_local_culls", t.occ_view_culled and not _drawn_in("target", space)
          and not _drawn_in("front", space) and not addon("localview").is_own(space), "")
    bpy.ops.occ.restore()
    check("view_user_local_restored", space.local_view is not None and _drawn_in("target", space)
          and not _drawn_in("front", space), (space.local_view, _drawn_in("target", space)))
    # an undo to data of while it was culled (its bit clear, its record set) after the
    # Restore: the record has no view any more, and the user's local view draws it again
    cull()
    bpy.ops.ed.undo_push(message="culled")
    bpy.ops.occ.restore()
    bpy.data.objects["front"].location.z += 0.1
    bpy.ops.ed.undo_push(message="edit")
    bpy.ops.ed.undo()
    update()
    check("view_user_local_undo_to_culled_draws", space.local_view is not None and _drawn_in("target", space)
          and not bpy.data.objects["target"].occ_view_culled,
          (space.local_view, _drawn_in("target", space), bpy.data.objects["target"].occ_view_culled))
    bpy.ops.occ.restore()
    cull()
    with bpy.context.temp_override(window=win, area=area, region=next(r for r in area.regions
                                                                      if r.type == "WINDOW")):
        bpy.ops.view3d.localview(frame_selected=False)     # the user leaves local view
    update()
    flags = np.zeros(len(bpy.data.objects), dtype=bool)
    bpy.data.objects.foreach_get("occ_view_culled", flags)
    check("view_user_leaves_local_record_ends", not flags.any() and _drawn_in("target", space), flags.sum())


def toggle_waits_for_engine():
    """Blender's local-view operator runs only with the engine thread idle: Blender may
    read a Python context override without the GIL inside an operator, and crashed when
    the engine thread ran Python then (a save while a modal Cull built the engine)."""
    import time
    _scene()
    win, area, space, other = _view()
    SESSION = addon("session").SESSION
    cull()                                           # the own local view, and the engine thread
    job = SESSION.worker.submit(time.sleep, 0.5)     # the engine thread busy for half a second
    bpy.ops.occ.restore()                            # ends the own local view: view3d.localview
    check("view_operator_waits_for_engine", job.done() and space.local_view is None,
          (job.done(), space.local_view))


def failed_pass_keeps_selection():
    """The object a pass selects for Blender's local view (evaluated while the engine
    works) is deselected after the entry, and when the pass fails before it."""
    _scene()
    win, area, space, other = _view()
    SESSION = addon("session").SESSION
    for o in bpy.context.view_layer.objects.selected:
        o.select_set(False)
    cull()
    ok_entry = space.local_view is not None and not len(bpy.context.view_layer.objects.selected)
    bpy.ops.occ.restore()

    def broken(*_args, **_kwargs):
        raise RuntimeError("a pass that fails")

    culler = SESSION.culler
    culler.cull = broken                             # the engine's pass fails on its thread
    try:
        r, err = cull()
    finally:
        del culler.cull
    check("view_failed_pass_keeps_selection",
          ok_entry and r != {"FINISHED"} and not len(bpy.context.view_layer.objects.selected)
          and SESSION.picked is None and space.local_view is None,
          (ok_entry, r, [o.name for o in bpy.context.view_layer.objects.selected], space.local_view))
