"""Primitive meshes and placement helpers for the sample scenes (trimesh + numpy)."""

import numpy as np
import trimesh


def box(size=(1.0, 1.0, 1.0)):
    return trimesh.creation.box(extents=size)


def sphere(subdivisions=3, radius=1.0):
    """Icosphere: 20 * 4**subdivisions triangles."""
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)


def cylinder(radius=1.0, height=1.0, sections=32):
    return trimesh.creation.cylinder(radius=radius, height=height, sections=sections)


def tube(radius=1.0, length=1.0, sections=32, rings=24):
    """An open tube along +Z from 0 to ``length``: ``2 * sections * (rings - 1)`` triangles."""
    a = np.linspace(0.0, 2 * np.pi, sections, endpoint=False)
    z = np.linspace(0.0, length, rings)
    verts = np.stack(np.broadcast_arrays(radius * np.cos(a)[None], radius * np.sin(a)[None], z[:, None]),
                     axis=-1).reshape(-1, 3)
    i = np.arange(rings - 1)[:, None] * sections
    j = np.arange(sections)[None]
    a0, a1 = i + j, i + (j + 1) % sections
    b0, b1 = a0 + sections, a1 + sections
    faces = np.concatenate([np.stack([a0, a1, b1], -1), np.stack([a0, b1, b0], -1)], axis=0).reshape(-1, 3)
    return trimesh.Trimesh(verts, faces, process=False)


def sweep(path, radius, sections=12):
    """A tube of ``radius`` along a polyline ``(k, 3)`` (cables)."""
    path = np.asarray(path, dtype=np.float64)
    d = np.gradient(path, axis=0)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ref = np.where(np.abs(d[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    u = np.cross(d, ref)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(d, u)
    a = np.linspace(0.0, 2 * np.pi, sections, endpoint=False)
    ring = np.cos(a)[None, :, None] * u[:, None] + np.sin(a)[None, :, None] * v[:, None]
    verts = (path[:, None] + radius * ring).reshape(-1, 3)
    k = len(path)
    i = np.arange(k - 1)[:, None] * sections
    j = np.arange(sections)[None]
    a0, a1 = i + j, i + (j + 1) % sections
    faces = np.concatenate([np.stack([a0, a1, a1 + sections], -1),
                            np.stack([a0, a1 + sections, a0 + sections], -1)]).reshape(-1, 3)
    return trimesh.Trimesh(verts, faces, process=False)


def gear(radius=1.0, thickness=0.2, teeth=24, sections=96):
    """A disc with box teeth, one mesh."""
    parts = [cylinder(radius, thickness, sections)]
    tooth = box((0.25 * radius, 2 * np.pi * radius / teeth * 0.5, thickness))
    for k in range(teeth):                 # build time, a few dozen teeth
        t = tooth.copy()
        t.apply_translation((radius + 0.1 * radius, 0, 0))
        t.apply_transform(trimesh.transformations.rotation_matrix(2 * np.pi * k / teeth, (0, 0, 1)))
        parts.append(t)
    return trimesh.util.concatenate(parts)


def translate(xyz):
    return trimesh.transformations.translation_matrix(xyz)


def place(xyz, scale=(1.0, 1.0, 1.0), rot_z=0.0):
    """Translation @ rotation about Z @ non-uniform scale, as one (4, 4) matrix."""
    m = trimesh.transformations.rotation_matrix(rot_z, (0, 0, 1))
    m = m @ np.diag([*scale, 1.0])
    m[:3, 3] = xyz
    return m


def align_z(start, end, radius):
    """Matrix that maps a unit tube along +Z (radius 1, length 1) onto ``start -> end``."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    d = end - start
    length = np.linalg.norm(d)
    z = d / length
    ref = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(ref, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = x * radius, y * radius, z * length
    m[:3, 3] = start
    return m


class SceneBuilder:
    """Adds named nodes to a trimesh.Scene, sharing geometry by name."""

    def __init__(self):
        self.scene = trimesh.Scene()
        self.geoms = {}

    def group(self, name, parent=None, matrix=None):
        self.scene.graph.update(frame_to=name, frame_from=parent or self.scene.graph.base_frame,
                                matrix=np.eye(4) if matrix is None else matrix)
        return name

    def add(self, name, geom_name, mesh_factory, matrix=None, parent=None):
        """A node ``name`` carrying the shared geometry ``geom_name`` (made once)."""
        if geom_name not in self.geoms:
            self.geoms[geom_name] = mesh_factory()
            self.scene.geometry[geom_name] = self.geoms[geom_name]
        self.scene.graph.update(frame_to=name, frame_from=parent or self.scene.graph.base_frame,
                                matrix=np.eye(4) if matrix is None else matrix, geometry=geom_name)
        return name
