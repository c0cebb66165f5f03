"""Seeded sample scenes with their camera paths, generated on first use and cached.

    import sample_scenes
    path = sample_scenes.scene_path("city")            # a .glb under .cache/scenes/
    cams = sample_scenes.default_camera_path("city")   # {"frames": [camera, ...]}
    cams = sample_scenes.default_camera_path("city", small=True)   # the path of city-small

Nothing generated is committed: the cache lives in ``$OCC_CACHE_DIR`` or
``<repo>/.cache/scenes`` (git-ignored), keyed by name, size and generator version.
"""

import importlib
import os
from pathlib import Path

import numpy as np

NAMES = ("city", "assembly", "vessels", "cathedral", "isosurface", "city-xl")
VERSION = 1           # bump when a generator changes: old cache entries are ignored
SEEDS = {"city": 1, "assembly": 2, "vessels": 3, "cathedral": 4, "isosurface": 5, "city-xl": 1}


def _module(name):
    if name not in NAMES:
        raise ValueError(f"unknown sample scene '{name}'; choose one of {', '.join(NAMES)}")
    return importlib.import_module(f".{name.replace('-', '_')}", __name__)


def cache_dir():
    env = os.environ.get("OCC_CACHE_DIR")
    return Path(env) if env else Path(__file__).resolve().parent.parent / ".cache" / "scenes"


def build_scene(name, small=False):
    """The scene as a ``trimesh.Scene`` (deterministic for a name and size)."""
    return _module(name).build(np.random.default_rng(SEEDS[name]), small=small)


def scene_path(name, cache_dir_=None, small=False, joined=False):
    """Path of the scene's GLB, generating it on first use (written atomically).

    joined: every object merged into one mesh (one node, "joined"), the case of a
    user's scene that was never cut for culling.
    """
    mod = _module(name)
    folder = Path(cache_dir_) if cache_dir_ else cache_dir()
    path = folder / f"{name}{'-small' if small else ''}{'-joined' if joined else ''}-v{VERSION}.glb"
    if not path.exists():
        folder.mkdir(parents=True, exist_ok=True)
        scene = mod.build(np.random.default_rng(SEEDS[name]), small=small)
        if joined:
            import trimesh
            merged = trimesh.Scene()
            merged.add_geometry(scene.to_geometry(), node_name="joined", geom_name="joined")
            scene = merged
        tmp = path.with_suffix(f".tmp{os.getpid()}")
        scene.export(tmp, file_type="glb")
        os.replace(tmp, path)
    return path


def camera_paths(name, small=False):
    """``{path name: {"frames": [camera, ...]}}``; the first is the default."""
    return _module(name).paths(small=small)


def default_camera_path(name, small=False):
    """The scene's first camera path, fitted to its size (``small=True`` for the -small scene)."""
    return next(iter(camera_paths(name, small).values()))
