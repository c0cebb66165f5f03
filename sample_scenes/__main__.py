"""``python -m sample_scenes NAME [--small]``: generate a sample scene and print its size."""

import argparse
import time

import sample_scenes


def main():
    p = argparse.ArgumentParser(prog="python -m sample_scenes")
    p.add_argument("name", choices=sample_scenes.NAMES + ("all",))
    p.add_argument("--small", action="store_true")
    args = p.parse_args()
    for name in sample_scenes.NAMES if args.name == "all" else (args.name,):
        t = time.perf_counter()
        path = sample_scenes.scene_path(name, small=args.small)
        scene = sample_scenes.build_scene(name, small=args.small)
        tris = sum(len(scene.geometry[scene.graph[n][1]].faces) for n in scene.graph.nodes_geometry)
        print(f"{name}{' (small)' if args.small else ''}: {len(scene.graph.nodes_geometry)} objects, "
              f"{tris:,} triangles, {path.stat().st_size / 1e6:.1f} MB at {path} "
              f"({time.perf_counter() - t:.1f} s)")


main()
