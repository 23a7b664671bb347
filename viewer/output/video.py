"""Relit video files: H.264 in MP4 through PyAV (FFmpeg's libx264), encoded on a background thread.

Frames go to ``<name>.partial.mp4`` beside the target, which replaces the target in one step when
:meth:`VideoWriter.close` has flushed every frame: an earlier video of the same name stays whole
until the new one is. The MP4 is fragmented (a self-contained fragment per keyframe interval, the
index up front), so a recording cut short, even by a crash, leaves a playable partial file holding
every finished fragment, under its own clearly marked name.
"""

from __future__ import annotations

import contextlib
import os
import queue
import threading
from fractions import Fraction
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.files.imageio import MARK_TEXT, ffmpeg_file
from viewer.files.output_lock import create_partial

TICKS_PER_FRAME = 1000  # time base = 1 / (1000 fps): frame i at exactly i / fps, wall-clock times to 1/1000 frame
FRAGMENT_FLAGS = "frag_keyframe+empty_moov+default_base_moof"


def partial_path(path) -> Path:
    """Where a video is written until it is complete: ``name.partial.mp4`` beside ``name.mp4``."""
    path = Path(path)
    return path.with_name(f"{path.stem}.partial{path.suffix}")


def partial_taken(path) -> InputError:
    """The error for a video whose partial name is already taken (checked before any work, and when
    the file is created)."""
    return InputError(partial_path(path), "exists (a recording cut short, or a file of yours): move it or give "
                                          "another output name; nothing was written")


def encoded_size(size: tuple[int, int]) -> tuple[int, int]:
    """The size a video of frames of ``size`` (w, h) is written at: 4:2:0 needs even sides, so an odd last row or
    column is left out (never padded)."""
    return tuple(max(int(v) - int(v) % 2, 2) for v in size)


