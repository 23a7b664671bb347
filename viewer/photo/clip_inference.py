"""A clip -> a clip bundle (:mod:`viewer.scene.clip_bundle`): every frame inferred as a photo is.

Frames stream from the decoder (:mod:`viewer.files.clip_reader`) one at a time, so memory does not
grow with the clip's length; the networks are loaded once and one GL context serves every frame.
Each frame's scene bundle is written whole (:func:`viewer.photo.inference.write_bundle`), then its
record, so a run that stops (Ctrl-C, a crash, a full disk) keeps every finished frame, and the same
command run again goes on from the first frame not finished. A frame where no person is found
(the person left the picture) is recorded as such, and shows the new background alone when
relit; a frame lost to a damaged packet is recorded as lost.

``temporal`` "on" (the default): what belongs to the scene rather than the frame is estimated once
per shot (:mod:`viewer.photo.shots` finds the cuts): the photo's own lighting is fitted on the
shot's first frame with a person and kept for the shot's other frames (the relit clip's exposure is
likewise resolved once per shot, :mod:`viewer.output.clip_render`); each frame's maps and matte
are blended with the frame before's along the optical flow where it holds (:mod:`viewer.photo.steady`);
and the camera's turn is read from the old background's motion (:mod:`viewer.photo.camera_motion`),
so that the new background turns with it.
"off": every frame exactly as ``relight infer`` makes a photo's bundle (its own lighting estimate,
maps and exposure), for comparison.
"""

from __future__ import annotations

import bisect
import contextlib
import functools
import json
import shutil
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

from viewer.errors import InputError, NoPersonError
from viewer.files.clip_reader import ClipInfo, check_range, clip_frames, expected_frames, probe_clip
from viewer.files.imageio import MARK, write_png, write_text
from viewer.files.ownership import (
    file_sha256,
    folder_lock,
)
from viewer.memory_needs import frames_freed
from viewer.nets.device import DEFAULT_DEVICE
from viewer.photo.bundle_version import inference_version
from viewer.photo.camera_motion import CameraMotion
from viewer.photo.clip_cache import (
    BUSY,
    ClipRequest,
    clip_key,
    clip_target,
    finished_frame,
    set_aside_if_damaged,
    source_state,
    start_over,
    unchanged,
)
from viewer.photo.clip_person import choose_person, person_gaps
from viewer.photo.frame_writes import FrameWarnings, FrameWrites
from viewer.photo.frames import output_frame
from viewer.photo.inference import ClipFrame, infer_scene, load_networks, write_bundle
from viewer.photo.person_track import PersonTrack
from viewer.photo.shots import ShotCuts
from viewer.photo.steady import SteadyMaps
from viewer.resize import resize
from viewer.scene.area_lights import load_lights
from viewer.scene.bundle import load_scene
from viewer.scene.clip_bundle import (
    FORMAT,
    FRAMES,
    RECORD,
    VERSION,
    ClipFrameEntry,
    absolute_pan,
    frame_name,
    read_frame_entry,
    read_record,
)

FRAME_MB = (1.5, 2.5)  # disk a frame's bundle takes: MB, plus MB per megapixel of its frame (measured 2.7 MB at 0.42 MP, 3.2 at 0.96)


MIN_FRAME_SIDE = 32  # pixels: a frame's shorter side at the bundle's size; a person in fewer is not relit
MAX_ASPECT = 8.0  # a frame's longer side over its shorter: past it the optical flow's frames (640 px long) are too thin


def check_frame_size(path, info: ClipInfo, max_size: int) -> None:
    """One line, before any frame is inferred, for a clip whose frames are too small or too thin to relight."""
    fw, fh = output_frame((info.width, info.height), max_size)
    if min(fw, fh) < MIN_FRAME_SIDE or max(fw, fh) > MAX_ASPECT * min(fw, fh):
        shown = f" ({fw}x{fh} at --max-size)" if (fw, fh) != (info.width, info.height) else ""
        raise InputError(path, f"its frames are {info.width}x{info.height} pixels{shown}"
                         f": too small or too thin to relight (at least {MIN_FRAME_SIDE} pixels on each side, at most "
                         f"{MAX_ASPECT:g} times as long as wide)")


