"""Small generated scenes for the tests, each with the cameras that exercise it.

Every builder returns ``(Scene, [Camera, ...], expect_culling)``; expect_culling
says whether the scene has objects that are truly hidden from its cameras (so a
strategy that culls nothing there is a failure).
"""

import numpy as np

from core import Camera, Scene

UNIT_BOX_V = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=np.float64)
UNIT_BOX_F = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                       [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])


def box_matrix(lo, hi):
    """World matrix that maps the unit box [0, 1]^3 onto [lo, hi]."""
    m = np.eye(4)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m[:3, :3] = np.diag(hi - lo)
    m[:3, 3] = lo
    return m


def boxes_scene(boxes, names=None, offset=(0.0, 0.0, 0.0), tree=None):
    """A scene of axis-aligned solid boxes ``[(lo, hi), ...]`` sharing one unit-box mesh."""
    names = names or [f"box{i}" for i in range(len(boxes))]
    off = np.asarray(offset, float)
    mats = np.array([box_matrix(np.add(lo, off), np.add(hi, off)) for lo, hi in boxes]).reshape(-1, 4, 4)
    kw = {} if tree is None else {"tree_parent": tree[0], "tree_object": tree[1]}
    return Scene.from_arrays(names, [(UNIT_BOX_V, UNIT_BOX_F)], np.zeros(len(boxes), int), mats, **kw)


def cam(eye, target, offset=(0, 0, 0), **kw):
    off = np.asarray(offset, float)
    return Camera.look_at(np.add(eye, off), np.add(target, off), **kw)


SLIT_RESOLUTION = (64, 48)


def slit_wall(width_px, resolution=SLIT_RESOLUTION, offset=(0.0, 0.0, 0.0)):
    """A wall at x=0 with a vertical slit ``width_px`` pixels wide (at ``resolution``,
    orthographic camera) and a thin post behind it, seen only through the slit; a
    second post behind the solid part is hidden."""
    w, h = resolution
    height = 12.0                         # ortho view height: 12 units over h pixels
    px = height / h                       # world units per pixel
    half = width_px * px / 2
    # Centre the slit on a column of pixel centres, so exactly width_px columns see through.
    c = (width_px % 2) * px / 2
    boxes = [((0, -20, -20), (0.2, c - half, 20)),      # wall, left of the slit
             ((0, c + half, -20), (0.2, 20, 20)),        # wall, right of the slit
             ((3, c - 0.1 * px, -1), (3.2, c + 0.1 * px, 1)),   # post behind the slit centre
             ((3, 5, -1), (3.5, 6, 1))]              # post behind solid wall
    scene = boxes_scene(boxes, ["wall_l", "wall_r", "post_slit", "post_hidden"], offset)
    camera = cam((-10, 0, 0), (0, 0, 0), offset, up=(0, 0, 1), aspect=w / h, near=0.5,
                 far=100, ortho_height=height)
    return scene, [camera], True


def nested_boxes(offset=(0.0, 0.0, 0.0)):
    """Closed hollow boxes inside each other (6 wall slabs each), a prize in the middle;
    the scene tree nests the shells as groups."""
    boxes, names, tree_parent, tree_object = [], [], [], []
    parent_group, t = -1, 0.2
    for level, r in enumerate((8.0, 5.0, 3.0)):
        group = len(tree_parent)
        tree_parent.append(parent_group)
        tree_object.append(-1)
        for axis in range(3):
            for sign in (-1, 1):
                lo, hi = np.full(3, -r), np.full(3, r)
                if sign < 0:
                    hi[axis] = -r + t
                else:
                    lo[axis] = r - t
                tree_parent.append(group)
                tree_object.append(len(boxes))
                boxes.append((lo, hi))
                names.append(f"shell{level}_{axis}{'-+'[sign > 0]}")
        parent_group = group
    tree_parent.append(parent_group)
    tree_object.append(len(boxes))
    boxes.append(((-0.5, -0.5, -0.5), (0.5, 0.5, 0.5)))
    names.append("prize")
    scene = boxes_scene(boxes, names, offset, (np.array(tree_parent), np.array(tree_object)))
    cams = [cam((-30, 4, 3), (0, 0, 0), offset, near=0.5, far=200),
            cam((-6.5, 0, 0), (1, 0, 0), offset, near=0.1, far=200)]   # inside the outer shell
    return scene, cams, True


