"""What asking every object's materials costs (:mod:`occ_addon.materials`), in bpy.

    .venv/bin/python tools/bench/see_through_cost.py [--objects 50000]

Builds OBJECTS one-triangle objects (one in ten with a mesh of its own), 20 node materials
spread over them, and times :func:`occ_addon.kinds.kind` over all of them with the
materials' answers forgotten first (a first pass, or the pass after a material edit), and
:func:`occ_addon.materials.see_through` alone with its answers remembered.  Prints ms.
"""

import argparse
import importlib.util
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--objects", type=int, default=50000)
    n = ap.parse_args(argv).objects
    import bpy
    spec = importlib.util.spec_from_file_location("occ_ext", os.path.join(ROOT, "__init__.py"),
                                                  submodule_search_locations=[ROOT])
    sys.modules["occ_ext"] = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(sys.modules["occ_ext"])
    from occ_ext.occ_addon import kinds, materials
    bpy.ops.wm.read_homefile(use_empty=True)
    me = bpy.data.meshes.new("m")
    me.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    mats = [bpy.data.materials.new(f"M{i}") for i in range(20)]
    for m in mats:
        m.use_nodes = True
    objs = [bpy.data.objects.new(f"o{i}", me.copy() if i % 10 == 0 else me) for i in range(n)]
    for k, m in enumerate(mats):
        objs[k * 10].data.materials.append(m)
    me.materials.append(mats[0])
    for _ in range(2):
        materials.forget()
        t = time.perf_counter()
        for o in objs:
            kinds.kind(o)
        first = time.perf_counter() - t
        t = time.perf_counter()
        for o in objs:
            materials.see_through(o)
        warm = time.perf_counter() - t
        print(f"{n:,} objects: kind() with the materials asked {1e3 * first:.0f} ms; "
              f"see_through() remembered {1e3 * warm:.0f} ms")


if __name__ == "__main__":
    main(sys.argv[1:])
