"""Recording relit video from the viewer, one frame per pass of the window's loop (so the window
stays responsive and shows each frame as it is recorded; encoding runs on the writer's thread).

- :class:`TurntableRecording`: a full 360 degree turn of the lighting from the current rotation,
  ``frames`` frames at ``fps``, each rendered at full quality.
- :class:`InteractionRecording`: what the user does, captured as a timeline while they do it, then
  rendered at full quality at the video's frame rate.
- :class:`ClipRecording`: a clip's every frame relit under the lighting set, with its audio.

Stopping early (the key again, or closing the window) finishes the file with the frames so far;
the fragmented MP4 (:mod:`viewer.output.video`) stays playable even if the program is killed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from viewer.output.render import turntable_yaws
from viewer.output.video import VideoWriter
from viewer.progress import TimeLeft
from viewer.scene.look import Look


class CountedRecording:
    """A recording whose ``total`` frames are known when it starts: how far it is, and the time left."""

    total: int
    done: int
    time_left: TimeLeft

    @property
    def finished(self) -> bool:
        return self.done >= self.total

    @property
    def fraction(self) -> float:
        return self.done / self.total

    def _added(self):
        self.done += 1
        self.time_left.update("frames", self.done, self.total)


class TurntableRecording(CountedRecording):
    kind = "turntable"

    def __init__(self, path: Path, size, start_yaw: float, frames: int = 120, fps: float = 30.0):
        self.path = Path(path)
        self.total = int(frames)
        self.yaws = turntable_yaws(start_yaw, 360.0, self.total)
        self.start_yaw = start_yaw
        self.done = 0
        self.writer = VideoWriter(self.path, size[0], size[1], fps=fps)
        self.time_left = TimeLeft({"frames": 1.0})

    def next_yaw(self) -> float:
        return float(self.yaws[self.done])

    def add(self, rgb: np.ndarray):
        self.writer.write(rgb)
        self._added()

    def close(self) -> Path:
        return self.writer.close()

    def abort(self) -> None:
        """A recording that failed: the frames so far stay in its partial file (the target untouched)."""
        self.writer.abort()


@dataclass(frozen=True)
class Moment:
    """What the viewer showed at ``seconds`` into a recording: enough to render that frame again."""
    seconds: float
    look: Look
    placed: tuple
    sigma: np.ndarray


class InteractionRecording:
    """What the user does, at the video's frame rate. While the user works, each pass of the loop
    adds the state shown (:meth:`capture`: the look, their lights and the sigmas, a few hundred bytes,
    only when something changed); the window draws as it always does (preview frames while
    dragging). :meth:`stop` ends the capture; then each pass renders one frame at full quality, the
    state at ``k / fps`` s (the turn interpolated between the moments around it, the rest as it was
    at that time), so ten seconds of dragging give ten seconds of video however slow a full frame is.
    The map and the person are those shown while it renders."""

    kind = "live"

    def __init__(self, path: Path, size, fps: float = 30.0):
        self.path = Path(path)
        self.size = size
        self.fps = float(fps)
        self.moments: list[Moment] = []
        self.start = None
        self.writer = None  # made when the capture stops
        self.done = 0
        self.total = None
        self.time_left = None
        self.resume = None  # the user's state when the capture ended

    @property
    def capturing(self) -> bool:
        return self.writer is None

    @property
    def finished(self) -> bool:
        return self.total is not None and self.done >= self.total

    @property
    def fraction(self) -> float | None:
        return None if self.total is None else self.done / self.total

    @property
    def seconds(self) -> float:
        return 0.0 if self.start is None else time.perf_counter() - self.start

    def capture(self, look: Look, placed, sigma: np.ndarray):
        now = time.perf_counter()
        if self.start is None:
            self.start = now
        last = self.moments[-1] if self.moments else None
        if last is not None and last.look == look and last.placed == tuple(placed) and np.array_equal(last.sigma, sigma):
            return
        self.moments.append(Moment(now - self.start, look, tuple(placed), np.array(sigma, copy=True)))

    def stop(self, look: Look, placed, sigma: np.ndarray):
        """The capture ends now, the user's state being this one (:attr:`resume`, restored when the
        frames are written); the frames are rendered from the next pass on."""
        self.resume = Moment(self.seconds, look, tuple(placed), np.array(sigma, copy=True))
        self.total = max(1, int(round(self.seconds * self.fps)))
        self.writer = VideoWriter(self.path, self.size[0], self.size[1], fps=self.fps)
        self.time_left = TimeLeft({"frames": 1.0})

    def moment(self, k: int) -> Moment:
        """The state of frame ``k``: the last moment at or before its time, its yaw and tilt carried
        linearly towards the next moment's."""
        t = k / self.fps
        times = [m.seconds for m in self.moments]
        i = max(int(np.searchsorted(times, t, side="right")) - 1, 0)
        m = self.moments[i]
        if i + 1 < len(self.moments):
            nxt = self.moments[i + 1]
            w = float(np.clip((t - m.seconds) / max(nxt.seconds - m.seconds, 1e-9), 0.0, 1.0))
            look = replace(m.look, yaw=m.look.yaw + w * (nxt.look.yaw - m.look.yaw),
                           tilt=m.look.tilt + w * (nxt.look.tilt - m.look.tilt))
            m = replace(m, look=look)
        return m

    def add(self, rgb: np.ndarray):
        self.writer.write(rgb)
        self.done += 1
        self.time_left.update("frames", self.done, self.total)

    def close(self) -> Path:
        return self.writer.close()

    def abort(self) -> None:
        """A recording that failed: the frames so far stay in its partial file (the target untouched)."""
        if self.writer is not None:
            self.writer.abort()