def _check_disk(path, info: ClipInfo, max_size: int, out_dir: Path, frames: int) -> None:
    """Refuse, in one line, a clip whose bundle would not fit on the disk."""
    fw, fh = output_frame((info.width, info.height), max_size)
    need = (FRAME_MB[0] + FRAME_MB[1] * fw * fh / 1e6) * 1e6 * frames
    free = shutil.disk_usage(out_dir.parent if not out_dir.exists() else out_dir).free
    if need > free:
        raise InputError(path, f"its clip bundle ({frames} frames at {fw}x{fh}) would need about {need / 1e9:.1f} GB of disk, "
                               f"{free / 1e9:.1f} GB is free: choose a part with --start and --end, or a smaller --max-size")


def locked_bundle(clip_path, out_dir, start: float, end: float | None,
                  cached: bool = False) -> tuple[Path, contextlib.AbstractContextManager]:
    """(``out_dir`` checked as a place for a clip bundle and made, the lock its maker holds: one run
    at a time makes a clip bundle; another is refused in one line, :data:`BUSY`). ``cached``: ``out_dir`` is the
    cache's (:func:`cached_clip_path`): damaged, it is made again (:func:`set_aside_if_damaged`, warned) instead of
    refused."""
    check_range(clip_path, start, end)
    if cached:
        note = set_aside_if_damaged(Path(out_dir).absolute())
        if note is not None:
            import warnings

            warnings.warn(note, stacklevel=2)
    out_dir = clip_target(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    return out_dir, folder_lock(out_dir, busy=BUSY)


def open_clip_bundle(clip_path, out_dir, request: ClipRequest = ClipRequest(),
                     digest: str | None = None) -> tuple[Path, dict, dict | None]:
    """Make ``out_dir`` ready for the clip bundle of ``clip_path`` made with ``request`` (its maker holding
    :func:`locked_bundle`'s lock): (the folder, its record as written now (not complete), the earlier
    record when the bundle there is whole already). An earlier bundle of another clip or options
    there is taken away; one of the same is kept (its finished frames are not inferred again, and
    the ranges it was split in, when it was, are kept: :mod:`viewer.photo.clip_ranges`). ``digest``:
    the clip's SHA-256 when the caller has just read it. The person to relight is chosen here, once
    for the clip (:func:`choose_person`), with its preview."""
    out_dir = Path(out_dir)
    info = probe_clip(clip_path)
    start, end, max_size = request.start, request.end, request.max_size
    check_frame_size(clip_path, info, max_size)
    options = request.options()
    digest = digest or file_sha256(clip_path)
    key = clip_key(digest, options, inference_version())
    total = expected_frames(info, start, end)
    record = {"format": FORMAT, "version": VERSION, "source": {**info.to_json(), "path": str(Path(clip_path).resolve()),
                                                               "sha256": digest},
              "options": options, "key": key, "temporal": request.temporal, "complete": False, "expected_frames": total, MARK[0]: MARK[1]}
    if (out_dir / RECORD).is_file():
        try:
            earlier = read_record(out_dir)
        except InputError:
            earlier = {}
        if earlier.get("key") != key:
            start_over(out_dir)
        elif earlier.get("complete") and _whole(out_dir, earlier):
            return out_dir, record, earlier  # whole: nothing to do
        else:  # the same bundle, unfinished: split as it was begun, its person as chosen
            record.update({k: earlier[k] for k in ("expected_frames", "shot_starts", "ranges", "person") if k in earlier})
    (out_dir / FRAMES).mkdir(parents=True, exist_ok=True)
    _check_disk(clip_path, info, max_size, out_dir, total)
    if "person" not in record:
        record["person"] = choose_person(clip_path, out_dir, start, end, max_size, request.person)
    write_text(out_dir / RECORD, json.dumps(record, indent=1) + "\n")
    return out_dir, record, None


def infer_clip(clip_path, out_dir, request: ClipRequest = ClipRequest(), device: str = DEFAULT_DEVICE,
               networks: dict | None = None, progress=None, ctx=None, digest: str | None = None, cached: bool = False) -> dict:
    """Write (or finish) the clip bundle of ``clip_path`` made with ``request`` (:class:`ClipRequest`:
    the part of the clip, the sizes, ...) into ``out_dir``; returns its record. ``progress(done, total,
    entry)`` after every frame (``total`` the header's estimate). Frames already finished by an earlier
    run of the same clip and request are kept. ``digest``: the clip's SHA-256 when the caller has just
    read it; ``cached``: ``out_dir`` is the cache's (:func:`locked_bundle`)."""
    made = not Path(out_dir).exists()
    out_dir, lock = locked_bundle(clip_path, out_dir, request.start, request.end, cached)
    with lock, _left_empty_removed(out_dir if made else None):
        before = source_state(clip_path)
        out_dir, record, earlier = open_clip_bundle(clip_path, out_dir, request, digest)
        if earlier is not None:
            return {**earlier, "frames_kept_from_earlier_run": earlier["frames"]}
        if record.get("ranges"):  # begun in ranges by a batch (viewer.photo.clip_ranges): finished range by range, as begun
            ranges = [ClipRange(*r) for r in record["ranges"]]
            done = [infer_frames(clip_path, out_dir, record, r, record.get("shot_starts"), device=device, networks=networks,
                                 progress=progress, ctx=ctx) for r in ranges]
            record = finish_ranges(clip_path, out_dir, ranges, done)
        else:
            done = infer_frames(clip_path, out_dir, record, device=device, networks=networks, progress=progress, ctx=ctx)
            record = finish_record(clip_path, out_dir, record, [done])
        unchanged(clip_path, before, out_dir)
        return record


@contextlib.contextmanager
def _left_empty_removed(folder: Path | None):
    """``folder`` (made by this run; None: not) removed again when the run fails and leaves it empty (a clip refused
    after its bundle's folder was made: no empty folder in the cache)."""
    try:
        yield
    except BaseException:
        if folder is not None:
            with contextlib.suppress(OSError):
                folder.rmdir()  # only when empty
        raise


def _whole(out_dir: Path, record: dict) -> bool:
    """Whether every frame of a complete record is finished and readable as recorded (a pan counted
    from a frame the record has no offset for is not)."""
    for i in range(int(record.get("frames", 0))):
        entry = finished_frame(out_dir / FRAMES, i)
        if entry is None:
            return False
        try:
            absolute_pan(entry, record, out_dir)
        except InputError:
            return False
    return int(record.get("frames", 0)) > 0


@dataclass(frozen=True)
class ClipRange:
    """Frames ``first`` to ``last`` (excluded) of a clip, begun ``warm`` frames before ``first``."""

    first: int
    last: int
    warm: int

    def to_json(self) -> list[int]:
        return [self.first, self.last, self.warm]


def finish_ranges(clip_path, out_dir, ranges: list[ClipRange], results: list[dict]) -> dict:
    """Every range done (``results`` in the order of ``ranges``): the pans joined across the ranges'
    starts, the record made complete. Returns it."""
    out_dir = Path(out_dir)
    record = read_record(out_dir)
    starts = record.get("shot_starts") or [0]
    offsets: dict[str, list[float]] = {}
    for clip_range, result in zip(ranges, results, strict=True):
        if result["frames"] != clip_range.last:
            raise InputError(clip_path, f"frames {clip_range.first} to {clip_range.last - 1} came out as {result['frames']} "
                                        "frames: the clip changed while it was read? run again")
    for clip_range, result in zip(ranges, results):
        begin = clip_range.first - clip_range.warm
        shot = bisect.bisect_right(starts, begin) - 1
        if record["temporal"] != "on" or begin <= starts[shot] or result["warm_pan"] is None:
            continue  # the range's pans count from their shots' first frames already
        before = read_frame_entry(out_dir / FRAMES / f"{frame_name(clip_range.first - 1)}.json")
        if before.pan_from is not None and str(before.pan_from) not in offsets:
            raise InputError(out_dir / FRAMES, f"frame {before.index}'s pan counts from frame {before.pan_from}, which no "
                                               "range began at: run again")
        reached = [before.pan[i] + (offsets[str(before.pan_from)][i] if before.pan_from is not None else 0.0) for i in (0, 1)]
        offsets[str(begin)] = [round(reached[i] - result["warm_pan"][i], 4) for i in (0, 1)]
    return finish_record(clip_path, out_dir, record, results, pan_offsets=offsets)


def finish_record(clip_path, out_dir: Path, record: dict, runs: list[dict], **more) -> dict:
    """The clip bundle's record made complete from what :func:`infer_frames` did (one run, or one a range
    in frame order) and written; ``more``: fields to add. No person in any frame is one line."""
    counts = {state: sum(r["counts"][state] for r in runs) for state in runs[0]["counts"]}
    count = runs[-1]["frames"]
    if counts["person"] == 0:
        raise NoPersonError(clip_path, f"no person found in any of its {count} frames")
    record = {**record, "complete": True, "frames": count, "first_frame_at": runs[-1]["first_at"], "states": counts,
              "frames_kept_from_earlier_run": sum(r["kept"] for r in runs),
              "shots": runs[-1]["shots"] if record["temporal"] == "on" else None, "seconds": round(sum(r["seconds"] for r in runs), 3),
              **more}
    record["gaps"] = person_gaps(clip_path, out_dir, record)
    write_text(out_dir / RECORD, json.dumps(record, indent=1) + "\n")
    return record


def infer_frames(clip_path, out_dir, record: dict, frames: ClipRange | None = None, shot_starts: list[int] | None = None,
                 device: str = DEFAULT_DEVICE, networks: dict | None = None, progress=None, ctx=None) -> dict:
    """Infer ``frames`` (a :class:`ClipRange`, ``first`` to ``last`` excluded; None: the whole clip) of the clip bundle in ``out_dir``
    (made ready by :func:`open_clip_bundle`, ``record``), each written whole as it is done; a frame
    finished by an earlier run is read instead. The ``warm`` frames before ``first`` are inferred (or
    read, when another run finished them) only to carry what one frame hands the next (the steadied
    maps, the camera's motion), never written: a range of a clip split across workers
    (:mod:`viewer.photo.clip_ranges`). ``shot_starts``: the frame each shot begins at, when found
    beforehand (ranges); None: the cuts are found as the frames come. Returns what was done: the
    frames per state, those kept, the frames seen (the last index + 1), the first frame's time on
    the clip's clock, the shots, the seconds, and the pan the camera's motion gave frame ``first - 1``."""
    from viewer.gl import create_headless_context

    own_ctx = ctx is None
    ctx = create_headless_context() if own_ctx else ctx
    try:
        return _FramesRun(clip_path, Path(out_dir) / FRAMES, record, frames or ClipRange(0, None, 0), shot_starts, device,
                          networks, ctx).all(progress)
    finally:
        if own_ctx:
            ctx.release()


class _FramesRun:
    """One :func:`infer_frames`: what a frame hands the next (the steadied maps, the camera's motion,
    the person followed, each shot's lights), the frames counted and their writes."""

    def __init__(self, clip_path, frames_dir: Path, record: dict, frames: ClipRange, shot_starts, device, networks, ctx):
        self.clip_path, self.frames_dir, self.record, self.range = clip_path, frames_dir, record, frames
        self.shot_starts, self.device, self.networks, self.ctx = shot_starts, device, networks, ctx
        options = record["options"]
        self.temporal = record["temporal"]
        info = probe_clip(clip_path)
        self.frame_size = output_frame((info.width, info.height), options["max_size"])  # the bundle's frame
        self.to_output = self.frame_size[0] / info.width  # source pixels -> the bundle's frame
        self.cuts = ShotCuts()
        on = self.temporal == "on"
        self.steady = SteadyMaps() if on else None
        self.motion = CameraMotion() if on else None
        self.follow = PersonTrack(record["person"]) if record.get("person") else None  # chosen once for the clip
        self.shot_lights: dict = {}  # shot -> the photo's lights fitted on its first frame with a person (temporal on)
        self.counts = {"person": 0, "no person": 0, "lost": 0}
        self.kept = 0
        self.begin = max(frames.first - frames.warm, 0)
        # a range begun within a shot (clip_ranges) counts that shot's pan from ``begin``, and
        # is given the shot's light as fitted on the shot's first frame with a person
        self.begin_shot = self.shot_of(self.begin, None) if on and shot_starts else None
        self.mid_shot = self.begin_shot is not None and self.begin > shot_starts[self.begin_shot]
        self.warned = FrameWarnings(clip_path)
        self.writes = FrameWrites()
        self._nets = None

    def networks_now(self) -> dict:
        self._nets = self._nets if self._nets is not None else (self.networks or load_networks(self.device))
        return self._nets

    def shot_of(self, index: int, rgb) -> int:
        if self.shot_starts:
            return bisect.bisect_right(self.shot_starts, index) - 1
        return self.cuts.shot_of(rgb)

    def all(self, progress) -> dict:
        first, last = self.range.first, self.range.last
        options = self.record["options"]
        total = int(self.record.get("expected_frames", 0))
        count, first_at, warm_pan = 0, 0.0, None
        t0 = time.perf_counter()
        with frames_freed() as after_frame:
            try:
                if self.mid_shot:
                    lights = _shot_lights(self.clip_path, self.frames_dir, self.record, self.shot_starts[self.begin_shot],
                                          self.begin, self.device, self.networks_now, self.ctx)
                    if lights is not None:
                        self.shot_lights[self.begin_shot] = lights
                for frame in clip_frames(self.clip_path, options["start"], options["end"]):
                    self.writes.deliver()
                    if frame.index < self.begin:
                        continue
                    if last is not None and frame.index >= last:
                        break
                    count, first_at = frame.index + 1, frame.at
                    entry, pan = self.one(frame)
                    if pan is not None and frame.index == first - 1:
                        warm_pan = list(pan)
                    after_frame()
                    if frame.index >= first:
                        self.counts[entry.state] += 1
                        if progress is not None:  # once the frame is written (on this thread: a window's progress draws)
                            self.writes.after(functools.partial(progress, count - first, max(total - first, count - first), entry))
            finally:
                try:
                    self.writes.close(quiet=sys.exc_info()[0] is not None)  # (an error on its way out is the one said)
                finally:
                    self.warned.close()
        return {"counts": self.counts, "kept": self.kept, "frames": count, "first_at": round(first_at, 6), "warm_pan": warm_pan,
                "shots": (len(self.shot_starts) if self.shot_starts else self.cuts.shot + 1) if self.temporal == "on" else None,
                "seconds": round(time.perf_counter() - t0, 3)}

    def one(self, frame):
        """One frame read (when an earlier run finished it) or inferred, and written when in the range:
        (its entry, the camera's pan on it or None)."""
        writing = frame.index >= self.range.first
        shot = self.shot_of(frame.index, frame.rgb) if self.temporal == "on" else frame.index
        counted_from = self.begin if self.mid_shot and shot == self.begin_shot else None
        if self.follow is not None:
            self.follow.at(frame.index)
        entry, alpha = self.finished(frame, shot, counted_from, writing)
        fresh = entry is None
        if fresh:
            entry, alpha = self.inferred(frame, shot, writing)
        pan = None
        if self.motion is not None:  # in the bundle's output pixels (the frame the pans are read on is the source's)
            pan = tuple(self.to_output * v for v in self.motion.shift_of(frame.rgb, alpha, shot))
            if fresh:
                entry = replace(entry, pan=pan, pan_from=counted_from)
        if fresh and writing:
            self.writes.put(functools.partial(write_text, self.frames_dir / f"{frame_name(frame.index)}.json",
                                              json.dumps(entry.to_json()) + "\n"))
        return entry, pan

    def finished(self, frame, shot: int, counted_from, writing: bool):
        """(the entry, the person's matte) of the frame as an earlier run finished it, what it hands the
        next frame carried on; (None, None) when it is to be inferred."""
        entry = finished_frame(self.frames_dir, frame.index)
        if entry is None or abs(entry.seconds - frame.seconds) >= 1e-4 or entry.shot != shot or \
                (entry.pan_from != counted_from and writing):  # (a pan counted elsewhere is made again)
            return None, None
        self.kept += writing
        alpha = None  # the person's matte at the frame's size (what the camera's motion leaves out)
        folder = self.frames_dir / frame_name(frame.index)
        if entry.state == "person" and shot not in self.shot_lights:  # the lights the shot's later frames were given
            self.shot_lights[shot] = load_lights(folder / "lights.json")
        if entry.state == "person" and (self.temporal == "on" or self.follow is not None):
            scene = load_scene(folder)
            alpha = scene.frame.alpha
            if self.follow is not None:  # the person followed from where this frame relit them
                self.follow.seen_in(alpha > 0.5)
            if self.steady is not None:  # the next frame steadied from this one's maps as written
                self.steady.carry(scene, resize(frame.rgb, self.frame_size), shot)
        elif self.steady is not None:
            self.steady.restart()
        return entry, alpha

    def inferred(self, frame, shot: int, writing: bool):
        """(the entry, the person's matte or None) of the frame inferred now, its bundle (or the frame as
        it is, without a person) written when in the range."""
        options = self.record["options"]
        index = frame.index
        if frame.rgb is None:
            if self.steady is not None:
                self.steady.restart()
            return ClipFrameEntry(index, frame.seconds, "lost", "a damaged packet: the frame before is shown", shot), None
        label = f"{self.clip_path} at {frame.seconds + options['start']:.3f} s"
        try:
            with self.warned.frame(label):
                given = ClipFrame(frame.rgb, self.shot_lights.get(shot), (self.steady, shot) if self.steady is not None else None,
                                  self.follow, options.get("people") == "all")
                result = infer_scene(label, None, size=options["size"], max_size=options["max_size"], device=self.device,
                                     networks=self.networks_now(), ctx=self.ctx, clip=given)
        except NoPersonError as exc:  # the frame as it is: what a photo background shows there
            if self.steady is not None:
                self.steady.restart()
            if writing:
                self.writes.put(functools.partial(write_png, self.frames_dir / f"{frame_name(index)}.png",
                                                  resize(frame.rgb, self.frame_size) / 255.0))
            return ClipFrameEntry(index, frame.seconds, "no person", exc.problem, shot), None
        result["record"]["clip"] = {"index": index, "seconds": round(frame.seconds, 6), "key": self.record["key"], "shot": shot}
        if writing:
            self.writes.put(functools.partial(write_bundle, result, self.frames_dir / frame_name(index)))
        self.shot_lights.setdefault(shot, result["lights"])
        return ClipFrameEntry(index, frame.seconds, "person", "; ".join(result["record"]["notes"]), shot), result["scene"].frame.alpha


def _shot_lights(clip_path, frames_dir: Path, record: dict, shot_start: int, begin: int, device: str, networks, ctx):
    """The photo's lights of the shot that began at frame ``shot_start``, for a range that begins at
    ``begin``, later in that shot: fitted on the shot's first frame with a person, as the run that
    infers that frame fits them (read from it when it is finished; the person followed as the
    ``record`` chose them). None: no person before ``begin``."""
    options = record["options"]
    start, end, size, max_size = options["start"], options["end"], options["size"], options["max_size"]
    follow = PersonTrack(record["person"]) if record.get("person") else None
    for frame in clip_frames(clip_path, start, end):
        if frame.index < shot_start or frame.rgb is None:
            continue
        if frame.index >= begin:
            return None
        entry = finished_frame(frames_dir, frame.index)
        if entry is not None:
            if entry.state == "person":
                return load_lights(frames_dir / frame_name(frame.index) / "lights.json")
            continue
        if follow is not None:
            follow.at(frame.index)
        try:
            given = ClipFrame(frame.rgb, follow=follow, everyone_too=options.get("people") == "all")
            return infer_scene(f"{clip_path} at {frame.seconds + start:.3f} s", None, size=size, max_size=max_size, device=device,
                               networks=networks(), ctx=ctx, clip=given)["lights"]
        except NoPersonError:
            continue
    return None
