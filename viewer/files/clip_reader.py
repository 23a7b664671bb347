"""Video clips in: any clip PyAV (FFmpeg) decodes, read one frame at a time, upright, each with its
own time.

- **Containers and codecs**: whatever the FFmpeg inside PyAV's wheel reads (mp4, mov, webm, avi,
  mkv; H.264, H.265, VP9, ProRes, MPEG-4, ...). Why PyAV and not OpenCV's reader: it gives each
  frame's presentation time, the display matrix and the audio packets, which a relit clip keeps.
- **Rotation**: a phone's portrait clip is stored sideways with a display matrix; frames come out
  as a player shows them (turned by the matrix's rotation, a multiple of 90 degrees).
- **Timing**: each frame keeps its presentation time (a variable-frame-rate clip stays variable),
  counted from the first frame read, so a relit clip has the source's timing.
- **Damage**: a packet the decoder cannot read (a cut or corrupt file) is one warning line naming
  the clip and the time, and its frame is reported lost (``ClipFrame.rgb`` None), so the frame
  count and the timing are kept; a file cut short ends the clip there, with a warning.
- **Scripts**: an FFmpeg concat script or a playlist (``READS_OTHER_FILES``) is refused: its frames are other
  files', which change without it changing (a clip bundle is cached by the clip's bytes).
- **Bounds**: at most ``MAX_CLIP_FRAMES`` frames in one run (``--start`` / ``--end`` choose a part);
  frames are read as they are needed, so memory does not grow with the clip's length.
"""

from __future__ import annotations

import heapq
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.files.imageio import ffmpeg_file
from viewer.files.kinds import regular_file

VIDEO_SUFFIXES = (".mp4", ".mov", ".m4v", ".webm", ".avi", ".mkv")
MAX_CLIP_FRAMES = 36_000  # 20 minutes at 30 fps: a clip bundle of ~3 MB a frame would need 100 GB beyond this
READS_OTHER_FILES = {"concat", "hls", "applehttp", "dash", "webm_dash_manifest", "image2"}  # FFmpeg demuxers whose frames are other files'
REORDER = 16  # frames held to put the decoder's output and lost packets in time order


@dataclass(frozen=True)
class ClipInfo:
    """What a clip holds, from its header: the size frames are shown at (``width`` x ``height``,
    the display matrix applied), its ``rotation`` (degrees a player turns the stored frames,
    counter-clockwise), the average frame rate, the frame count (the container's, else estimated
    from the duration), the duration in seconds, the first audio stream's codec (None: silent) and the stored pixels'
    aspect (``sar``: width over height; frames come out with square pixels, as a player shows them)."""

    path: Path
    width: int
    height: int
    rotation: int
    fps: float
    frames: int
    duration: float
    audio: str | None
    sar: float = 1.0

    def to_json(self) -> dict:
        return {"path": str(self.path), "width": self.width, "height": self.height, "rotation": self.rotation,
                "fps": round(self.fps, 6), "frames": self.frames, "duration": round(self.duration, 6), "audio": self.audio}


@dataclass(frozen=True)
class ClipFrame:
    """One frame: its ``index`` among the frames read, its time in ``seconds`` from the first frame
    read (``at``: the first frame's time on the container's clock, which the audio shares), and its
    pixels (H, W, 3) uint8 sRGB upright; ``rgb`` None: lost (a packet that did not decode)."""

    index: int
    seconds: float
    rgb: np.ndarray | None
    at: float = 0.0


def is_clip(path) -> bool:
    """Whether ``path`` names a video by its suffix (what ``relight`` reads as a clip)."""
    return Path(path).suffix.lower() in VIDEO_SUFFIXES


def _open(path):
    import av

    regular_file(path, "clip")
    try:
        container = av.open(ffmpeg_file(path))
    except av.FFmpegError as exc:
        raise InputError(path, f"is not a video this program can read ({_reason(exc)})") from None
    if set(container.format.name.split(",")) & READS_OTHER_FILES:
        name = container.format.name
        container.close()  # its frames would be other files' (cached by this file's bytes, not theirs)
        raise InputError(path, f"is a script or playlist that names other files ({name}), not a video: give the video "
                               "file itself")
    if not container.streams.video:
        container.close()
        raise InputError(path, "holds no video stream (audio only, or not a video): give a clip with a picture")
    if container.streams.video[0].codec_context is None:
        name = codec_name(container.streams.video[0])
        container.close()
        raise InputError(path, f"its video is in a codec this program cannot decode ({name})")
    return container


