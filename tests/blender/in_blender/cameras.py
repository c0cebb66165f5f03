"""The cameras of a pass (occ_addon/cameras.py): the scene camera as Blender renders it."""


import bpy

from .common import box, check, cull, drawn, hidden_by_addon, new_scene, promise, update


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
