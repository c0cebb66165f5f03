"""What hiding a baked frame's set costs during playback, against the drawing it saves.

Each frame change under a baked shot costs Blender's update of the view layer after the
hide (the base update grows with the scene's object count: 0.8 s at 28,845 objects,
however few objects change), and saves the drawing of what it hides.  Neither the draw
nor the saving can be read from Blender, so the saving is estimated from what can be
read: the time between two consecutive frames of playback ``T``, the update ``U`` inside
it, and the share ``s`` of the triangles the frame hides.  The draw with the frame's set
hidden takes at most ``T - U``; drawing time follows the triangles drawn, so the draw
without hiding is about ``(T - U) / (1 - s)`` and the saving about ``(T - U) s / (1 - s)``.
``T - U`` also holds the frame's other work, which over-estimates the saving; but the draw
does not follow the triangles alone (far, small objects cost more per triangle), which
under-estimates it, and more: in a real window (Blender 3.4, llvmpipe,
``tools/bench/gui_playback.py``) the estimate was 0.82 of the measured saving on the city and
0.3 on city-xl.  So the advice to play without the bake comes only where the update
outgrows :data:`MARGIN` times the estimate.
"""

from collections import deque

WINDOW = 8           # frames of playback the advice is taken over (medians)
MIN_UPDATE_MS = 10.0  # below this an update is never worth an advice
MAX_GAP_S = 5.0      # two frame changes further apart are not playback (the user paused)
MARGIN = 3.0         # the update must outgrow this many times the estimated saving


def _median(values) -> float:
    v = sorted(values)
    n = len(v)
    return 0.0 if n == 0 else (v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2]))


class PlaybackCost:
    """The last :data:`WINDOW` frames of playback: per frame the update's ms and the
    estimated ms of drawing saved."""

    def __init__(self, window: int = WINDOW):
        self.samples: deque = deque(maxlen=window)
        self.last: tuple | None = None       # (frame, seconds, update ms, share) of the last change

    def reset(self) -> None:
        self.samples.clear()
        self.last = None

    def frame(self, frame: int, seconds: float, update_ms: float, share: float | None) -> None:
        """A frame change at ``seconds`` (a monotonic clock) whose apply took ``update_ms``
        and hid ``share`` of the triangles (None: not known).  The time from the last change
        to this one held the last frame's update and its draw: a sample of the last frame.
        Only a change to the next or the previous frame soon after the last one is
        playback; anything else starts over."""
        last, self.last = self.last, (frame, seconds, float(update_ms), share)
        if last is None or abs(frame - last[0]) != 1 or not 0.0 < seconds - last[1] <= MAX_GAP_S:
            return
        if last[3] is None:
            self.samples.clear()
            return
        interval_ms = 1e3 * (seconds - last[1])
        drawn = max(interval_ms - last[2], 0.0)
        s = min(max(float(last[3]), 0.0), 0.999)
        self.samples.append((last[2], drawn * s / (1.0 - s)))

    def advice(self) -> tuple[float, float] | None:
        """``(update ms, saved ms)``, medians over the window, where the update costs more
        than :data:`MARGIN` times the drawing it is estimated to save (play without the
        bake); else None."""
        if len(self.samples) < self.samples.maxlen:
            return None
        update = _median(u for u, _ in self.samples)
        saved = _median(s for _, s in self.samples)
        return (update, saved) if update >= MIN_UPDATE_MS and update > MARGIN * saved else None
