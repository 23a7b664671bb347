"""Recording relit video from the viewer, one frame per pass of the window's loop (so the window
stays responsive and shows each frame as it is recorded; encoding runs on the writer's thread).

- :class:`TurntableRecording`: a full 360 degree turn of the lighting from the current rotation,
  ``frames`` frames at ``fps``, each rendered at full quality.
- :class:`LiveRecording`: what the user does, one full-quality frame per pass of the loop, timed
  by the wall clock.

Stopping early (the key again, or closing the window) finishes the file with the frames so far;
the fragmented MP4 (:mod:`viewer.video`) stays playable even if the program is killed.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..render import turntable_yaws
from ..video import VideoWriter


class TurntableRecording:
    kind = "turntable"

    def __init__(self, path: Path, size, start_yaw: float, frames: int = 120, fps: float = 30.0):
        self.path = Path(path)
        self.total = int(frames)
        self.yaws = turntable_yaws(start_yaw, 360.0, self.total)
        self.start_yaw = start_yaw
        self.done = 0
        self.writer = VideoWriter(self.path, size[0], size[1], fps=fps)

    @property
    def finished(self) -> bool:
        return self.done >= self.total

    @property
    def fraction(self) -> float:
        return self.done / self.total

    def next_yaw(self) -> float:
        return float(self.yaws[self.done])

    def add(self, rgb: np.ndarray):
        self.writer.write(rgb)
        self.done += 1

    def close(self) -> Path:
        return self.writer.close()


class LiveRecording:
    kind = "live"

    def __init__(self, path: Path, size, fps: float = 30.0):
        self.path = Path(path)
        self.writer = VideoWriter(self.path, size[0], size[1], fps=fps)
        self.start = None
        self.done = 0
        self.finished = False
        self.fraction = None

    def add(self, rgb: np.ndarray):
        now = time.perf_counter()
        if self.start is None:
            self.start = now
        self.writer.write(rgb, seconds=now - self.start)
        self.done += 1

    def close(self) -> Path:
        return self.writer.close()