def codec_name(stream) -> str:
    """A stream's codec (a stream FFmpeg has no decoder for has no codec context: its tag then)."""
    context = stream.codec_context
    return context.name if context is not None else f"undecodable ({stream.codec_tag or 'unknown'})"


def _reason(exc) -> str:
    return str(getattr(exc, "strerror", None) or exc).strip().rstrip(".")


def _rotation(stream, first) -> int:
    """Degrees a player turns the stored frames (counter-clockwise), a multiple of 90: the display
    matrix's, as the first decoded frame carries it."""
    angle = getattr(first, "rotation", 0) or 0
    return int(round(float(angle) / 90.0)) * 90 % 360


def upright(rgb: np.ndarray, rotation: int, sar: float = 1.0) -> np.ndarray:
    """The stored frame as a player shows it: its pixels ``sar`` times as wide as tall made square (the width
    scaled, :func:`viewer.resize.resize`), then turned ``rotation`` counter-clockwise degrees."""
    if sar != 1.0:
        from viewer.resize import resize

        h, w = rgb.shape[:2]
        rgb = resize(rgb, (max(int(round(w * sar)), 1), h))
    turns = (rotation // 90) % 4
    return np.ascontiguousarray(np.rot90(rgb, turns)) if turns else rgb


SAR_RANGE = (0.125, 8.0)  # a pixel's width over its height: a header's outside this is not believed (square taken)


def _sar(stream) -> float:
    """The stream's sample aspect ratio (its pixels' width over height; 1 when the header has none or an absurd one)."""
    ratio = stream.sample_aspect_ratio
    value = float(ratio) if ratio else 1.0
    return value if SAR_RANGE[0] <= value <= SAR_RANGE[1] else 1.0


def probe_clip(path) -> ClipInfo:
    """The clip's :class:`ClipInfo`; one line for a file that is not a clip, has no video stream
    or no frame. Decodes the first frame (the display matrix and the size shown come with it)."""
    import av

    with _open(path) as container:
        stream = container.streams.video[0]
        first = None
        try:
            for frame in container.decode(stream):
                first = frame
                break
        except av.FFmpegError as exc:
            raise InputError(path, f"its first frame does not decode ({_reason(exc)})") from None
        if first is None:
            raise InputError(path, "holds no frame (an empty or cut video stream)")
        rotation = _rotation(stream, first)
        sar = _sar(stream)
        w, h = max(int(round(first.width * sar)), 1), first.height
        if rotation in (90, 270):
            w, h = h, w
        fps = float(stream.average_rate or stream.guessed_rate or 0.0) or 30.0
        duration = float(stream.duration * stream.time_base) if stream.duration else (
            float(container.duration) / 1e6 if container.duration else 0.0)
        frames = int(stream.frames or 0) or int(round(duration * fps))
        audio = codec_name(container.streams.audio[0]) if container.streams.audio else None
    return ClipInfo(Path(path), int(w), int(h), rotation, fps, frames, duration, audio, sar)


def check_range(path, start: float, end: float | None) -> None:
    """One line for a ``--start`` / ``--end`` that selects nothing."""
    if not np.isfinite(start) or start < 0:
        raise InputError(path, f"--start must be 0 or more seconds, got {start}")
    if end is not None and (not np.isfinite(end) or end <= start):
        raise InputError(path, f"--end must come after --start ({start} s), got {end}")


def expected_frames(info: ClipInfo, start: float, end: float | None) -> int:
    """Frames from ``start`` to ``end`` seconds, as the header tells (at least 1: the header may not know)."""
    if start <= 0 and end is None and info.frames:
        return info.frames
    stop = info.duration if end is None else (min(end, info.duration) if info.duration else end)
    return max(int(np.ceil((stop - start) * info.fps - 1e-6)), 1)


def clip_frames(path, start: float = 0.0, end: float | None = None, limit: int = MAX_CLIP_FRAMES) -> Iterator[ClipFrame]:
    """The clip's frames from ``start`` to ``end`` (seconds of the clip; None: its end), in time
    order, upright. More than ``limit`` frames is one line naming the limit (before any is read when
    the header tells the count)."""
    import av

    check_range(path, start, end)
    info = probe_clip(path)
    expected = expected_frames(info, start, end)
    if expected > limit:
        raise InputError(path, f"{expected} frames from {start:g} s to {'its end' if end is None else f'{end:g} s'}: "
                               f"more than the {limit} one run takes; choose a part with --start and --end")
    with _open(path) as container:
        stream = container.streams.video[0]
        base = float(stream.time_base)
        origin = float(stream.start_time or 0) * base
        if start > 0:
            container.seek(int((start + origin) / base), stream=stream, backward=True)
        pending: list = []  # (time, tie, rgb or None): a heap, the decoder's output put in time order
        first = last = None
        count = 0
        tie = 0
        stored = None  # the first frame's stored size: a clip whose size changes is refused when it does

        def shown(frame) -> np.ndarray:
            nonlocal stored
            if stored is None:
                stored = (frame.width, frame.height)
            elif (frame.width, frame.height) != stored:
                raise InputError(path, f"its frames change size at {float(frame.pts or 0) * base - origin:.2f} s (from "
                                       f"{stored[0]}x{stored[1]} to {frame.width}x{frame.height}): a clip is relit at one size; "
                                       "cut it there (--end) or convert it to one size first")
            return upright(frame.to_ndarray(format="rgb24"), info.rotation, info.sar)

        def ready(force: bool):
            nonlocal first, last, count
            while pending and (force or len(pending) > REORDER):
                t, _, rgb = heapq.heappop(pending)
                if t < start - 1e-6 or (end is not None and t >= end - 1e-9):
                    continue
                if last is not None and t <= last + 1e-6:  # two frames at one time (a muxer's repeated timestamp)
                    warnings.warn(f"{path}: two frames at {t:.6f} s: the second left out", stacklevel=2)
                    continue
                last = t
                if first is None:
                    first = t
                if count >= limit:
                    raise InputError(path, f"holds more than the {limit} frames one run takes; choose a part with --start and --end")
                yield ClipFrame(count, t - first, rgb, first + origin)
                count += 1

        try:
            for packet in container.demux(stream):
                if packet.size == 0:
                    continue  # the demuxer's end-of-stream packet: flushed below
                t = None if packet.pts is None else float(packet.pts) * base - origin
                if end is not None and t is not None and t >= end + 1.0:
                    break  # a second past the end: every frame before it has been decoded
                try:
                    frames = packet.decode()
                except av.FFmpegError as exc:
                    if t is not None and (t < start - 1e-6 or (end is not None and t >= end - 1e-9)):
                        continue  # outside the part asked for: no frame of it is lost
                    when = f"{t:.3f} s" if t is not None else "an unknown time"
                    warnings.warn(f"{path}: a damaged packet at {when} did not decode ({_reason(exc)}): that frame is "
                                  "lost, the frame before it is shown in its place", stacklevel=2)
                    if t is not None:
                        heapq.heappush(pending, (t, tie, None))
                        tie += 1
                    continue
                for frame in frames:
                    ft = (float(frame.pts) * base - origin) if frame.pts is not None else (t or 0.0)
                    heapq.heappush(pending, (ft, tie, shown(frame)))
                    tie += 1
                yield from ready(False)
            for frame in stream.decode(None):  # the decoder's delayed frames
                ft = float(frame.pts) * base - origin if frame.pts is not None else 0.0
                heapq.heappush(pending, (ft, tie, shown(frame)))
                tie += 1
        except av.FFmpegError as exc:
            warnings.warn(f"{path}: the file ends early ({_reason(exc)}): the clip ends at its last whole frame", stacklevel=2)
        yield from ready(True)
    if count == 0:
        raise InputError(path, f"holds no frame from {start:g} s" + (f" to {end:g} s" if end is not None else ""))
