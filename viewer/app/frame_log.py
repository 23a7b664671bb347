"""What the window's frames took: the latest ones' times and kinds (the panel's plot, the state
file), the longest since start-up, when a new map or photo reached the screen, and how long the
full-quality and sharp frames took after the lighting stopped (``relight bench viewer`` reads them)."""

from __future__ import annotations

import time
from collections import deque

FRAME_HISTORY = 600
START_FRAMES = 3  # the first frames draw the whole scene once (not counted in the longest frame)


class FrameLog:
    def __init__(self):
        self.frames: deque = deque(maxlen=FRAME_HISTORY)  # (ms, kind)
        self.count = 0  # frames drawn
        self.longest = (0.0, "")  # (ms, kind) of the longest frame since the start-up's
        self.switched_at: float | None = None  # wall clock (time.time) of the last frame that showed a new map or photo
        # after the lighting last stopped: ms to its full-quality frame at the preview's level, and to the sharp one
        self.settle: dict = {"full_quality_ms": None, "sharp_ms": None}
        self._settle_start: float | None = None

    def record(self, start: float, kind: str) -> float:
        """A frame begun at ``start`` (perf_counter) was swapped now; returns its ms."""
        now = time.perf_counter()
        ms = (now - start) * 1000.0
        self.frames.append((ms, kind))
        if kind == "switch":
            self.switched_at = time.time()
        elif kind == "settle":
            self._settle_start = start
            self.settle = {"full_quality_ms": ms, "sharp_ms": None}
        elif kind == "update" and self._settle_start is not None:
            self.settle["sharp_ms"] = (now - self._settle_start) * 1000.0
            self._settle_start = None
        elif kind != "sharpen":
            self._settle_start = None  # cut short (a drag, a new map, a recording): no sharp time
        if self.count >= START_FRAMES and ms > self.longest[0]:
            self.longest = (ms, kind)
        self.count += 1
        return ms