class VideoWriter:
    """``write(rgb)`` frames (H, W, 3) uint8 or float in [0, 1]; ``close()`` when done (also as a
    context manager). Frames are queued to an encoding thread, so a caller rendering frames is not
    held up by the encoder unless it runs ahead by more than ``queue_frames``."""

    def __init__(self, path, width: int, height: int, fps: float = 30.0, crf: int = 18, keyframe_seconds: float = 1.0,
                 queue_frames: int = 8):
        import av

        self.path = Path(path)
        if self.path.suffix.lower() != ".mp4":
            raise InputError(self.path, "videos are written as H.264 MP4: give a .mp4 path")
        if not (np.isfinite(fps) and 0.1 <= fps <= 1000):
            raise InputError(self.path, f"frame rate must be in [0.1, 1000] frames a second, got {fps}")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.path.is_dir():
            raise InputError(self.path, "is a folder: give a .mp4 file path")
        self.partial = partial_path(self.path)
        try:  # created here, exclusively: a file already under that name (a recording cut short, the user's) is kept
            create_partial(self.partial, self.path)  # killed, the next run under a lock removes it (viewer.files.output_lock)
        except FileExistsError:
            raise partial_taken(self.path) from None
        except OSError as exc:
            raise InputError(self.path, f"cannot write the video ({exc.strerror or exc})") from None
        self.size = (int(width), int(height))
        # 4:2:0 needs even sides: an odd last row or column is left out (never padded)
        self.encoded_size = encoded_size(self.size)
        self.fps = float(fps)
        self.frames = 0
        self._last_pts = -1
        # flush_packets: each finished fragment reaches the file at once, not when an I/O buffer fills
        try:
            self._container = av.open(ffmpeg_file(self.partial), "w", format="mp4",
                                      options={"movflags": FRAGMENT_FLAGS, "flush_packets": "1"})
        except (OSError, av.FFmpegError) as exc:
            self.partial.unlink(missing_ok=True)  # the empty file made above
            raise InputError(self.path, f"cannot write the video ({exc})") from None
        try:
            self._container.metadata["comment"] = MARK_TEXT  # viewer.files.ownership: the program's own file
            rate = Fraction(self.fps).limit_denominator(1001)
            self._time_base = 1 / (rate * TICKS_PER_FRAME)
            stream = self._container.add_stream("libx264", rate=rate)
            stream.width, stream.height = self.encoded_size
            stream.pix_fmt = "yuv420p"
            stream.codec_context.time_base = self._time_base
            stream.codec_context.gop_size = max(int(round(self.fps * keyframe_seconds)), 1)
            # no B-frames: frame times start at 0 and every encoded frame can be muxed at once
            stream.options = {"crf": str(crf), "preset": "veryfast", "bf": "0"}
        except Exception:
            self._container.close()
            raise
        self._stream = stream
        self._queue: queue.Queue = queue.Queue(maxsize=queue_frames)
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._encode_loop, name="video-encoder", daemon=True)
        self._thread.start()

    def write(self, rgb: np.ndarray, seconds: float | None = None):
        """Append a frame shown at ``seconds`` from the start (default: the next frame at ``fps``)."""
        self._raise_pending()
        if rgb.dtype != np.uint8:
            rgb = (np.clip(np.nan_to_num(rgb, nan=0.0), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
        h, w = rgb.shape[:2]
        if (w, h) != self.size or rgb.ndim != 3 or rgb.shape[2] != 3:
            raise ValueError(f"frame of shape {rgb.shape} does not match the video's {self.size[0]}x{self.size[1]} RGB")
        pts = self.frames * TICKS_PER_FRAME if seconds is None else int(round(seconds / self._time_base))
        pts = max(pts, self._last_pts + 1)  # strictly increasing, even for two frames at the same time
        self._last_pts = pts
        sw, sh = self._stream.width, self._stream.height
        if (sw, sh) != (w, h):
            rgb = rgb[:sh, :sw] if sw <= w and sh <= h else np.pad(rgb, ((0, max(sh - h, 0)), (0, max(sw - w, 0)), (0, 0)),
                                                                   mode="edge")[:sh, :sw]
        self._queue.put((np.ascontiguousarray(rgb), pts))
        self.frames += 1

    def _encode_loop(self):
        import av

        finished = False  # the end-of-stream marker was taken from the queue
        try:
            while True:
                item = self._queue.get()
                if item is None:
                    finished = True
                    break
                rgb, pts = item
                frame = av.VideoFrame.from_ndarray(rgb, format="rgb24")
                frame.pts, frame.time_base = pts, self._time_base
                for packet in self._stream.encode(frame):
                    self._container.mux(packet)
            for packet in self._stream.encode():
                self._container.mux(packet)
        except BaseException as exc:  # reported to the writer's thread by write() / close()
            self._error = exc
            while not finished and self._queue.get() is not None:  # let a blocked write() and close() go on
                pass
        finally:
            try:
                self._container.close()
            except BaseException as exc:
                self._error = self._error or exc

    def _raise_pending(self):
        if isinstance(self._error, OSError):  # the disk or the folder (full, removed meanwhile): one line
            reason = getattr(self._error, "strerror", None) or str(self._error)
            raise InputError(self.path, f"cannot write the video ({reason})") from None
        if self._error is not None:
            raise RuntimeError(f"encoding {self.path} failed: {self._error}") from self._error

    def _finish_encoding(self):
        if self._thread.is_alive():
            self._queue.put(None)
            self._thread.join()

    def close(self) -> Path:
        """Flush the encoder, finish the file and put it in place of the target; returns its path.
        An encoding that failed leaves no partial file (this writer's own, and not a video)."""
        self._finish_encoding()
        if self._error is not None:
            self.partial.unlink(missing_ok=True)
        self._raise_pending()
        os.replace(self.partial, self.path)
        return self.path

    def abort(self) -> Path:
        """Stop here: the frames so far are flushed into the partial file, which stays under its own
        name (the target is left as it was); returns the partial file's path."""
        self._finish_encoding()
        if not self.frames:
            self.partial.unlink(missing_ok=True)
        return self.partial

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close()
            return
        partial = self.abort()
        if exc is not None and self.frames:
            exc.add_note(f"the {self.frames} frames so far are in {partial}; {self.path} was left as it was")


def read_video(path) -> tuple[np.ndarray, float]:
    """All frames of a video as (T, H, W, 3) uint8, and its frame rate."""
    import av

    with av.open(ffmpeg_file(path)) as container:
        stream = container.streams.video[0]
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(stream)]
        rate = float(stream.average_rate or stream.guessed_rate or 0.0)
    return np.stack(frames) if frames else np.zeros((0, 0, 0, 3), np.uint8), rate



def _can_carry(stream) -> bool:
    """Whether an MP4 can hold ``stream``'s codec as it is (a header written to memory with it)."""
    import io

    import av

    try:
        with av.open(io.BytesIO(), "w", format="mp4") as probe:
            probe.add_stream_from_template(stream)
            probe.start_encoding()
        return True
    except (av.FFmpegError, ValueError):  # PyAV: "'mp4' format does not support 'adpcm_ima_wav' codec"
        return False


def _packets(path, kind: str, shift: float = 0.0, until: float | None = None):
    """(time, packet) of the first ``kind`` stream of ``path``, on a clock ``shift`` seconds later
    than the file's (packets before 0 or from ``until`` on left out), the packets moved to it."""
    import av

    with av.open(ffmpeg_file(path)) as container:
        stream = getattr(container.streams, kind)[0]
        base = stream.time_base
        ticks = int(round(shift / base))
        for packet in container.demux(stream):
            if packet.pts is None or packet.size == 0:
                continue
            t = float((packet.pts - ticks) * base)
            if t < -1e-6 or (until is not None and t >= until):
                continue
            packet.pts -= ticks
            if packet.dts is not None:
                packet.dts -= ticks
            yield t, packet


def _mux(out, sources) -> None:
    """Mux ``sources`` ((template stream, (time, packet) iterator) each) into ``out`` in time order."""
    import heapq

    def tagged(k, stream, packets):
        for t, packet in packets:
            yield t, k, stream, packet

    streams = [(out.add_stream_from_template(template), packets) for template, packets in sources]
    for _, _, stream, packet in heapq.merge(*(tagged(k, s, ps) for k, (s, ps) in enumerate(streams)), key=lambda x: x[:2]):
        packet.stream = stream
        out.mux(packet)


def _part_packets(part: Path, starts: float):
    """(time, packet) of a part whose first frame is at ``starts`` seconds of the clip (the muxer
    starts every file's clock at its first frame)."""
    packets = _packets(part, "video")
    first = next(packets, None)
    if first is None:
        return
    offset = first[0] - starts
    yield from _packets(part, "video", offset)


def join_clip(parts: list[tuple[Path, float]], path, audio_source=None, audio_at: float = 0.0,
              duration: float | None = None) -> str | None:
    """Join a relit clip's ``parts`` ((an MP4 of one encoder's settings, the clip's time of its first
    frame) each, in order) into ``path`` (an MP4 written whole or not at all, its index up front), with the first
    audio stream of ``audio_source`` from ``audio_at`` seconds of that file's clock, for
    ``duration`` seconds, copied as it is. An audio codec an MP4 cannot hold goes unchanged into
    :func:`audio_sidecar` beside it. Returns a note saying so (None otherwise)."""
    import av

    path = Path(path)
    partial = partial_path(path)
    try:
        create_partial(partial, path)  # killed mid-join, the next run removes it (viewer.files.output_lock)
    except FileExistsError:
        raise partial_taken(path) from None
    note = None
    try:
        with contextlib.ExitStack() as stack:
            audio = None
            if audio_source is not None:
                src = stack.enter_context(av.open(ffmpeg_file(audio_source)))
                audio = src.streams.audio[0] if src.streams.audio else None
                if audio is not None and not _can_carry(audio):
                    note = _audio_sidecar(audio, audio_source, path, audio_at, duration)
                    audio = None
            first = stack.enter_context(av.open(ffmpeg_file(parts[0][0])))
            sources = [(first.streams.video[0], (p for part, starts in parts for p in _part_packets(part, starts)))]
            if audio is not None:
                sources.append((audio, _packets(audio_source, "audio", audio_at, duration)))
            with av.open(ffmpeg_file(partial), "w", format="mp4", options={"movflags": "+faststart"}) as out:
                out.metadata["comment"] = MARK_TEXT  # viewer.files.ownership: the program's own file
                _mux(out, sources)
        os.replace(partial, path)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return note


def audio_sidecar(path, source) -> Path:
    """Where the audio of ``source`` goes when an MP4 cannot hold it: ``<name>.audio<source's suffix>``
    beside the video, in the source's own container (which held it)."""
    path = Path(path)
    return path.with_name(f"{path.stem}.audio{Path(source).suffix.lower()}")


def _audio_sidecar(audio, audio_source, path: Path, audio_at: float, duration: float | None) -> str:
    """The audio an MP4 cannot hold, copied unchanged into the source's container beside the video; the note."""
    import av

    from viewer.files.imageio import atomic_path

    sidecar = audio_sidecar(path, audio_source)
    container_format = audio.container.format.name.split(",")[0]
    with atomic_path(sidecar) as tmp, av.open(ffmpeg_file(tmp), "w", format=container_format) as out:
        out.metadata["comment"] = MARK_TEXT
        _mux(out, [(audio, _packets(audio_source, "audio", audio_at, duration))])
    from viewer.files.clip_reader import codec_name

    return f"the source's audio ({codec_name(audio)}) cannot go into an MP4 unchanged: it is in {sidecar}"
