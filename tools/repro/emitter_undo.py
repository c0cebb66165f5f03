"""Plain bpy, no add-on: does Blender itself crash on a frame change after a hair
emitter's delete and undo (the crash the seeded workflows found; README Limits)?

    .venv/bin/python tools/repro/emitter_undo.py SEED        (or .venv-bpy42/bin/python ...)

Ten boxes and a hair emitter instancing a box, then 200 seeded steps: deletes, adds,
moves and mesh edits (each with an undo push), undos, and frame changes.  Prints
``OK SEED`` when it ends; a crash ends the process first.
"""

import random
import sys

import bpy

FACES = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def box(name, location):
    me = bpy.data.meshes.new(name)
    me.from_pydata([(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)], [], FACES)
    o = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(o)      # the scene again: an undo replaces it
    o.location = location
    return o


def push(message):
    bpy.ops.ed.undo_push(message=message)


def main(seed):
    rng = random.Random(seed)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.preferences.edit.undo_steps = 64
    for i in range(10):
        box(f"Prop.{i:03d}", (rng.uniform(-5, 5), rng.uniform(-5, 5), 0))
    emitter = box("Emitter", (0, 0, 0))
    source = box("HairSource", (3, 3, 0))
    emitter.modifiers.new("hair", "PARTICLE_SYSTEM")
    ps = emitter.particle_systems[0].settings
    ps.type, ps.count, ps.hair_length = "HAIR", 4, 1.0
    ps.render_type, ps.instance_object, ps.particle_size = "OBJECT", source, 2.5
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 60
    bpy.context.view_layer.update()
    push("start")
    for step in range(200):
        k = rng.random()
        objects = list(bpy.data.objects)
        if k < 0.15 and objects:
            bpy.data.objects.remove(rng.choice(objects), do_unlink=True)
            push("delete")
        elif k < 0.3:
            box(f"Added{step}", (rng.uniform(-5, 5), rng.uniform(-5, 5), 0))
            push("add")
        elif k < 0.45:
            try:
                bpy.ops.ed.undo()
            except RuntimeError:                      # nothing left to undo
                pass
        elif k < 0.6 and objects:
            rng.choice(objects).location.x += 0.3
            push("move")
        elif k < 0.7 and objects:
            o = rng.choice(objects)
            if o.type == "MESH":
                for v in o.data.vertices:
                    v.co.z *= 1.5
                o.data.update()
                push("mesh")
        else:
            bpy.context.scene.frame_set(rng.randint(1, 60))
    print("OK", seed)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 0)
