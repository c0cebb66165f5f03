"""Debug pictures without dependencies: PNG writing and colouring of ID buffers."""

import struct
import zlib

import numpy as np

# One colour per Visibility state, then the background.
STATE_COLOURS = np.array([[60, 200, 80],     # VISIBLE: green
                          [220, 60, 50],     # OCCLUDED: red
                          [70, 110, 230],    # VIEW_CULLED: blue
                          [25, 25, 30]], dtype=np.uint8)


def write_png(path, image):
    """Write ``(h, w) uint8`` grey or ``(h, w, 3) uint8`` RGB, top row first, as PNG."""
    img = np.ascontiguousarray(image, dtype=np.uint8)
    if img.ndim == 2:
        img = img[..., None]
    h, w, c = img.shape
    colour_type = {1: 0, 3: 2}[c]
    raw = np.concatenate([np.zeros((h, 1), np.uint8), img.reshape(h, w * c)], axis=1).tobytes()

    def chunk(tag, data):
        body = tag + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, colour_type, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(raw, 6)))
        f.write(chunk(b"IEND", b""))


def object_shade(ids):
    """A brightness in [0.6, 1] per pixel that differs between neighbouring object IDs, so
    that objects of one state stay apart in a picture (1 for empty pixels)."""
    k = (np.maximum(ids, 0).astype(np.uint64) * np.uint64(2654435761)) % np.uint64(997)
    return np.where(ids >= 0, 0.6 + 0.4 * k.astype(np.float64) / 996.0, 1.0)


def colour_by_state(ids, state, shade=False):
    """ID buffer ``(h, w)`` (row 0 at the bottom, -1 empty) -> RGB by each object's state,
    top row first; ``shade`` varies the brightness per object (:func:`object_shade`)."""
    idx = np.where(ids >= 0, state[np.maximum(ids, 0)], len(STATE_COLOURS) - 1)
    rgb = STATE_COLOURS[idx]
    if shade:
        rgb = (rgb * object_shade(ids)[..., None]).astype(np.uint8)
    return rgb[::-1]
