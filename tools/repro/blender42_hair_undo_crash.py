"""Plain bpy, no add-on: a crash of Blender 4.2 LTS in ``scene.frame_set`` after an
emitter's delete and undo, with a second view layer shown.  Unlike
``../shared/repro/blender_hair_undo_two_layers.py`` (Blender 4.2 and 5.0), no object is
moved or tagged: adding an object after the second layer is shown is enough.

    .venv-bpy42/bin/python tools/repro/blender42_hair_undo_crash.py   # exit 139 or 134 in 2 runs of 3
    .venv/bin/python tools/repro/blender42_hair_undo_crash.py         # bpy 5.0.1: "NO CRASH" (3 of 3)

The seeded workflows' seed 829 (``--hide-in VIEW``, bpy 4.2) crashes in the same frame
change after the same steps (its emitter deleted, an undo back past the deletion),
with and without the add-on's tags (it tags no object it does not show).
"""

import bpy

FACES = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def box(name, loc):
    me = bpy.data.meshes.new(name)
    me.from_pydata([(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)], [], FACES)
    o = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(o)
    o.location = loc
    return o


bpy.ops.wm.read_homefile(use_empty=True)
scene = bpy.context.scene
emitter, source = box("Emitter", (0, 0, 0)), box("HairSource", (3, 3, 0))
emitter.modifiers.new("hair", "PARTICLE_SYSTEM")
ps = emitter.particle_systems[0].settings
ps.type, ps.count, ps.render_type, ps.instance_object = "HAIR", 4, "OBJECT", source
bpy.context.view_layer.update()                   # the first view layer's depsgraph, evaluated
bpy.ops.ed.undo_push(message="build")

layer = scene.view_layers.new("Second")           # a second view layer, shown in the window
bpy.context.window.view_layer = layer
bpy.context.view_layer.update()
bpy.ops.ed.undo_push(message="view layer")

box("Other", (6, 6, 0))                           # an object added; nothing else touched
bpy.context.view_layer.update()
bpy.data.objects.remove(emitter, do_unlink=True)  # the emitter deleted ...
bpy.ops.ed.undo_push(message="delete")
bpy.ops.ed.undo()                                 # ... and back
bpy.context.view_layer.update()

print("evaluating every view layer", flush=True)
bpy.context.scene.frame_set(55)
print("NO CRASH", flush=True)
