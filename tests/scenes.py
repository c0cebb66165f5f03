"""Small generated scenes for the tests, each with the cameras that exercise it.

Every builder in ``SCENES`` returns ``(Scene, [Camera, ...], expect_culling)``;
expect_culling says whether the scene has objects that are truly hidden from its
cameras (so a strategy that culls nothing there is a failure).  After them: the
smaller scenes, cameras and boxes that several test modules share.
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


def ortho_cam(w=8, h=8, mirror=False):
    """Down -Z onto the XY plane, one unit per pixel (as tests/test_gl.py's ortho_cam); ``mirror``
    scales the view's x by -1 (a mirrored camera: the picture flips left-right)."""
    c = Camera.look_at((0, 0, 10), (0, 0, 0), up=(0, 1, 0), aspect=w / h, near=1, far=20,
                       ortho_height=h)
    if not mirror:
        return c
    return Camera.from_matrices(np.diag([-1.0, 1.0, 1.0, 1.0]) @ c.view, c.projection)


HOLE_SCENE = [((-4, -4, 2), (-1, 4, 3)), ((1, -4, 2), (4, 4, 3)),     # wall, hole at |x|, |y| < 1
              ((-4, -4, 2), (4, -1, 3)), ((-4, 1, 2), (4, 4, 3)),
              ((-0.9, -0.9, -1), (0.9, 0.9, 1)),                      # post behind the hole
              ((-4, -4, -2), (4, 4, -0.5)),                           # back wall, the post's foot in it
              ((2, 2, 0), (3, 3, 1))]                                 # post behind solid wall


def shifted(camera, dx_px, dy_px, width, height):
    """The camera with its image moved by a fraction of a pixel: a renderer that
    samples its pixels at other positions (another GPU's rounding)."""
    t = np.eye(4)
    t[0, 3], t[1, 3] = 2.0 * dx_px / width, 2.0 * dy_px / height
    return Camera.from_matrices(camera.view, t @ camera.projection)


def slabs_behind_a_wall_edge(width=1200, height=800):
    """A wall whose top edge runs between two pixel rows, and thin slabs seen edge-on
    (1.4 pixels tall) behind it, each sticking out above the edge by a different
    fraction of a pixel (0.05 .. 0.95); plus slabs 1.4 pixels tall in front of
    nothing.  Camera at the origin looking down +x, 60 degree field of view."""
    f = (height / 2) / np.tan(np.radians(30.0))        # pixels per unit of z / x
    wall_x, slab_x = 10.0, 20.0
    edge = 3.3 / f                                     # the wall's edge: 3.3 pixels above the centre row
    boxes = [((wall_x, -30.0, -30.0), (wall_x + 0.5, 30.0, edge * wall_x))]
    names = ["wall"]
    for k, out in enumerate(np.linspace(0.05, 0.95, 10)):
        top = (3.3 + out) / f * slab_x
        y = -9.0 + 2.0 * k
        boxes.append(((slab_x, y, top - 1.4 / f * slab_x), (slab_x + 3.0, y + 1.0, top)))
        names.append(f"behind_{out:.2f}")
    for k, phase in enumerate(np.linspace(0.0, 0.9, 4)):      # no wall above them: in front of nothing
        bottom = (40.0 + phase) / f * slab_x
        y = -6.0 + 3.0 * k
        boxes.append(((slab_x, y, bottom), (slab_x + 3.0, y + 1.0, bottom + 1.4 / f * slab_x)))
        names.append(f"open_{phase:.2f}")
    scene = boxes_scene(boxes, names)
    cam = Camera.look_at((0, 0, 0), (1, 0, 0), up=(0, 0, 1), fov_y_deg=60.0, aspect=width / height,
                         near=0.05, far=200.0)
    return scene, cam


def invalid_scene(bad_matrix=True, bad_vertices=True):
    """A wall, two boxes behind it, and bad objects in front of one of them."""
    box = (UNIT_BOX_V, UNIT_BOX_F)
    nan_mesh = (np.where(np.arange(24).reshape(8, 3) == 5, np.nan, UNIT_BOX_V), UNIT_BOX_F)
    mats = [box_matrix((0, -20, -20), (0.2, 20, 20)),      # wall
            box_matrix((3, -1, -1), (3.5, 1, 1)),          # behind the wall
            box_matrix((3, 5, -1), (3.5, 6, 1)),           # behind the wall
            box_matrix((-3, -1, -1), (-2, 1, 1)),          # in front, valid
            box_matrix((-5, -30, -30), (-4.8, 30, 30)),    # a second wall would hide everything
            box_matrix((-3, 4, -1), (-2, 5, 1))]           # in front, NaN vertices
    names = ["wall", "behind_a", "behind_b", "front", "bad_wall", "bad_mesh"]
    if bad_matrix:
        mats[4] = mats[4].copy()
        mats[4][0, 3] = np.nan
    meshes = [box, nan_mesh] if bad_vertices else [box]
    mesh_of = [0, 0, 0, 0, 0, 1 if bad_vertices else 0]
    return Scene.from_arrays(names, meshes, mesh_of, np.array(mats))


def random_boxes(rng, k):
    """``k`` seeded random boxes ``(k, 2, 3)``: scattered, all on a plane or many with one
    centre, some flat along an axis."""
    kind = rng.integers(0, 4)
    lo = rng.uniform(-50, 50, (k, 3))
    if kind == 1:
        lo[:, 2] = 0.0                                   # all on a plane
    if kind == 2:
        lo[k // 2:] = lo[0]                              # many identical centres
    size = rng.exponential(1.0, (k, 3)) * (rng.random((k, 3)) > 0.2)
    return np.stack([lo, lo + size], axis=1)