def hollow_building(offset=(0.0, 0.0, 0.0)):
    """A building with four walls and a roof, the camera inside; furniture inside
    (visible) and a row of houses outside behind the walls (hidden)."""
    walls = [((-10, -10, 0), (10, -9.8, 4)), ((-10, 9.8, 0), (10, 10, 4)),
             ((-10, -10, 0), (-9.8, 10, 4)), ((9.8, -10, 0), (10, 10, 4)),
             ((-10, -10, 4), (10, 10, 4.2)), ((-10, -10, -0.2), (10, 10, 0))]
    inside = [((2, 2, 0), (3, 3, 1)), ((-5, 3, 0), (-4, 6, 2)), ((4, -6, 0), (6, -5, 0.8))]
    outside = [((20 + 5 * i, -3, 0), (23 + 5 * i, 3, 6)) for i in range(5)]
    boxes = walls + inside + outside
    names = ([f"wall{i}" for i in range(6)] + [f"chair{i}" for i in range(3)]
             + [f"house{i}" for i in range(5)])
    scene = boxes_scene(boxes, names, offset)
    cams = [cam((-8, 0, 1.7), (1, 0, 1.2), offset, near=0.05, far=300, fov_y_deg=90, aspect=2.0)]
    return scene, cams, True


def near_plane_crossing(offset=(0.0, 0.0, 0.0)):
    """Boxes that cross the near plane, one containing the eye, others behind a near wall."""
    boxes = [((-1, -1, -1), (1, 1, 1)),                 # contains the eye
             ((0.05, -5, -5), (0.3, 5, 5)),             # a wall straddling the near plane
             ((4, -1, -1), (5, 1, 1)),                  # behind the wall: hidden
             ((-3, -0.5, -0.5), (-2, 0.5, 0.5))]        # behind the eye: outside
    scene = boxes_scene(boxes, ["around_eye", "near_wall", "behind_wall", "behind_eye"], offset)
    cams = [cam((0, 0, 0), (1, 0, 0), offset, near=0.1, far=50)]
    return scene, cams, True


def tiny_and_flat(offset=(0.0, 0.0, 0.0)):
    """Zero-thickness quads (as flat boxes), sub-pixel objects and a hiding wall."""
    boxes = [((5, -2, -2), (5, 2, 2)),                  # zero-thickness wall (x extent 0)
             ((8, -0.5, -0.5), (8.5, 0.5, 0.5)),        # hidden behind the flat wall
             ((5, 3, 0), (5.001, 3.001, 0.001)),        # tiny, beside the wall: sub-pixel
             ((5, -3, -0.02), (5.02, -2.98, 0.0)),      # small, beside the wall
             ((6, 2.5, -1), (6, 2.5, 1))]               # a line (two zero extents)
    scene = boxes_scene(boxes, ["flat_wall", "behind_flat", "tiny", "small", "line"], offset)
    cams = [cam((0, 0, 0), (1, 0, 0), offset, near=0.1, far=50, fov_y_deg=70)]
    return scene, cams, True


def random_city(seed, n=400, offset=(0.0, 0.0, 0.0)):
    """Seeded random boxes on a plane: buildings of random size, a ground slab."""
    rng = np.random.default_rng(seed)
    lo = np.column_stack([rng.uniform(-60, 60, n), rng.uniform(-60, 60, n), np.zeros(n)])
    size = np.column_stack([rng.uniform(0.5, 6, n), rng.uniform(0.5, 6, n), rng.uniform(0.5, 12, n)])
    boxes = [((-70, -70, -0.5), (70, 70, 0))] + list(zip(lo, lo + size, strict=True))
    scene = boxes_scene(boxes, None, offset)
    cams = []
    for _ in range(3):
        eye = np.array([rng.uniform(-65, -55), rng.uniform(-20, 20), rng.uniform(1.0, 20)])
        target = np.array([0.0, rng.uniform(-20, 20), rng.uniform(0, 3)])
        cams.append(cam(eye, target, offset, near=0.1, far=400, fov_y_deg=rng.uniform(30, 100),
                        aspect=rng.uniform(0.5, 2.5)))
    return scene, cams, True


def extreme_cameras(offset=(0.0, 0.0, 0.0)):
    """The random city from very wide, very narrow and orthographic cameras."""
    scene, _, _ = random_city(7, 300, offset)
    cams = [cam((-65, 0, 2), (0, 0, 1), offset, fov_y_deg=170, aspect=1.0, near=0.05, far=500),
            cam((-65, 0, 2), (0, 0, 1), offset, fov_y_deg=2, aspect=1.0, near=1, far=500),
            cam((-65, 0, 2), (0, 0, 1), offset, fov_y_deg=60, aspect=8.0, near=0.1, far=500),
            cam((-65, 0, 2), (0, 0, 1), offset, fov_y_deg=60, aspect=0.125, near=0.1, far=500),
            cam((-65, -30, 40), (0, 0, 0), offset, aspect=1.5, near=0.1, far=500, ortho_height=60)]
    return scene, cams, True


SCENES = {
    "slit1px": lambda off: slit_wall(1, offset=off),
    "slit2px": lambda off: slit_wall(2, offset=off),
    "nested_boxes": nested_boxes,
    "hollow_building": hollow_building,
    "near_plane": near_plane_crossing,
    "tiny_and_flat": tiny_and_flat,
    "random_city": lambda off: random_city(3, offset=off),
    "extreme_cameras": extreme_cameras,
}
