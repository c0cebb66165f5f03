"""Plain bpy, no add-on: Blender 4.2 and 5.0 crash iterating a depsgraph's object
instances after a script removes (``bpy.data.objects.remove``) the object a
geometry-nodes Object Info node instances.

    .venv/bin/python tools/repro/gn_deleted_object_crash.py             # segfaults (bpy 5.0.1, 4.2.0)
    .venv/bin/python tools/repro/gn_deleted_object_crash.py --operator  # the Delete operator instead: no crash

The steps: a mesh whose geometry-nodes modifier instances object ``Source`` (Object
Info, as instance) on three points, evaluated; ``Source`` removed by a script; the view
layer evaluated again and its ``depsgraph.object_instances`` iterated.  The native stack
ends in Blender's dupli generation (``mul_m4_m4m4`` <- ``make_duplis_geometry_set_impl``
<- ``object_duplilist``).  The Delete operator (X) only unlinks such an
object (the node still uses it), so a user's delete does not get there; a script's or
another add-on's removal does.  Blender's viewport iterates the same instances to draw
them; the add-on's passes and the seeded workflows' truth iterate them to read what
instances draw, and met it there (workflow seeds 7016 on 4.2 and 7120 on 5.0.1, whose
step removes an object with ``bpy.data.objects.remove``, and 7038 without the add-on).
Blender 5.2.4 runs it to the end.  Prints ``NO CRASH`` when Blender survives.
"""

import argparse

import bpy


def cube(scene, name, x):
    me = bpy.data.meshes.new(name)
    me.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)], [],
                   [(0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)])
    obj = bpy.data.objects.new(name, me)
    scene.collection.objects.link(obj)
    obj.location = (x, 0.0, 0.0)
    return obj


def object_scatter(source):
    """A node group: the input geometry plus ``source`` instanced on three points."""
    ng = bpy.data.node_groups.new("scatter", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gin, gout = ng.nodes.new("NodeGroupInput"), ng.nodes.new("NodeGroupOutput")
    line = ng.nodes.new("GeometryNodeMeshLine")
    line.inputs["Count"].default_value = 3
    info = ng.nodes.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = source
    info.inputs["As Instance"].default_value = True
    points = ng.nodes.new("GeometryNodeInstanceOnPoints")
    join = ng.nodes.new("GeometryNodeJoinGeometry")
    ng.links.new(line.outputs["Mesh"], points.inputs["Points"])
    ng.links.new(info.outputs["Geometry"], points.inputs["Instance"])
    ng.links.new(gin.outputs[0], join.inputs[0])
    ng.links.new(points.outputs["Instances"], join.inputs[0])
    ng.links.new(join.outputs[0], gout.inputs[0])
    return ng


def instances():
    return sum(1 for i in bpy.context.evaluated_depsgraph_get().object_instances if i.is_instance)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--operator", action="store_true", help="delete with the Delete operator (X in the viewport)")
    args = p.parse_args()
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    source = cube(scene, "Source", 3.0)
    host = cube(scene, "Host", 0.0)
    host.modifiers.new("scatter", "NODES").node_group = object_scatter(source)
    bpy.context.view_layer.update()
    print(f"Blender {bpy.app.version_string}: {instances()} instances", flush=True)
    if args.operator:
        for o in scene.objects:
            o.select_set(o == source)
        bpy.ops.object.delete()
    else:
        bpy.data.objects.remove(source, do_unlink=True)
    bpy.context.view_layer.update()
    print(f"after the deletion: {instances()} instances", flush=True)
    print("NO CRASH", flush=True)


if __name__ == "__main__":
    main()
