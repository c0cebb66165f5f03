"""The cameras of a pass (occ_addon/cameras.py): the scene camera as Blender renders it."""


import bpy
import numpy as np

from .common import addon, box, check, cull, drawn, hidden_but_seen, hidden_by_addon, new_scene, promise, update


def camera_as_rendered():
    """The scene camera as Blender renders it: scale ignored; a mirrored camera."""
    scene = new_scene()
    cam = scene.camera
    cam.data.clip_end = 100.0
    box("far", (40, -1, 8), (41, 1, 9))                # beyond the wall's top edge, far away
    bpy.data.objects["wall"].scale.z = 4.0             # wall z -2..6 -> lower; far seen above it
    bpy.data.objects["wall"].location.z = 0.0
    # at the sides of the view, in front of the wall
    box("left", (-4, 1.3, 0.5), (-3.8, 1.5, 0.7))
    box("right", (-4, -1.5, 0.5), (-3.8, -1.3, 0.7))
    box("up", (-4, -0.1, 1.9), (-3.8, 0.1, 2.0))
    names = ("far", "left", "right", "up")
    for tag, scale in (("small", (0.01, 0.01, 0.01)), ("mirrored", (-1.0, 1.0, 1.0)),
                       ("large", (3.0, 3.0, 3.0)), ("nonuniform", (1.0, 0.3, 1.0))):
        cam.scale = scale
        update()
        r, _ = cull()
        check(f"camera_scale_{tag}_ignored", r == {"FINISHED"} and all(drawn(n) for n in names),
              (r, [(n, drawn(n)) for n in names]))
        promise(f"camera_scale_{tag}_truth")
    # a mirrored camera looking through a hole
    scene = new_scene()
    wall = bpy.data.objects["wall"]
    wall.scale.y = 5.0
    wall.location.y = -3.5                              # y -6..-1
    box("wall_r", (0, 1, -2), (0.5, 6, 6))              # a gap at y -1..1
    box("through_hole", (5, 0.3, 0.5), (5.4, 0.7, 0.9))
    box("hidden_behind", (5, 3, 0), (6, 4, 1))
    scene.camera.scale = (-1.0, 1.0, 1.0)
    scene.camera.data.shift_x = 0.1
    update()
    cull()
    check("camera_mirrored_through_hole", drawn("through_hole") and hidden_by_addon("hidden_behind"),
          (drawn("through_hole"), hidden_by_addon("hidden_behind")))
    promise("camera_mirrored_hole_truth")


def camera_panoramic_refused():
    """A panoramic scene camera is refused with a report, not a traceback."""
    scene = new_scene()
    scene.camera.data.type = "PANO"
    r, err = cull()
    check("camera_panoramic_refused", isinstance(r, str) and "panoramic" in r and "Traceback" not in err, (r, err))


def camera_scale_zero_reported():
    """A camera scaled to 0 is a report the user can act on."""
    scene = new_scene()
    scene.camera.scale = (0.0, 0.0, 0.0)
    update()
    r, err = cull()
    check("camera_scale_zero_reported", isinstance(r, str) and "scale of 0" in r and "Traceback" not in err,
          (r, err[-800:]))


RENDER_SIZES = (  # (x, y, percentage, pixel aspect x, y, sensor fit, shift x, y): wide, tall, tiny, odd
    (200, 60, 100, 1, 1, "AUTO", 0.0, 0.0), (200, 66, 100, 1, 1, "AUTO", 0.0, 0.0),
    (160, 60, 100, 1, 1, "AUTO", 0.1, -0.05), (201, 60, 100, 1, 1, "VERTICAL", 0.0, 0.0),
    (60, 200, 100, 1, 1, "AUTO", 0.0, 0.2), (256, 1, 100, 1, 1, "AUTO", 0.0, 0.0),
    (1, 256, 100, 1, 1, "HORIZONTAL", 0.0, 0.0), (300, 60, 33, 1, 1, "AUTO", 0.0, 0.0),
    (97, 13, 150, 2, 1, "AUTO", -0.2, 0.0), (320, 180, 7, 1, 2, "VERTICAL", 0.0, 0.1),
    (333, 2, 100, 1.3, 1, "AUTO", 0.0, 0.0), (50, 8, 50, 1, 1, "HORIZONTAL", 0.3, 0.0),
    (400, 4, 25, 1, 1, "AUTO", 0.0, 0.0), (4, 400, 25, 1, 1, "AUTO", 0.0, 0.0),
)


def camera_render_sizes():
    """The scene camera at wide, tall, tiny and odd render sizes, percentages, pixel aspects,
    sensor fits and shifts: the add-on's camera is ``calc_matrix_camera`` at Blender's
    render size (the percentage applied as Blender applies it, integer division) and
    the display size it culls for is that size; a cull at each hides nothing that covers
    a pixel there."""
    scene = new_scene()
    cam = scene.camera
    box("beside", (-4, 1.3, 0.5), (-3.8, 1.5, 0.7))
    box("behind", (5, -1, 0), (6, 1, 1))
    box("above", (20, -1, 7), (21, 1, 8))                 # seen over the wall's top edge
    box("edge", (-4, -3.3, 0.9), (-3.9, -3.2, 1.1))       # near the left or right border
    cameras = addon("cameras")
    wrong, seen_hidden = [], []
    for x, y, pct, ax, ay, fit, sx, sy in RENDER_SIZES:
        r = scene.render
        r.resolution_x, r.resolution_y, r.resolution_percentage = x, y, pct
        r.pixel_aspect_x, r.pixel_aspect_y = ax, ay
        cam.data.sensor_fit, cam.data.shift_x, cam.data.shift_y = fit, sx, sy
        update()
        # Blender's render size (BKE_render_resolution; a side is at least 4 before the percentage)
        size = (r.resolution_x * pct // 100, r.resolution_y * pct // 100)
        camera, shown = cameras.scene_camera(bpy.context)
        expected = np.array(cam.calc_matrix_camera(bpy.context.evaluated_depsgraph_get(), x=max(size[0], 1),
                                                   y=max(size[1], 1), scale_x=ax, scale_y=ay))
        if tuple(shown) != size or not np.allclose(camera.projection, expected, rtol=0, atol=1e-6):
            wrong.append((x, y, pct, ax, ay, fit, tuple(shown), size))
        if min(size) >= 1:
            res, err = cull()
            bad = hidden_but_seen()
            if res != {"FINISHED"} or bad:
                seen_hidden.append((x, y, pct, ax, ay, fit, sx, sy, res, bad, err[-300:]))
    check("camera_render_size_matches", not wrong, wrong)
    check("camera_render_sizes_truth", not seen_hidden, seen_hidden)
