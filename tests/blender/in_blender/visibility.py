"""The hide record (occ_addon/visibility.py): the user owns every hide flag."""


import bpy

from .common import addon, box, check, cull, hidden_by_addon, new_scene, update


def user_hide_wins():
    """A user's show then hide on an object the add-on hid is the user's hide."""
    new_scene()
    box("target", (3, -1, 0), (4, 1, 1))
    update()
    cull()
    t = bpy.data.objects["target"]
    hid = hidden_by_addon("target")
    t.hide_viewport = False
    update()
    t.hide_viewport = True
    update()
    bpy.ops.occ.restore()
    check("user_hide_kept_by_restore", hid and bpy.data.objects["target"].hide_viewport,
          (hid, bpy.data.objects["target"].hide_viewport))
    cull()
    bpy.ops.occ.restore()
    check("user_hide_kept_by_pass", bpy.data.objects["target"].hide_viewport
          and not bpy.data.objects["target"].occ_culled, "")


def records_read_once_a_pass():
    """Within one pass (identity.one_pass) the records read from the memo are what a
    fresh bulk read of Blender's data gives, through a seeded run of the module's
    writes (item by item and in bulk), over all objects and over a view layer holding
    some of them; an object a handler adds inside a pass's update is seen after it
    (identity.evaluate); outside a pass a write not of the module's (a script) is seen."""
    import random

    import numpy as np
    vis, ids = addon("visibility"), addon("identity")
    new_scene()
    layer_coll = bpy.data.collections.new("part")
    bpy.context.scene.collection.children.link(layer_coll)
    for i in range(40):
        box(f"b{i}", (i, 0, 0), (i + 0.5, 1, 1), coll=layer_coll if i % 3 else None)
    bpy.context.view_layer.layer_collection.children["part"].exclude = True   # the layer holds some
    update()
    layer = bpy.context.view_layer.objects

    def fresh(prop, coll=None):
        coll = bpy.data.objects if coll is None else coll
        out = np.zeros(len(coll), dtype=bool)
        coll.foreach_get(prop, out)
        return out

    rng = random.Random(11)
    bad = []
    with ids.one_pass():
        for step in range(60):
            prop = rng.choice(ids.RECORDS)
            n = len(bpy.data.objects)
            new = np.array([rng.random() < 0.5 for _ in range(n)])
            if rng.random() < 0.5:                    # few changed: item by item
                new = ids.flags(prop)
                new[rng.randrange(n)] ^= True
            vis._set_record(prop, ids.flags(prop), new)
            for p in ids.RECORDS:
                if not np.array_equal(ids.flags(p), fresh(p)):
                    bad.append(("flags", step, p))
                lf = ids.layer_flags(p, ids.uids(layer), layer)
                if not np.array_equal(lf, fresh(p, layer)):
                    bad.append(("layer", step, p))

    def fresh_uids():
        out = np.zeros(len(bpy.data.objects), dtype=np.int64)
        bpy.data.objects.foreach_get("session_uid", out)
        return out

    added = []

    def add_extra(*_):                                # another add-on's handler that adds an object
        bpy.app.handlers.depsgraph_update_post.remove(add_extra)
        added.append(box("a_extra", (0, 5, 0), (1, 6, 1)))   # (first by name: every index moves)

    with ids.one_pass():                              # identities: read once, and a new object seen
        first = ids.uids()
        if not np.array_equal(first, fresh_uids()) or not np.array_equal(ids.uids(), first):
            bad.append("uids in a pass")
        bpy.app.handlers.depsgraph_update_post.append(add_extra)
        bpy.data.objects["b0"].location.x += 0.25     # an edit, evaluated by the pass's update
        ids.evaluate(bpy.context.view_layer)
        if not added:
            bad.append("the handler did not run inside the update")
        elif not np.array_equal(ids.uids(), fresh_uids()) or ids.ident(added[0]) not in ids.uids():
            bad.append("uids after an object was added inside an update")
        if not np.array_equal(ids.flags("occ_culled"), fresh("occ_culled")):
            bad.append("records after an object was added inside an update")
        if not np.array_equal(ids.layer_flags("occ_culled", ids.uids(layer), layer), fresh("occ_culled", layer)):
            bad.append("layer records after an object was added inside an update")
    if add_extra in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(add_extra)
    for extra in added:
        bpy.data.objects.remove(extra)
    ob = bpy.data.objects["b5"]

    def record_of(o):
        return bool(ids.flags("occ_culled")[list(bpy.data.objects).index(o)])

    # kept across passes over the same objects (only the add-on writes a record); read
    # again once the session forgets (undo, redo, a file load) or the objects differ
    before = record_of(ob)
    ob.occ_culled = not before                        # written behind the add-on's back
    if record_of(ob) != before:
        bad.append("a kept record was read again over the same objects")
    ids.forget()
    if record_of(ob) == before:
        bad.append("a record not read again after forget (undo, load)")
    ob.occ_culled = before
    extra = box("kept_extra", (0, 9, 0), (1, 10, 1))
    if record_of(ob) != before or not np.array_equal(ids.flags("occ_culled"), fresh("occ_culled")):
        bad.append("a record kept over other objects")
    bpy.data.objects.remove(extra)
    if not np.array_equal(ids.flags("occ_culled"), fresh("occ_culled")):
        bad.append("a record kept after an object was removed")
    ids.store("occ_culled", np.zeros(len(bpy.data.objects), dtype=bool))
    ids.store(ids.VIEW_RECORD, np.zeros(len(bpy.data.objects), dtype=bool))
    check("records_read_once_a_pass", not bad, bad[:5])
