"""Shadow volumes: their boxes hold every point a light's shadow of a box can reach."""

import math

import numpy as np
import pytest

from core import Camera, Culler, Visibility
from core.lights import Light, in_world, shadow_boxes
from tests import scenes

SCENE_BOX = np.array([[-50.0, -50.0, -1.0], [50.0, 50.0, 30.0]])


def _inside(points, box, slack=1e-9):
    return np.all((points >= box[0] - slack) & (points <= box[1] + slack), axis=-1)


def _shadow_points(box, light, rng, count=400):
    """Points of the box's shadow volume inside the scene box: along rays from random
    emitter points through random points of the box."""
    p = box[0] + rng.random((count, 3)) * (box[1] - box[0])
    if light.kind == "sun":
        axis = np.cross(light.direction, rng.normal(size=(count, 3)))
        axis /= np.linalg.norm(axis, axis=1, keepdims=True)
        a = 0.5 * light.angle * np.sqrt(rng.random(count))[:, None]
        d = light.direction * np.cos(a) + np.cross(axis, light.direction) * np.sin(a)
    else:
        v = rng.normal(size=(count, 3))
        v *= (light.radius * rng.random(count) ** (1 / 3) / np.linalg.norm(v, axis=1))[:, None]
        d = p - (light.position + v)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
    t = rng.random(count)[:, None] * 150.0
    q = p + t * d
    return q[_inside(q, SCENE_BOX)]


@pytest.mark.parametrize("seed", range(6))
def test_shadow_boxes_hold_the_shadow_volume(seed):
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-20, 20, (5, 3)) * [1, 1, 0.5] + [0, 0, 10]
    boxes = np.stack([lo, lo + rng.uniform(0.2, 4, (5, 3))], axis=1)
    lights = [Light("sun", direction=rng.normal(size=3), angle=math.radians(rng.uniform(0, 10))),
              Light("point", position=rng.uniform(-30, 30, 3) + [0, 0, 40], radius=rng.uniform(0, 1)),
              Light("area", position=rng.uniform(-30, 30, 3) + [0, 0, 40], radius=rng.uniform(0, 3))]
    out, owner = shadow_boxes(boxes, lights, SCENE_BOX)
    assert len(out) == len(boxes) * len(lights)
    for k, light in enumerate(lights):
        for i, box in enumerate(boxes):
            shadow = out[k * len(boxes) + i]
            assert owner[k * len(boxes) + i] == i
            pts = _shadow_points(box, light, rng)
            assert _inside(pts, shadow, 1e-6).all(), (light.kind, i)


def test_a_box_beyond_the_reach_casts_nothing():
    boxes = np.array([[[0, 0, 0], [1, 1, 1]], [[40, 0, 0], [41, 1, 1]]], dtype=float)
    out, owner = shadow_boxes(boxes, [Light("point", position=(0, 0, 5), reach=10.0)], SCENE_BOX)
    assert owner.tolist() == [0]


def test_a_light_from_everywhere_shadows_the_scene_box():
    out, _ = shadow_boxes(np.array([[[0, 0, 0], [1, 1, 1]]], dtype=float), [Light("everywhere")], SCENE_BOX)
    np.testing.assert_allclose(out[0], SCENE_BOX)


def test_a_light_turning_with_the_view_lands_in_world_space():
    camera = Camera.look_at((0, 0, 0), (1, 0, 0), up=(0, 0, 1))
    (sun,) = in_world([Light("sun", direction=(0, -1, 0), in_view=True)], camera, turn_deg=5.0)
    np.testing.assert_allclose(sun.direction, (0, 0, -1), atol=1e-12)      # view "down" is world -z here
    assert sun.angle == pytest.approx(math.radians(10.0))


def _yard():
    """A camera over a floor, a slab far above the view, a crate behind a wall."""
    boxes = [((-40, -40, -0.2), (40, 40, 0)), ((-2, -2, 14), (2, 2, 14.5)),
             ((6, -8, 0), (6.5, 8, 6)), ((8, -1, 0), (9, 1, 1))]
    scene = scenes.boxes_scene(boxes, ["floor", "slab", "wall", "crate"])
    camera = scenes.cam((-10, 0, 3), (0, 0, 0), near=0.1, far=200, fov_y_deg=30, aspect=16 / 9)
    return scene, camera


def test_a_caster_outside_the_view_stays_and_one_behind_a_wall_goes(ctx):
    scene, camera = _yard()
    with Culler(scene, resolution=(160, 90), ctx=ctx) as c:
        plain = c.cull(camera, fresh=True).state
        lit = c.cull(camera, lights=[Light("sun", direction=(0, 0, -1), angle=math.radians(1))]).state
    assert plain[1] == Visibility.VIEW_CULLED and plain[3] == Visibility.OCCLUDED
    assert lit[1] == Visibility.VISIBLE                      # its shadow falls on the floor in view
    assert lit[3] == Visibility.OCCLUDED                     # its shadow falls behind the wall only


def test_a_sun_from_below_keeps_no_slab(ctx):
    scene, camera = _yard()
    with Culler(scene, resolution=(160, 90), ctx=ctx) as c:
        lit = c.cull(camera, lights=[Light("sun", direction=(0, 0, 1))]).state
    assert lit[1] == Visibility.VIEW_CULLED