class ClipRecording(CountedRecording):
    """A clip relit in the window (R while a clip is open): every frame of the clip, one per pass of
    the loop, at full quality under the lighting the user set (the timeline brings each frame's
    person and camera turn, :meth:`viewer.app.clip_player.ClipPlayer.record_frame`), at the source's
    timing; then joined with the source's audio (:func:`viewer.output.clip_render.join_relit`).
    ``resume``: the frame the user was at, shown again afterwards. Stopped early, the video holds the
    frames so far and the audio as long."""

    kind = "clip"

    def __init__(self, path: Path, size, timeline):
        self.path = Path(path)
        self.bundle = timeline.bundle
        self.times = list(timeline.times)
        self.total = len(self.times)
        self.resume = timeline.index
        self.done = 0
        self.video = self.path.with_name(f"{self.path.stem}.video.mp4")  # the frames alone, before the audio joins them
        self.writer = VideoWriter(self.video, size[0], size[1], fps=timeline.fps)
        self.time_left = TimeLeft({"frames": 1.0})
        self.note = None

    def add(self, rgb: np.ndarray):
        self.writer.write(rgb, seconds=self.times[self.done])
        self._added()

    def close(self) -> Path:
        """The video with the source's audio at :attr:`path` (as long as the frames recorded); a note
        about the audio (none, a sidecar, or the join failed and the frames are there without it) in
        :attr:`note`. No frame recorded: no file."""
        import os

        from viewer.output.clip_render import join_relit

        if self.done == 0:
            self.writer.abort()  # its empty partial file removed
            raise RuntimeError("no frame was recorded")
        video = self.writer.close()
        end = self.times[self.done] if self.done < self.total else self.bundle.duration
        try:
            self.note = join_relit(self.bundle, [(video, self.times[0])], self.path, end - self.times[0])
        except Exception as exc:  # the frames are kept: a video without its audio, said
            os.replace(video, self.path)  # the window's own file onto a name no file had (Recorder.capture_stem)
            self.note = f"without its audio ({exc})"
        video.unlink(missing_ok=True)  # the window's own file, joined into the video
        return self.path

    def abort(self) -> None:
        """A recording that failed: its frames-only file, the window's own, goes."""
        self.writer.abort().unlink(missing_ok=True)
        self.video.unlink(missing_ok=True)
