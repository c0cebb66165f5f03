"""Cameras: the contract's look-at / perspective / orthographic matrices in float64.

Conventions (stated once): OpenGL.  Column vectors, ``clip = P @ V @ world``;
the camera looks down its -Z axis; normalised device coordinates span [-1, 1]
on every axis; pixel ``(i, j)`` of a ``W x H`` target is sampled at its centre
``((i + 0.5) / W * 2 - 1, (j + 0.5) / H * 2 - 1)`` with row 0 at the bottom.

The engine never multiplies world positions by ``V`` directly: it works in
camera-relative coordinates (``world - eye``, float64) with
:meth:`Camera.relative_view_projection`, so scenes far from the origin keep
their precision when values are later rounded to float32.
"""

import json
import math
from dataclasses import dataclass

import numpy as np

from .errors import OccError
from .tolerance import tol

CAMERA_KEYS = ("eye", "target", "up", "fov_y_deg", "aspect", "near", "far", "ortho_height")


def _finite(value, name, shape=None):
    a = np.asarray(value, dtype=np.float64)
    if shape is not None and a.shape != shape:
        raise OccError(f"camera {name} must have shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise OccError(f"camera {name} must be finite, got {a.tolist()}")
    return a


def _json_type(value):
    return {bool: "true/false", str: "a string", list: "a list", dict: "an object",
            type(None): "null"}.get(type(value), type(value).__name__)


def _json_number(value, name, where="camera"):
    """A JSON number as float; true/false and strings are not numbers (Python says they are)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise OccError(f"{where} {name} must be a number, got {_json_type(value)} {json.dumps(value)}")
    return float(value)


def _json_vector(value, name, where="camera"):
    """A JSON list of three numbers as ``(3,) float64``."""
    if (not isinstance(value, list) or len(value) != 3
            or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value)):
        raise OccError(f"{where} {name} must be a list of 3 numbers [x, y, z], got {json.dumps(value)}")
    return np.array(value, dtype=np.float64)


def look_at(eye, target, up):
    """gluLookAt as a ``(4, 4) float64`` view matrix."""
    eye = _finite(eye, "eye", (3,))
    f = _finite(target, "target", (3,)) - eye
    up = _finite(up, "up", (3,))
    fn = np.linalg.norm(f)
    scale = max(np.abs(eye).max(), 1.0)
    if fn <= 1e-12 * scale:
        raise OccError(f"camera eye and target coincide at {eye.tolist()}")
    f = f / fn
    if not up.any():                             # an input, not a computed value: exact zero
        raise OccError(f"camera up {up.tolist()} has zero length; give a direction such as [0, 0, 1]")
    s = np.cross(f, up)
    sn = np.linalg.norm(s)
    if sn <= 1e-9 * max(np.linalg.norm(up), tol.tiny):
        raise OccError(f"camera up {up.tolist()} is parallel to the view direction")
    s = s / sn
    u = np.cross(s, f)
    v = np.eye(4)
    v[0, :3], v[1, :3], v[2, :3] = s, u, -f
    v[:3, 3] = -v[:3, :3] @ eye
    return v


def perspective(fov_y_deg, aspect, near, far):
    """gluPerspective as a ``(4, 4) float64`` projection matrix."""
    fov_y_deg, aspect, near, far = (float(_finite(x, n)) for x, n in
                                    ((fov_y_deg, "fov_y_deg"), (aspect, "aspect"),
                                     (near, "near"), (far, "far")))
    if not 0.0 < fov_y_deg < 180.0:
        raise OccError(f"camera fov_y_deg must be in (0, 180), got {fov_y_deg}")
    if aspect <= 0.0:
        raise OccError(f"camera aspect must be > 0, got {aspect}")
    if near <= 0.0:
        raise OccError(f"a perspective camera needs near > 0, got near={near}")
    if far <= near:
        raise OccError(f"camera far must be > near, got near={near}, far={far}")
    f = 1.0 / math.tan(math.radians(fov_y_deg) / 2.0)
    p = np.zeros((4, 4))
    p[0, 0] = f / aspect
    p[1, 1] = f
    p[2, 2] = (far + near) / (near - far)
    p[2, 3] = 2.0 * far * near / (near - far)
    p[3, 2] = -1.0
    return p


def orthographic(height, aspect, near, far):
    """glOrtho of a ``height * aspect`` by ``height`` view as ``(4, 4) float64``."""
    height, aspect, near, far = (float(_finite(x, n)) for x, n in
                                 ((height, "ortho_height"), (aspect, "aspect"),
                                  (near, "near"), (far, "far")))
    if height <= 0.0 or aspect <= 0.0:
        raise OccError(f"camera ortho_height and aspect must be > 0, got {height}, {aspect}")
    if far <= near:
        raise OccError(f"camera far must be > near, got near={near}, far={far}")
    w = height * aspect
    p = np.eye(4)
    p[0, 0] = 2.0 / w
    p[1, 1] = 2.0 / height
    p[2, 2] = -2.0 / (far - near)
    p[2, 3] = -(far + near) / (far - near)
    return p


@dataclass(frozen=True, eq=False)
class Camera:
    """A view and a projection, ``(4, 4) float64`` each, plus the eye they imply."""

    view: np.ndarray
    projection: np.ndarray

    def __post_init__(self):
        view = _finite(self.view, "view matrix", (4, 4))
        proj = _finite(self.projection, "projection matrix", (4, 4))
        if abs(np.linalg.det(view[:3, :3])) < 1e-12:
            raise OccError("camera view matrix is singular")
        object.__setattr__(self, "view", view)
        object.__setattr__(self, "projection", proj)

    @classmethod
    def look_at(cls, eye, target, up=(0.0, 0.0, 1.0), fov_y_deg=60.0, aspect=1.5,
                near=0.1, far=1000.0, ortho_height=None):
        """The contract's camera: gluLookAt with gluPerspective or glOrtho."""
        if ortho_height is None:
            proj = perspective(fov_y_deg, aspect, near, far)
        else:
            proj = orthographic(ortho_height, aspect, near, far)
        return cls(look_at(eye, target, up), proj)

    @classmethod
    def from_matrices(cls, view, projection):
        """From a view and a projection matrix (e.g. Blender's region_3d matrices)."""
        return cls(np.array(view, dtype=np.float64), np.array(projection, dtype=np.float64))

    @classmethod
    def from_dict(cls, d, where="camera"):
        """From one camera of the camera JSON contract (numbers must be JSON numbers)."""
        if not isinstance(d, dict):
            raise OccError(f"{where} must be a JSON object, got {_json_type(d)}")
        unknown = set(d) - set(CAMERA_KEYS)
        if unknown:
            raise OccError(f"{where}: unknown camera keys {sorted(unknown)}; expected {list(CAMERA_KEYS)}")
        for key in ("eye", "target"):
            if key not in d:
                raise OccError(f"{where} needs '{key}'")
        vec = {k: _json_vector(d[k], k, where) for k in ("eye", "target", "up") if k in d}
        num = {k: _json_number(d[k], k, where) for k in ("fov_y_deg", "aspect", "near", "far")
               if k in d}
        ortho = d.get("ortho_height")
        if ortho is not None:
            ortho = _json_number(ortho, "ortho_height", where)
        return cls.look_at(vec["eye"], vec["target"], vec.get("up", (0.0, 0.0, 1.0)),
                           num.get("fov_y_deg", 60.0), num.get("aspect", 1.5),
                           num.get("near", 0.1), num.get("far", 1000.0), ortho)

    @property
    def is_orthographic(self):
        """True when the projection has no perspective divide (w row is 0 0 0 1)."""
        return bool(np.allclose(self.projection[3], (0.0, 0.0, 0.0, 1.0)))

    @property
    def eye(self):
        """Eye position in world space, ``(3,) float64``."""
        r = self.view[:3, :3]
        return -np.linalg.solve(r, self.view[:3, 3])

    @property
    def direction(self):
        """Unit view direction in world space, ``(3,) float64``."""
        d = -np.linalg.inv(self.view[:3, :3])[:, 2]
        return d / np.linalg.norm(d)

    def relative_view_projection(self):
        """``P @ V @ T(eye)``: maps camera-relative positions (world - eye) to clip space."""
        v = self.view.copy()
        v[:3, 3] = 0.0
        # V @ T(eye) keeps the rotation and drops the translation exactly: V's
        # translation is -R @ eye by construction, so the sum cancels.
        return self.projection @ v

    def view_projection(self):
        """``P @ V`` in float64 (for world-space use, e.g. tests)."""
        return self.projection @ self.view


def camera_cut(before, after, scene_size):
    """Whether the view jumped between two passes: ``before`` is None, or the eye moved
    more than ``tol.coherence_move_rel`` of the scene's size, the view turned more than
    ``tol.coherence_turn_deg``, or the projection changed.  The one definition of a camera
    cut: what a coherent strategy remembers, and what live mode calls a fresh pass."""
    if before is None:
        return True
    move, turn = view_change(before, after)
    if move > tol.coherence_move_rel * max(scene_size, tol.tiny) or turn > tol.coherence_turn_deg:
        return True
    scale = np.abs(before.projection).max()
    return bool(np.abs(after.projection - before.projection).max() > tol.coherence_projection_rel * scale)


def view_change(a, b, frame=True):
    """Eye distance and turn (degrees) between two cameras: the angle of the rotation
    from one camera frame to the other (roll included), or with ``frame=False`` only
    the angle between their view directions."""
    move = float(np.linalg.norm(a.eye - b.eye))
    if frame:
        ra, rb = a.view[:3, :3], b.view[:3, :3]
        ra = ra / np.linalg.norm(ra, axis=1, keepdims=True)      # rows: the camera's axes
        rb = rb / np.linalg.norm(rb, axis=1, keepdims=True)
        cos = float(np.clip((np.trace(ra @ rb.T) - 1.0) / 2.0, -1.0, 1.0))
    else:
        cos = float(np.clip(a.direction @ b.direction, -1.0, 1.0))
    return move, math.degrees(math.acos(cos))


def load_cameras(path):
    """Read a camera JSON file: one camera, or ``{"frames": [camera, ...]}`` -> list of Camera."""
    try:
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
    except OSError as e:
        raise OccError(f"cannot read camera file {path}: {e.strerror}") from None
    except UnicodeDecodeError as e:
        raise OccError(f"camera file {path} is not UTF-8 text (byte {e.start}); save it as UTF-8 JSON") from None
    except json.JSONDecodeError as e:
        raise OccError(f"camera file {path} is not valid JSON: {e}") from None
    return cameras_from_json(data)


def cameras_from_json(data):
    """One camera dict or ``{"frames": [...]}`` -> list of Camera."""
    if isinstance(data, dict) and "frames" in data:
        frames = data["frames"]
        if not isinstance(frames, list) or not frames:
            raise OccError("camera 'frames' must be a non-empty list")
        return [Camera.from_dict(f, f"camera frame {i}") for i, f in enumerate(frames)]
    return [Camera.from_dict(data)]
